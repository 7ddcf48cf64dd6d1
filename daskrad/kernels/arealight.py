"""Area lights by the paper's method: the light's window on the hemisphere base (issue 5, item 1).

From a point ``p`` with unit normal ``n`` (an element vertex), an area light (an emitting convex
polygon, one-sided along its normal) gives the irradiance

    ``H = π Le F · V``,

``F`` Lambert's unoccluded point-to-polygon form factor (exact; the same
:func:`daskrad.kernels.lambert.lambert_polygon` the shadow-ray method uses, so the unoccluded
answer is the same bits for both methods) and ``V`` the visible fraction of the light. By
Nusselt's analog (docs/design.md §2) ``F`` is the area of the light's projection onto the base
disc of the unit hemisphere over ``p``, over ``π``; and every point of the disc carries the same
weight, so ``V`` is the fraction of the light's projected area that no occluder covers. The paper
measures it on the disc, but only where the light is:

1. Candidate occluders through the voxel grid: the triangles registered in the cells of the
   bounding box of the pyramid ``{eye} ∪ light`` that cross the pyramid (a cell wholly outside
   one of its face planes is skipped), kept when some part of them lies inside the pyramid,
   above the horizon and in front of the light. With no candidate, ``V = 1``
   and nothing is rasterized (the common case in open parts of a scene).
2. Project the light onto the disc exactly as the hemisphere-base form factor projects an
   element (:func:`daskrad.kernels.hemisphere.project_element`: horizon clip, edges split into
   pieces of at most ``edge_angle`` as seen from ``p``, eqs. 1–4), and take the min–max
   **window** of its projected outline.
3. Rasterize only that window, ``R × R`` pixels stretched over it (the same relative accuracy
   for a light that fills half the sky and one that is a speck): the light first, into a
   z-buffer with the exact depth (``1/t`` along the pixel's direction), then every candidate
   (:func:`daskrad.kernels.hemisphere.fill_polygon`), only on the light's pixels, and only
   its part inside the pyramid to the light widened by 2° (:func:`clip_planes`,
   :func:`clip_polygon`: the margin keeps the clip's edges off the light's pixels). An occluder
   hides a pixel when it is nearer than the light by more than ``off``, the same rule as a shadow
   ray's ``tmax = 1 − off/|d|``, so the light's own triangles and the ceiling around it (coplanar
   with it) never shadow it.
4. ``V = (light pixels not hidden) / (light pixels)``: each pixel of the window has the same
   area on the disc, hence the same projected solid angle (eqs. 6–7 restricted to the window).

Before step 1, :func:`daskrad.kernels.faces.face_hides` tries to prove the light wholly hidden
by a single convex face of the scene (one ray and a few point-in-polygon tests); where it
does, ``V = 0`` and nothing else runs (:func:`area_irradiance_stats`).

Steps 1 and 3 are interleaved (:func:`visible_fraction`): the cells are searched slab by slab
from the eye towards the light and each slab's candidates drawn at once, and the search stops
as soon as every light pixel is hidden (``V = 0`` exactly: a hidden pixel never becomes
visible again). A wholly hidden light, most of the vertex-light pairs of a room with many
luminaires, then costs its first few occluders instead of every triangle in its pyramid
(RenderPark's office: 90 % of the pairs with candidates are wholly hidden, behind 117 of
them on average). The pixels hidden do not depend on the order occluders are drawn in, so
``V`` has the same bits as searching everything first.

Occluders are two-sided (the grid's triangles carry no orientation, and a shadow ray is blocked
by either side), so a triangle is oriented towards the eye before it is projected. The eye is
``p + off · n``, the shadow rays' origin: the receiver's own polygon lies ``off`` below it and
is clipped away at the horizon, and a wall meeting the floor at ``p`` projects onto the rim
half of the disc away from the room, never onto a light inside the room.

Accuracy: a pixel whose square the outline of the light or of its visible part does not cross
is counted exactly, so ``|V_raster − V| <= (B_vis + V B_light) / N_light`` with ``B`` the pixels
an outline crosses (at most ``4R + 4`` for a convex outline in an ``R × R`` window) and
``N_light`` the light's pixels (about ``R²`` times the fill of its window). In practice the
per-row errors cancel and the error is far below that bound (tests/test_arealight.py,
benchmarks/bench_arealight.py).

A point's value depends on the point, the scene and the points before it in the same call
(the face that last hid each light, tried first, :func:`daskrad.kernels.faces.face_hides`):
where that face proves a light hidden that the ray's face does not, ``V = 0``, the exact answer,
stands where the window method alone would give its raster's error (one vertex of 293,004 in
RenderPark's office, 1.5e-4 → 0). The direct pass calls it on fixed vertex ranges
(:func:`daskrad.direct.batches`), so the bits are the same on any number of workers.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_VISIBLE
from daskrad.kernels.faces import UNION_RAYS, face_hides_fan
from daskrad.kernels.geometry import lex_less, orthonormal_basis
from daskrad.kernels.grid import any_hit_fan, new_fan
from daskrad.kernels.hemisphere import (
    depth_coefficients,
    edge_capacity,
    fill_polygon,
    project_element,
    split_table,
)
from daskrad.kernels.lambert import lambert_polygon
from daskrad.kernels.tolerances import WINDOW_CLIP_ANGLE, WINDOW_MIN

#: The pyramid's box is searched in at most this many slabs along its longest axis, from the
#: eye's end (:func:`visible_fraction`), and a wholly hidden light stops after the slab that
#: hides it. Measured on RenderPark's office (graz, 8,203 vertices x 32 emitter patches) and
#: the classroom (9,168 x 24) against one search of the whole box: 8 slabs, -20 % and -6 %
#: CPU; 3 and 16 about the same; slabs of one cell, -0 % and +10 % (each slab along x walks
#: every row of the box again).
SLABS = 8

#: Occluders remembered per light: those that last hid it wholly, searched first at the next
#: point (:func:`visible_fraction`). Since the face that last hid a light is tried first
#: (:func:`daskrad.kernels.faces.face_hides`), the lights the window method still hides are
#: those no single face hides, and searching the boxes of many remembered occluders costs
#: more than it finds. 3,000-vertex runs at six places of each scene's vertex list, window
#: method with faces (two repeats, seconds): RenderPark's office (``graz.obj``) 1 / 2 / 4 / 8
#: occluders 1.58 / 1.61 / 1.66 / 1.70–1.84, the classroom 3.80 / 3.84 / 3.89 / 3.96,
#: office3 1.64 / 1.66 / 1.70 / 1.73; none at all (the face kept): 1.89 / 3.90 / 2.05. The
#: same bits for every count.
HINT = 1


@jit_leaf
def _pyramid(ex, ey, ez, corners, count, en, off, planes):
    """The face planes of the pyramid from the eye ``e`` to the light ``corners[:count]``.

    ``planes (5, 5)``: rows ``a < count`` are the side planes through ``e`` and the light's
    edge ``a → a+1``, as ``(kx, ky, kz, kd, slack)`` with ``k · x − kd >= −slack`` inside
    (``slack = off |k|``: a point within ``off`` of the pyramid counts as inside); a row with
    ``k = 0`` (the eye in the plane of an edge and the centroid) never rejects. Row ``count``
    is the light's plane, ``en · x − en · c0``, positive on the eye's side.
    """
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for a in range(count):
        gx += corners[a, 0]
        gy += corners[a, 1]
        gz += corners[a, 2]
    gx /= count
    gy /= count
    gz /= count
    for a in range(count):
        b = a + 1 if a + 1 < count else 0
        ax = corners[a, 0] - ex
        ay = corners[a, 1] - ey
        az = corners[a, 2] - ez
        bx = corners[b, 0] - ex
        by = corners[b, 1] - ey
        bz = corners[b, 2] - ez
        kx = ay * bz - az * by
        ky = az * bx - ax * bz
        kz = ax * by - ay * bx
        kd = kx * ex + ky * ey + kz * ez
        s = kx * gx + ky * gy + kz * gz - kd
        if s < 0.0:
            kx, ky, kz, kd = -kx, -ky, -kz, -kd
        elif not s > 0.0:
            kx, ky, kz, kd = 0.0, 0.0, 0.0, -1.0  # 0 − (−1) = 1 > 0: never rejects
        planes[a, 0] = kx
        planes[a, 1] = ky
        planes[a, 2] = kz
        planes[a, 3] = kd
        planes[a, 4] = off * np.sqrt(kx * kx + ky * ky + kz * kz)
    planes[count, 0] = en[0]
    planes[count, 1] = en[1]
    planes[count, 2] = en[2]
    planes[count, 3] = en[0] * corners[0, 0] + en[1] * corners[0, 1] + en[2] * corners[0, 2]
    planes[count, 4] = off


@jit_leaf
def clip_polygon(poly, n_p, planes, count):
    """Clip the convex polygon ``poly[0:3, :n_p]`` (rows x, y, z; ``poly (6, 8)``, rows 3–5
    scratch) to the half-spaces ``k · x − kd >= 0`` of ``planes[:count]`` (rows ``(kx, ky,
    kz, kd, ·)``; a row with ``k = 0`` is skipped); returns the corners left (< 3: nothing).

    A crossing point is computed from the lexicographically smaller end of its edge, so two
    triangles sharing an edge get the same point (their projections stay watertight).
    At most ``3 + count`` corners for a triangle: ``poly (6, 8)`` is enough for 5 planes
    (:func:`_occlude`), ``(6, 10)`` for the 6 of a candidate's test (:func:`_candidates`).
    """
    for pl in range(count):
        kx = planes[pl, 0]
        ky = planes[pl, 1]
        kz = planes[pl, 2]
        kd = planes[pl, 3]
        if kx == 0.0 and ky == 0.0 and kz == 0.0:
            continue
        m = 0
        for a in range(n_p):
            b = a + 1 if a + 1 < n_p else 0
            da = kx * poly[0, a] + ky * poly[1, a] + kz * poly[2, a] - kd
            db = kx * poly[0, b] + ky * poly[1, b] + kz * poly[2, b] - kd
            if da >= 0.0:
                poly[3, m] = poly[0, a]
                poly[4, m] = poly[1, a]
                poly[5, m] = poly[2, a]
                m += 1
            if (da >= 0.0) != (db >= 0.0):
                if lex_less(poly[0, a], poly[1, a], poly[2, a],
                            poly[0, b], poly[1, b], poly[2, b]):
                    i0, i1, d0, d1 = a, b, da, db
                else:
                    i0, i1, d0, d1 = b, a, db, da
                t = d0 / (d0 - d1)
                for k in range(3):
                    poly[3 + k, m] = poly[k, i0] + t * (poly[k, i1] - poly[k, i0])
                m += 1
        n_p = m
        for a in range(n_p):
            for k in range(3):
                poly[k, a] = poly[3 + k, a]
        if n_p < 3:
            return n_p
    return n_p


@jit_leaf
def clip_planes(ex, ey, ez, corners, count, delta, out):
    """``out[:count]``: the planes ``(kx, ky, kz, kd)`` (``k · x − kd >= 0`` inside) through
    the eye ``e`` and each edge ``a → a+1`` of the light, turned about the edge's direction by
    the angle ``delta`` away from the light: the pyramid they bound holds every direction
    within ``delta`` of the light's (:func:`clip_polygon`). A degenerate edge, the eye in the
    plane of an edge and the centroid, or a turned plane that would leave a corner of the
    light outside gives ``k = 0`` (no clip by that plane)."""
    gx = 0.0
    gy = 0.0
    gz = 0.0
    for a in range(count):
        gx += corners[a, 0] / count
        gy += corners[a, 1] / count
        gz += corners[a, 2] / count
    cd = np.cos(delta)
    sd = np.sin(delta)
    for a in range(count):
        b = a + 1 if a + 1 < count else 0
        for k in range(4):
            out[a, k] = 0.0
        dx = corners[b, 0] - corners[a, 0]
        dy = corners[b, 1] - corners[a, 1]
        dz = corners[b, 2] - corners[a, 2]
        dl = np.sqrt(dx * dx + dy * dy + dz * dz)
        if not dl > 0.0:
            continue
        dx /= dl
        dy /= dl
        dz /= dl
        # m: from the eye towards the edge, perpendicular to it (unit)
        mx = 0.5 * (corners[a, 0] + corners[b, 0]) - ex
        my = 0.5 * (corners[a, 1] + corners[b, 1]) - ey
        mz = 0.5 * (corners[a, 2] + corners[b, 2]) - ez
        md = mx * dx + my * dy + mz * dz
        mx -= md * dx
        my -= md * dy
        mz -= md * dz
        ml = np.sqrt(mx * mx + my * my + mz * mz)
        if not ml > 0.0:
            continue
        mx /= ml
        my /= ml
        mz /= ml
        # k = d × m, the plane's normal, towards the centroid; then turned by delta: k' =
        # cos δ k + sin δ m holds the edge inside by the angle δ (k' · (x − e) = r sin δ on
        # it, r the distance from the eye to the edge's line)
        kx = dy * mz - dz * my
        ky = dz * mx - dx * mz
        kz = dx * my - dy * mx
        side = kx * (gx - ex) + ky * (gy - ey) + kz * (gz - ez)
        if side < 0.0:
            kx, ky, kz = -kx, -ky, -kz
        elif not side > 0.0:
            continue
        kx = cd * kx + sd * mx
        ky = cd * ky + sd * my
        kz = cd * kz + sd * mz
        # Turning the plane moves its half behind the eye inwards: with the eye nearer the
        # light's plane than ~tan(δ)/4 of its size (above its inside), the far corners would
        # fall outside. Every corner must stay inside, else this plane clips nothing.
        inside = True
        for c in range(count):
            if not kx * (corners[c, 0] - ex) + ky * (corners[c, 1] - ey) \
                    + kz * (corners[c, 2] - ez) > 0.0:
                inside = False
        if not inside:
            continue
        out[a, 0] = kx
        out[a, 1] = ky
        out[a, 2] = kz
        out[a, 3] = kx * ex + ky * ey + kz * ez


@jit_leaf
def _cell_range(lo, hi, origin, cell, n):
    """First and last cell along one axis that ``[lo, hi]`` touches (clamped to the grid)."""
    a = int(np.floor(min(max((lo - origin) / cell, -1.0), n + 1.0)))
    b = int(np.floor(min(max((hi - origin) / cell, -1.0), n + 1.0)))
    return max(0, min(n - 1, a)), max(0, min(n - 1, b))


@jit_leaf
def _box_cells(grid, ex, ey, ez, corners, count, off):
    """Cell ranges ``(i0, i1, j0, j1, k0, k1)`` of the pyramid's bounding box, grown by
    ``off`` and clamped to the grid."""
    lox = ex
    hix = ex
    loy = ey
    hiy = ey
    loz = ez
    hiz = ez
    for a in range(count):
        lox = min(lox, corners[a, 0])
        hix = max(hix, corners[a, 0])
        loy = min(loy, corners[a, 1])
        hiy = max(hiy, corners[a, 1])
        loz = min(loz, corners[a, 2])
        hiz = max(hiz, corners[a, 2])
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    i0, i1 = _cell_range(lox - off, hix + off, origin[0], cell[0], dims[0])
    j0, j1 = _cell_range(loy - off, hiy + off, origin[1], cell[1], dims[1])
    k0, k1 = _cell_range(loz - off, hiz + off, origin[2], cell[2], dims[2])
    return i0, i1, j0, j1, k0, k1


@jit_leaf
def _narrow(k, rest, origin, cell, lo, hi, a, b):
    """``[a, b]`` narrowed to the cells ``i`` of an axis (``lo..hi`` the box's) whose centre
    ``c = origin + (i + 1/2) cell`` may satisfy ``k · c + rest >= 0``: a plane bounds them from
    one side, widened by one cell against rounding; ``b < a`` when none can."""
    if k == 0.0:
        return (a, a - 1) if rest < 0.0 else (a, b)
    bound = ((-rest / k) - origin) / cell - 0.5
    bound = min(max(bound, lo - 2.0), hi + 2.0)  # clamped before int()
    if k > 0.0:
        return max(a, int(np.floor(bound)) - 1), b
    return a, min(b, int(np.ceil(bound)) + 1)


@jit_leaf
def _candidates(grid, ex, ey, ez, nx, ny, nz, count, planes, hz, off, stamp, sid, cand,
                n_c, i0, i1, j0, j1, k0, k1, cpl, sc, prune=True):
    """Triangles that may hide part of the light from the eye, appended to ``cand`` after its
    first ``n_c``; returns the new count. Only cells ``i0..i1 × j0..j1 × k0..k1`` (a part of
    :func:`_box_cells`) are walked. ``off`` here is the height over the light's plane below
    which nothing can hide it (the raster's ``off`` along the most slanted ray,
    :func:`visible_fraction`); ``cpl`` the pyramid's half-spaces (:func:`_candidate_planes`),
    ``sc (6, 10)`` scratch.

    A candidate has a part inside the pyramid (its faces widened by their margins, in front
    of the light by more than ``off``) and above the horizon: a triangle that has none meets
    no segment from the eye to the light, so a pair left without a candidate is exactly
    :data:`LIGHT_VISIBLE`, and dropping it changes no ``V`` but where the raster's polyline
    outlines of the light stray outside the true pyramid (within the raster's own error).

    A triangle intersecting the pyramid has a point ``x`` inside it (within ``off``); ``x``
    lies in some cell, in whose list the grid registered the triangle, and that cell is not
    rejected (its corner farthest inside each plane is at least as far inside as ``x``). So
    walking the cells of the pyramid's bounding box that no plane rejects finds every such
    triangle, whatever parts the box is walked in; ``stamp (T,)`` (``== sid`` once seen for
    this light and point) drops repeats, within a part and across parts.

    ``prune``: walk only the rows of a layer that some cell of can pass every plane, and test
    only the cells that hold a triangle (the same cells, hence the same candidates; ``False``,
    every cell of the box tested, is the reference the tests hold it to). A pyramid fills a
    thin slanted part of its box, and most of it is air: at RenderPark's office (graz) a
    vertex-light pair's box has ~4 times the rows that hold a cell of it, and ~88 % of the
    cells it reaches are empty.
    """
    npl = count + 1
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    hx = 0.5 * cell[0]
    hy = 0.5 * cell[1]
    hzc = 0.5 * cell[2]
    tris = grid.triangles
    for k in range(k0, k1 + 1):
        cz = origin[2] + (k + 0.5) * cell[2]
        # The rows of the layer some cell of can pass: the row test below with each plane at
        # its best cell along x (the end of i0..i1 its normal points to) is linear in the
        # row's y centre, so each plane bounds j from one side (widened by one row against
        # rounding, as below); a row outside holds no cell that passes that plane.
        ja = j0
        jb = j1
        if prune:
            for a in range(npl):
                kx = planes[a, 0]
                ky = planes[a, 1]
                bx = origin[0] + ((i1 if kx > 0.0 else i0) + 0.5) * cell[0]
                rest = (kx * bx + planes[a, 2] * cz - planes[a, 3] + abs(kx) * hx
                        + abs(ky) * hy + abs(planes[a, 2]) * hzc + planes[a, 4])
                ja, jb = _narrow(ky, rest, origin[1], cell[1], j0, j1, ja, jb)
        for j in range(ja, jb + 1):
            cy = origin[1] + (j + 0.5) * cell[1]
            # The cell test below is linear in the cell's x centre along a row: each plane
            # bounds i from one side, so the row's candidate cells form one interval, found
            # per row instead of per cell (widened by one cell against rounding; the exact
            # per-cell test still runs inside it).
            ia = i0
            ib = i1
            for a in range(npl):
                kx = planes[a, 0]
                rest = (planes[a, 1] * cy + planes[a, 2] * cz - planes[a, 3]
                        + abs(kx) * hx + abs(planes[a, 1]) * hy + abs(planes[a, 2]) * hzc
                        + planes[a, 4])
                ia, ib = _narrow(kx, rest, origin[0], cell[0], i0, i1, ia, ib)
            for i in range(ia, ib + 1):
                c = (k * dims[1] + j) * dims[0] + i
                # most cells are empty (graz: 82 % of the grid, ~88 % of those a pyramid
                # reaches): two loads instead of the plane tests
                if prune and grid.cell_start[c] == grid.cell_start[c + 1]:
                    continue
                cx = origin[0] + (i + 0.5) * cell[0]
                out = False
                for a in range(npl):
                    kx = planes[a, 0]
                    ky = planes[a, 1]
                    kz = planes[a, 2]
                    far = (kx * cx + ky * cy + kz * cz - planes[a, 3]
                           + abs(kx) * hx + abs(ky) * hy + abs(kz) * hzc)
                    if far < -planes[a, 4]:
                        out = True
                        break
                if out:
                    continue
                for q in range(grid.cell_start[c], grid.cell_start[c + 1]):
                    t = grid.cell_items[q]
                    if stamp[t] == sid:
                        continue
                    stamp[t] = sid
                    # Cheapest rejections first: in front of the light by more than off
                    # (drops the light's own triangles and the ceiling around it, which fill
                    # the cells at the pyramid's base), then above the eye's horizon
                    # somewhere (else clipped away entirely), then no side plane separates it.
                    lp = count
                    best = -np.inf
                    for v in range(3):
                        best = max(best, planes[lp, 0] * tris[t, v, 0]
                                   + planes[lp, 1] * tris[t, v, 1]
                                   + planes[lp, 2] * tris[t, v, 2] - planes[lp, 3])
                    if best <= off:
                        continue
                    up = -np.inf
                    for v in range(3):
                        up = max(up, nx * (tris[t, v, 0] - ex) + ny * (tris[t, v, 1] - ey)
                                 + nz * (tris[t, v, 2] - ez))
                    if up <= hz:
                        continue
                    keep = True
                    for a in range(count):
                        kx = planes[a, 0]
                        ky = planes[a, 1]
                        kz = planes[a, 2]
                        best = -np.inf
                        for v in range(3):
                            best = max(best, kx * tris[t, v, 0] + ky * tris[t, v, 1]
                                       + kz * tris[t, v, 2] - planes[a, 3])
                        if best < -planes[a, 4]:
                            keep = False
                            break
                    if keep:
                        # exactly: some part of it inside the pyramid (widened by the
                        # planes' margins) and above the horizon; the face planes alone
                        # keep a large triangle that passes beside the pyramid
                        for v in range(3):
                            for x in range(3):
                                sc[x, v] = tris[t, v, x]
                        keep = clip_polygon(sc, 3, cpl, count + 2) >= 3
                    if keep:
                        cand[n_c] = t
                        n_c += 1
    return n_c


@jit_leaf
def _centroid_ray(grid, ex, ey, ez, corners, count, off, ray, fan):
    """Visibility ``0.0``/``1.0`` of the light's centroid by one shadow ray from the eye: the
    fallback for a light too thin to hold a pixel centre of its own window. ``ray (2, 3)``:
    scratch for the ray's origin and direction; ``fan``: :func:`area_irradiance_stats`'
    (never aimed: it only marks the triangles the ray tested)."""
    o = ray[0]
    d = ray[1]
    o[0] = ex
    o[1] = ey
    o[2] = ez
    for k in range(3):
        s = 0.0
        for a in range(count):
            s += corners[a, k]
        d[k] = s / count - o[k]
    dl = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if not dl > 2.0 * off:
        return 1.0
    return 0.0 if any_hit_fan(grid, fan, o, d, off / dl, 1.0 - off / dl) else 1.0


@jit_leaf
def _light_window(ex, ey, ez, n, corners, count, en, hz, r, cos_thr, tab, lx, ly, lz, ev,
                  enrm, eoff, scr, qclip, xs, ys, xcross, cnt, item, zbuf, mask, xc, yc, off):
    """Steps 2–3 for the light: project it, take its window, fill it into the z-buffer.

    Returns ``(status, x0, inv_px, y0, inv_py, n_light)``: ``status`` 0 when the raster is
    ready (``item`` 0 on the light's ``n_light`` pixels, −1 elsewhere, the light ``off``
    nearer in ``zbuf``), 1 when the light is at most ``off`` above the horizon (``V = 1``,
    nothing to measure), 2 when it is too thin for a pixel centre (one centroid ray decides).
    """
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(n[0], n[1], n[2])
    cx, cy, cz, qx, qy, qz = scr[0], scr[1], scr[2], scr[3], scr[4], scr[5]
    for a in range(count):
        wx = corners[a, 0] - ex
        wy = corners[a, 1] - ey
        wz = corners[a, 2] - ez
        lx[a] = t1x * wx + t1y * wy + t1z * wz
        ly[a] = t2x * wx + t2y * wy + t2z * wz
        lz[a] = n[0] * wx + n[1] * wy + n[2] * wz
    for a in range(4):
        ev[0, a] = a if a < count else -1
    enrm[0, 0] = en[0]
    enrm[0, 1] = en[1]
    enrm[0, 2] = en[2]
    eoff[0] = en[0] * corners[0, 0] + en[1] * corners[0, 1] + en[2] * corners[0, 2]
    m, mm, c = project_element(0, ex, ey, ez, ev, enrm, eoff, lx, ly, lz, hz, cos_thr, tab,
                               cx, cy, cz, qx, qy, qz, qclip, xs, ys)
    if mm == 0:
        # at most ``off`` above the eye's horizon (F is round-off there): nothing to measure
        return 1, 0.0, 0.0, 0.0, 0.0, 0
    # ---- the window: min–max of the projected outline, inside [-1, 1]²
    x0 = np.inf
    x1 = -np.inf
    y0 = np.inf
    y1 = -np.inf
    for a in range(mm):
        x0 = min(x0, xs[a])
        x1 = max(x1, xs[a])
        y0 = min(y0, ys[a])
        y1 = max(y1, ys[a])
    x0 = max(x0, -1.0)
    y0 = max(y0, -1.0)
    x1 = min(x1, 1.0)
    y1 = min(y1, 1.0)
    if not (x1 - x0 > WINDOW_MIN and y1 - y0 > WINDOW_MIN):
        return 2, 0.0, 0.0, 0.0, 0.0, 0
    inv_px = r / (x1 - x0)
    inv_py = r / (y1 - y0)
    for i in range(r):
        xc[i] = x0 + (i + 0.5) / inv_px
        yc[i] = y0 + (i + 0.5) / inv_py
    for j in range(r):
        for i in range(r):
            q = 1.0 - xc[i] * xc[i] - yc[j] * yc[j]
            mask[j * r + i] = np.sqrt(q) if q > 0.0 else -1.0
            item[j * r + i] = -1
            zbuf[j * r + i] = -np.inf
    nlx = t1x * en[0] + t1y * en[1] + t1z * en[2]
    nly = t2x * en[0] + t2y * en[1] + t2z * en[2]
    nlz = n[0] * en[0] + n[1] * en[1] + n[2] * en[2]
    da, db, dc, de = depth_coefficients(False, qx, qy, qz, m, nlx, nly, nlz, c)
    n_light = fill_polygon(xs, ys, mm, 0, xc, yc, r, r, x0, inv_px, y0, inv_py, mask,
                           da, db, dc, de, xcross, cnt, item, zbuf)
    if n_light == 0:
        return 2, 0.0, 0.0, 0.0, 0.0, 0
    # Only the light's pixels matter: mask the rest out, and pull the light ``off`` nearer
    # (an occluder must be nearer than t_light − off to hide it, as a shadow ray's tmax).
    for idx in range(r * r):
        if item[idx] < 0:
            mask[idx] = -1.0
        else:
            near = zbuf[idx]
            zbuf[idx] = near / (1.0 - off * near) if off * near < 1.0 else np.inf
    return 0, x0, inv_px, y0, inv_py, n_light


@jit_leaf
def _occlude(grid, ex, ey, ez, n, cand, s0, s1, hz, r, cos_thr, tab, lx, ly, lz, ev, enrm,
             eoff, scr, qclip, xs, ys, xcross, cnt, item, zbuf, mask, xc, yc, x0, inv_px, y0,
             inv_py, first, stop, hid, clip, count, poly):
    """Step 3 for the occluders ``cand[s0:s1]``: each, oriented towards the eye, hides the
    light's pixels it covers nearer than the light.

    Only its part inside ``clip[:count]`` (the pyramid from the eye to the light widened by
    :data:`~daskrad.kernels.tolerances.WINDOW_CLIP_ANGLE`, :func:`clip_planes`) is projected,
    in pieces of at most 4 corners fanned from its first: a wall or a desk near the eye
    subtends tens of degrees, and projected whole it took ~120 polyline points (one per
    degree) to cover a window a few degrees wide (RenderPark's office: 120 → 20 points a
    projection, 22 % less time for the window method; ``poly (6, 8)`` is scratch).

    ``hid (H + 1,) int32``: the last ``H`` occluders that covered light pixels, in a ring
    (``hid[H]`` counts them), the hint :func:`visible_fraction` searches first at the next
    point.

    ``first`` is the first light pixel still visible (``item`` 0) before them; returns it
    after them, ``r²`` when every light pixel is hidden (the rest are then skipped when
    ``stop``). A hidden
    pixel never becomes visible again (an occluder only ever sets ``item`` 1), so ``first``
    only moves forward and the set of hidden pixels does not depend on the order occluders
    are drawn in.
    """
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(n[0], n[1], n[2])
    cx, cy, cz, qx, qy, qz = scr[0], scr[1], scr[2], scr[3], scr[4], scr[5]
    tris = grid.triangles
    for s in range(s0, s1):
        t = cand[s]
        for a in range(3):
            for k in range(3):
                poly[k, a] = tris[t, a, k]
        n_p = clip_polygon(poly, 3, clip, count)
        if n_p < 3:
            continue
        for a in range(n_p):
            wx = poly[0, a] - ex
            wy = poly[1, a] - ey
            wz = poly[2, a] - ez
            lx[a] = t1x * wx + t1y * wy + t1z * wz
            ly[a] = t2x * wx + t2y * wy + t2z * wz
            lz[a] = n[0] * wx + n[1] * wy + n[2] * wz
        ax = tris[t, 1, 0] - tris[t, 0, 0]
        ay = tris[t, 1, 1] - tris[t, 0, 1]
        az = tris[t, 1, 2] - tris[t, 0, 2]
        bx = tris[t, 2, 0] - tris[t, 0, 0]
        by = tris[t, 2, 1] - tris[t, 0, 1]
        bz = tris[t, 2, 2] - tris[t, 0, 2]
        gx = ay * bz - az * by
        gy = az * bx - ax * bz
        gz = ax * by - ay * bx
        g = np.sqrt(gx * gx + gy * gy + gz * gz)
        if not g > 0.0:
            continue
        gx /= g
        gy /= g
        gz /= g
        go = gx * tris[t, 0, 0] + gy * tris[t, 0, 1] + gz * tris[t, 0, 2]
        side = go - (gx * ex + gy * ey + gz * ez)
        if side > 0.0:
            gx, gy, gz, go = -gx, -gy, -gz, -go
        elif not side < 0.0:
            continue  # the eye in its plane: seen edge-on, it covers nothing
        enrm[0, 0] = gx
        enrm[0, 1] = gy
        enrm[0, 2] = gz
        eoff[0] = go
        nlx = t1x * gx + t1y * gy + t1z * gz
        nly = t2x * gx + t2y * gy + t2z * gz
        nlz = n[0] * gx + n[1] * gy + n[2] * gz
        covered = 0
        a = 1
        while a + 1 < n_p:      # pieces (0, a, a+1[, a+2]): shared diagonals are watertight
            ev[0, 0] = 0
            ev[0, 1] = a
            ev[0, 2] = a + 1
            ev[0, 3] = a + 2 if a + 2 < n_p else -1
            a += 2 if a + 2 < n_p else 1
            m, mm, c = project_element(0, ex, ey, ez, ev, enrm, eoff, lx, ly, lz, hz,
                                       cos_thr, tab, cx, cy, cz, qx, qy, qz, qclip, xs, ys)
            if mm == 0:
                continue
            da, db, dc, de = depth_coefficients(False, qx, qy, qz, m, nlx, nly, nlz, c)
            covered += fill_polygon(xs, ys, mm, 1, xc, yc, r, r, x0, inv_px, y0, inv_py,
                                    mask, da, db, dc, de, xcross, cnt, item, zbuf)
        if covered > 0:
            nh = hid.shape[0] - 1
            hid[hid[nh] % nh] = t
            hid[nh] += 1
            while first < r * r and item[first] != 0:
                first += 1
            if stop and first == r * r:
                return first
    return first


@jit_leaf
def _candidate_planes(planes, count, off, ex, ey, ez, n, hz, cpl):
    """``cpl[:count + 2]``: the half-spaces a candidate must reach into
    (:func:`_candidates`), as :func:`clip_polygon` takes them (``k · x − kd >= 0``): the
    pyramid's faces ``planes[:count]`` widened by their margins, its light plane
    ``planes[count]`` moved ``off`` towards the eye, and the eye's horizon ``hz`` above it
    along ``n``."""
    for a in range(count):
        for x in range(3):
            cpl[a, x] = planes[a, x]
        cpl[a, 3] = planes[a, 3] - planes[a, 4]
    for x in range(3):
        cpl[count, x] = planes[count, x]
        cpl[count + 1, x] = n[x]
    cpl[count, 3] = planes[count, 3] + off
    cpl[count + 1, 3] = n[0] * ex + n[1] * ey + n[2] * ez + hz


@jit_leaf
def _tri_cell_range(tris, t, a, origin, cell, dims):
    """:func:`_cell_range` of triangle ``t``'s extent along axis ``a``."""
    return _cell_range(min(tris[t, 0, a], min(tris[t, 1, a], tris[t, 2, a])),
                       max(tris[t, 0, a], max(tris[t, 1, a], tris[t, 2, a])),
                       origin[a], cell[a], dims[a])


@jit_leaf
def _hinted(grid, hint, ex, ey, ez, n, count, planes, hz, off, stamp, sid, cand, n_c,
            i0, i1, j0, j1, k0, k1, cpl, sc, prune=True):
    """:func:`_candidates` over the cells of the hinted occluders' bounding boxes within
    ``i0..i1 × j0..j1 × k0..k1``: the candidates of those cells, appended after ``cand[:n_c]``;
    returns the new count (:func:`visible_fraction`)."""
    found = n_c
    tris = grid.triangles
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    nh = hint.shape[0] - 1
    for h in range(min(hint[nh], nh)):
        t = hint[h]
        a0, a1 = _tri_cell_range(tris, t, 0, origin, cell, dims)
        b0, b1 = _tri_cell_range(tris, t, 1, origin, cell, dims)
        c0, c1 = _tri_cell_range(tris, t, 2, origin, cell, dims)
        a0, a1 = max(a0, i0), min(a1, i1)
        b0, b1 = max(b0, j0), min(b1, j1)
        c0, c1 = max(c0, k0), min(c1, k1)
        if a0 <= a1 and b0 <= b1 and c0 <= c1:
            found = _candidates(grid, ex, ey, ez, n[0], n[1], n[2], count, planes, hz, off,
                                stamp, sid, cand, found, a0, a1, b0, b1, c0, c1, cpl, sc,
                                prune)
    return found


@jit_leaf
def visible_fraction(grid, p, n, corners, count, en, off, hz, resolution, cos_thr, tab,
                     planes, stamp, sid, cand, lx, ly, lz, ev, enrm, eoff, scr, qclip, xs, ys,
                     xcross, cnt, item, zbuf, mask, xc, yc, slabs, hint, hid, clip, poly,
                     cpl, sc, ray, fan, prune=True):
    """``(V, n_candidates)``: the visible fraction of one light from ``p`` (module docstring).

    ``corners (count, 3)`` is the light, ``en (3,)`` its unit emitting normal (``p`` must lie
    on that side); ``hz`` the horizon clip height; ``resolution`` the window side ``R``;
    ``cos_thr, tab`` the edge splitting of :func:`daskrad.kernels.hemisphere.split_table`.
    The rest are scratch buffers sized by :func:`area_irradiance_stats`; ``sid`` must differ
    from every value in ``stamp`` (a fresh id per call). ``n_candidates`` counts the
    occluders found before ``V`` was settled (0: none at all, the light wholly visible).
    ``slabs`` is :data:`SLABS`, or 0 for the reference the tests hold it to: one search of
    the whole box, then every candidate drawn.

    The search (step 1) and the raster (step 3) are interleaved: the pyramid's box is walked
    in :data:`SLABS` slabs along its longest axis, from the eye's end, and each layer's
    candidates are drawn at once; as soon as every light pixel is hidden, ``V = 0`` and the
    rest of the box is not searched. Most vertex-light pairs of a scene with many luminaires
    are of that kind (a desk, a wall or the luminaire's own housing between them), and the
    occluders nearest the eye, found first, usually hide the light alone. Neither the set of
    candidates (every cell of the box is walked unless ``V = 0``) nor the hidden pixels
    depend on the walk order (:func:`_occlude`), so ``V`` has the same bits as a search of
    the whole box followed by the raster.

    ``hint (H + 1,) int32``: occluders that hid this light from an earlier point (a ring, as
    ``hid``; ``hint[H] == 0``: none). With the early stop, the cells of their bounding boxes
    are searched before the slabs: the housing that hides a luminaire from one point of a
    floor hides it from the next, and it lies at the light's end of the box, which the slabs
    reach last. The search only comes first; it finds candidates of the box by the same rules,
    so the candidates and ``V`` are those of the slabs alone, and no point's ``V`` depends on
    which point came before it. ``hid`` receives the occluders that covered light pixels.
    ``prune``: :func:`_candidates`'s (the same candidates).
    """
    r = resolution
    ex = p[0] + off * n[0]
    ey = p[1] + off * n[1]
    ez = p[2] + off * n[2]
    _pyramid(ex, ey, ez, corners, count, en, off, planes)
    i0, i1, j0, j1, k0, k1 = _box_cells(grid, ex, ey, ez, corners, count, off)
    # An occluder hides a pixel when it is nearer than the light by more than off along the
    # pixel's ray, i.e. higher than off·cos θ over the light's plane; cos θ is least towards
    # a corner (the light is convex), so nothing lower can hide any pixel.
    off_l = off
    for a in range(count):
        dx = ex - corners[a, 0]
        dy = ey - corners[a, 1]
        dz = ez - corners[a, 2]
        dl = np.sqrt(dx * dx + dy * dy + dz * dz)
        if dl > 0.0:
            off_l = min(off_l, off * (en[0] * dx + en[1] * dy + en[2] * dz) / dl)
    off_l = max(off_l, 0.0)
    _candidate_planes(planes, count, off_l, ex, ey, ez, n, hz, cpl)
    # the longest axis of the box in cells, walked from the eye's end
    axis = 0
    lo = i0
    hi = i1
    e_at = ex
    if j1 - j0 > hi - lo:
        axis, lo, hi, e_at = 1, j0, j1, ey
    if k1 - k0 > hi - lo:
        axis, lo, hi, e_at = 2, k0, k1, ez
    mid = grid.origin[axis] + 0.5 * (lo + hi + 1) * grid.cell[axis]
    step = 1 if e_at <= mid else -1
    stop = slabs > 0
    n_layers = hi - lo + 1
    thick = (n_layers + slabs - 1) // slabs if stop else n_layers
    n_c = 0
    ready = False
    first = 0
    x0 = inv_px = y0 = inv_py = 0.0
    n_light = 0
    hid[hid.shape[0] - 1] = 0
    # pass -1: the cells of the hinted occluders, when there are any (the early stop only)
    first_pass = -1 if stop and hint[hint.shape[0] - 1] > 0 else 0
    for q in range(first_pass, (n_layers + thick - 1) // thick):
        if q < 0:
            found = _hinted(grid, hint, ex, ey, ez, n, count, planes, hz, off_l, stamp, sid,
                            cand, n_c, i0, i1, j0, j1, k0, k1, cpl, sc, prune)
            # the hinted occluders themselves drawn first: where they hide the light alone,
            # the other candidates of their cells are not drawn (the order changes no pixel)
            nh = hint.shape[0] - 1
            w = n_c
            for s in range(n_c, found):
                t = cand[s]
                for hh in range(min(hint[nh], nh)):
                    if hint[hh] == t:
                        cand[s] = cand[w]
                        cand[w] = t
                        w += 1
                        break
        else:
            if step == 1:
                s0 = lo + q * thick
                s1 = min(s0 + thick - 1, hi)
            else:
                s1 = hi - q * thick
                s0 = max(s1 - thick + 1, lo)
            a0, a1, b0, b1, c0, c1 = i0, i1, j0, j1, k0, k1
            if axis == 0:
                a0, a1 = s0, s1
            elif axis == 1:
                b0, b1 = s0, s1
            else:
                c0, c1 = s0, s1
            found = _candidates(grid, ex, ey, ez, n[0], n[1], n[2], count, planes, hz,
                                off_l, stamp, sid, cand, n_c, a0, a1, b0, b1, c0, c1, cpl, sc,
                                prune)
        if found == n_c:
            continue
        if not ready:
            status, x0, inv_px, y0, inv_py, n_light = _light_window(
                ex, ey, ez, n, corners, count, en, hz, r, cos_thr, tab, lx, ly, lz, ev, enrm,
                eoff, scr, qclip, xs, ys, xcross, cnt, item, zbuf, mask, xc, yc, off)
            if status == 1:
                return 1.0, found
            if status == 2:
                return _centroid_ray(grid, ex, ey, ez, corners, count, off, ray, fan), found
            ready = True
            # the occluders' clip, only for a pair that draws any (most have no candidate)
            clip_planes(ex, ey, ez, corners, count, WINDOW_CLIP_ANGLE, clip)
            while first < r * r and item[first] != 0:
                first += 1
        first = _occlude(grid, ex, ey, ez, n, cand, n_c, found, hz, r, cos_thr, tab, lx, ly,
                         lz, ev, enrm, eoff, scr, qclip, xs, ys, xcross, cnt, item, zbuf, mask,
                         xc, yc, x0, inv_px, y0, inv_py, first, stop, hid, clip, count,
                         poly)
        n_c = found
        if stop and first == r * r:
            return 0.0, n_c
    if n_c == 0:
        return 1.0, 0
    n_vis = 0
    for idx in range(first, r * r):
        if item[idx] == 0:
            n_vis += 1
    return n_vis / n_light, n_c


@jit
def area_irradiance_stats(grid, faces, points, normals, off, hz, em_corners, em_count,
                          em_normal, em_radiance, resolution, edge_angle, slabs=SLABS,
                          hint=HINT, prune=True, union=UNION_RAYS):
    """Irradiance from the area lights at ``points`` by the window method, and its work.

    Parameters
    ----------
    grid : daskrad.kernels.grid.Grid
        Voxel grid over every triangle of the scene (the occluders).
    faces : Faces
        The convex planar faces (input polygons) ``grid``'s triangles tile: a light that one
        face hides wholly is settled by one ray (:func:`face_hides`) before any search.
        :func:`~daskrad.kernels.faces.no_faces`: the window method alone (the same ``V`` up
        to the raster's own error where a face hides the light).
    points, normals : (n, 3) float64
        Where (for a vertex: moved a hair into its polygon) and the unit normal of the lit
        side.
    off : float
        Shadow offset, an absolute length: the eye sits ``off`` above the point, and an
        occluder must be nearer than the light by more than ``off``.
    hz : float
        Horizon clip height above the eye (absolute length, ``HORIZON_EPS · diag``).
    em_corners : (M, 4, 3) float64
        Emitting polygons (row 3 unused for a triangle); ``em_count (M,) int64`` corners,
        ``em_normal (M, 3)`` unit emitting side, ``em_radiance (M, 3)`` ``Le``.
    resolution : int
        Side ``R`` of the window raster (``R × R`` pixels over the light's min–max window).
    edge_angle : float
        Radians a polyline piece of a projected edge may subtend (eq. 4).
    slabs : int
        :data:`SLABS`; 0 searches every pyramid whole and draws every candidate (the
        reference for the early stop: the same bits, slower).
    hint : int
        :data:`HINT` occluders remembered per light and searched first, and the face that
        last hid the light wholly tried before :func:`face_hides`'s ray; 0: neither (slower
        where housings and walls hide luminaires; the same bits, but where the remembered
        face hides a light the ray's face does not, and the raster would let a pixel through
        that face, which covers the whole light: then ``V = 0``, the exact answer, with the
        hint, and the raster's error without it).
    prune : bool
        Walk only the rows of the pyramid's box that hold a cell of it, and test only its
        cells that hold a triangle (:func:`_candidates`); ``False``: every cell (the same
        bits, slower).
    union : int
        Where no single face hides a light, try the faces several rays meet together
        (:func:`daskrad.kernels.faces.faces_hide`, ``union`` rays beyond the light's
        corners, :data:`~daskrad.kernels.faces.UNION_RAYS`); 0: no such proof (the window
        method's bits but where its raster lets a pixel through faces that cover the light).

    Returns
    -------
    H : (n, 3) float64
        ``Σ_lights π Le F V``.
    work : (n,) int64
        Candidate occluders found per point before each light's ``V`` was settled (summed over
        lights; 0: no candidate, no raster at all; 1 for a light one face hides).
    classes : (n, M) int8
        Each light's class at each point: ``LIGHT_VISIBLE`` (``F > 0`` and no candidate
        occluder in the pyramid to the light: ``V = 1`` exactly, not only to the raster's
        resolution), ``LIGHT_HIDDEN`` (``F > 0``, ``V = 0``) or ``LIGHT_TRACE``
        (:data:`daskrad.kernels.direct.LIGHT_TRACE`: neither, or a thin occluder that covers
        no pixel centre).
    """
    npts = points.shape[0]
    out = np.zeros((npts, 3))
    work = np.zeros(npts, dtype=np.int64)
    classes = np.zeros((npts, em_corners.shape[0]), dtype=np.int8)
    r = resolution
    n_tri = grid.triangles.shape[0]
    stamp = np.full(n_tri, -1, dtype=np.int64)
    cand = np.empty(n_tri, dtype=np.int32)
    planes = np.zeros((5, 5))
    clip = np.zeros((5, 5))
    poly = np.empty((6, 8))
    cpl = np.empty((6, 4))      # a candidate's half-spaces: 4 faces, light, horizon
    sc = np.empty((6, 10))      # ... a triangle clipped by 6 planes keeps at most 9 corners
    ray = np.empty((2, 3))      # the thin light's centroid ray
    fan = new_fan(grid)         # never aimed: the rays' marks (each triangle tested once)
    lx = np.empty(8)
    ly = np.empty(8)
    lz = np.empty(8)
    ev = np.zeros((1, 4), dtype=np.int32)
    enrm = np.zeros((1, 3))
    eoff = np.zeros(1)
    scr = np.zeros((6, 5))
    qclip = np.zeros(5, dtype=np.bool_)
    cap = edge_capacity(edge_angle)
    xs = np.empty(cap)
    ys = np.empty(cap)
    xcross = np.empty((r, cap))
    cnt = np.zeros(r, dtype=np.int64)
    item = np.empty(r * r, dtype=np.int32)
    zbuf = np.empty(r * r)
    mask = np.empty(r * r)
    xc = np.empty(r)
    yc = np.empty(r)
    tab = split_table(edge_angle)
    cos_thr = np.cos(edge_angle)
    # per light, the occluders that last hid it wholly (a ring of HINT, count last)
    hints = np.zeros((em_corners.shape[0], max(hint, 1) + 1), dtype=np.int32)
    hid = np.zeros(max(hint, 1) + 1, dtype=np.int32)
    # per light, the triangle whose face last hid it wholly (face_hides tries it first)
    face_hint = np.full(em_corners.shape[0], -1, dtype=np.int64)
    sid = 0
    for i in range(npts):
        p = points[i]
        n = normals[i]
        for m in range(em_corners.shape[0]):
            cntm = em_count[m]
            en = em_normal[m]
            # one-sided emitter: p strictly on its emitting side (as the shadow-ray method)
            side = (en[0] * (p[0] - em_corners[m, 0, 0]) + en[1] * (p[1] - em_corners[m, 0, 1])
                    + en[2] * (p[2] - em_corners[m, 0, 2]))
            if side <= 0.0:
                continue
            F = lambert_polygon(p[0], p[1], p[2], n[0], n[1], n[2], em_corners[m], cntm)
            if F <= 0.0:
                continue
            k = face_hides_fan(grid, faces, p[0] + off * n[0], p[1] + off * n[1],
                               p[2] + off * n[2], n, em_corners[m], cntm, en, off, hz,
                               face_hint[m], union, fan)
            if k >= 0:
                if hint > 0:
                    face_hint[m] = k
                work[i] += 1        # one occluder, and V = 0 exactly
                classes[i, m] = LIGHT_HIDDEN
                continue
            vis, n_c = visible_fraction(grid, p, n, em_corners[m], cntm, en, off, hz, r,
                                        cos_thr, tab, planes, stamp, sid, cand, lx, ly, lz,
                                        ev, enrm, eoff, scr, qclip, xs, ys, xcross, cnt, item,
                                        zbuf, mask, xc, yc, slabs, hints[m], hid, clip,
                                        poly, cpl, sc, ray, fan, prune)
            sid += 1
            if hint > 0 and vis == 0.0 and hid[hid.shape[0] - 1] > 0:
                hints[m, :] = hid
            work[i] += n_c
            if vis == 1.0 and n_c == 0:     # no occluder in the pyramid at all: exact
                classes[i, m] = LIGHT_VISIBLE
            elif vis == 0.0:
                classes[i, m] = LIGHT_HIDDEN
            for c in range(3):
                out[i, c] += np.pi * em_radiance[m, c] * F * vis
    return out, work, classes


@jit
def area_irradiance(grid, faces, points, normals, off, hz, em_corners, em_count, em_normal,
                    em_radiance, resolution, edge_angle):
    """``H (n, 3) float64`` and ``classes (n, M) int8``: :func:`area_irradiance_stats`
    without the work counts."""
    H, _, classes = area_irradiance_stats(grid, faces, points, normals, off, hz, em_corners,
                                          em_count, em_normal, em_radiance, resolution,
                                          edge_angle, SLABS)
    return H, classes


@jit
def patch_classes(points, normals, lamp_class, of, corners, count, normal):
    """The classes ``(n, M) int8`` of the emitting patches at ``points (n, 3)`` (unit
    ``normals``) from those of their lamps, ``lamp_class (n, P) int8`` (``of (M,)``: each
    patch's lamp; ``corners (M, 4, 3)``, ``count``, ``normal``: the patches).

    A lamp wholly visible (or wholly hidden) from a point is so in each of its patches; a
    class is given only to a patch the point lies in front of with ``F > 0``, as
    :func:`area_irradiance_stats` gives it, ``LIGHT_TRACE`` (0) elsewhere."""
    n = points.shape[0]
    out = np.zeros((n, of.shape[0]), np.int8)
    for i in range(n):
        p = points[i]
        q = normals[i]
        for m in range(of.shape[0]):
            c = lamp_class[i, of[m]]
            if c == 0:
                continue
            en = normal[m]
            side = (en[0] * (p[0] - corners[m, 0, 0]) + en[1] * (p[1] - corners[m, 0, 1])
                    + en[2] * (p[2] - corners[m, 0, 2]))
            if side <= 0.0:
                continue
            if lambert_polygon(p[0], p[1], p[2], q[0], q[1], q[2], corners[m], count[m]) > 0.0:
                out[i, m] = c
    return out
