"""The hemisphere-base form factor (Doi; docs/design.md §2): an item buffer on Nusselt's disc.

From a differential area at ``p`` with unit normal ``n``, every receiving element is projected
straight onto the base disc of the unit hemisphere over ``p``:

1. Local frame with ``z = n`` (:func:`daskrad.kernels.geometry.orthonormal_basis`).
2. Cull before any rasterizing: back-facing elements (receivers are one-sided: the element's
   lit side must face ``p``, ``(p - q)·n_e > 0``) and elements wholly at or below the horizon.
3. Clip against the plane ``z = h`` in 3-D (Sutherland–Hodgman), ``h = horizon_eps · diag`` a
   tiny height *above* the tangent plane, so polygons coplanar with the shooter (its own
   polygon, the rest of the floor it stands on) vanish instead of rasterizing round-off.
4. Split each edge by inserting points **on the edge in (local) world space** until each piece
   subtends less than the threshold angle (eq. 4). Instead of recursive midpoint insertion the
   number of pieces is computed directly, ``n = ceil(angle / threshold)``, and the inserted
   points are placed at *equal angles* as seen from ``p`` (law of sines:
   ``P_k = A + s_k (B - A)``, ``s_k = |A| sin(kδ) / (|A| sin(kδ) + |B| sin((n-k)δ))``,
   ``δ = angle/n``). They are still points of the world-space edge, so projecting them gives
   points exactly on the projected curve, as midpoint insertion does; but every piece subtends
   exactly ``angle/n <= threshold`` (equal steps in world space give unequal angles, the
   largest at the end nearest ``p``), and the count needs no recursion. ``s_k`` has two
   positive terms in its denominator, so it stays well conditioned even when the edge passes
   close to ``p`` (where slerp divides by ``sin(angle) ≈ 0``).
5. Project each point ``v`` to ``(x, y) = (v.x, v.y) / |v|`` (eqs. 1–3).
6. Scan-convert into an ``R × R`` item buffer over ``[-1, 1]²`` with a depth buffer; pixels
   whose centre lies outside the unit circle are ignored.

**Shape of the projected outline.** The projection of a convex planar polygon seen from a point
off its plane is a spherically convex region; its edges are great-circle arcs, and a great
circle projects orthographically onto the base as an ellipse centred on the origin with semi-major
axis 1. The region lies on one side of each arc: the side containing the pole is the inside of the
ellipse (locally convex), the other side the outside (locally *concave*). So the projection is
convex only when every edge has the pole on the polygon's side, e.g. when the polygon contains
the zenith; in general it is not. A long thin strip low over the horizon projects to a crescent
hugging the rim, which a horizontal scanline can cross twice. Hence the raster uses general
even-odd scanline filling (all edge crossings of each row, sorted), not a convex two-edge walk.
The polygon is still *simple* (the projection is injective on the upper hemisphere), so
even-odd and non-zero filling agree.

**Watertightness.** A pixel belongs to an element when its centre lies inside the polyline
(half-open rules: a crossing is counted when ``y0 <= y < y1``, a span covers centres in
``[x_left, x_right)``). Everything derived from an edge (clip points, inserted points, scanline
crossings) is computed from its canonical endpoint (:func:`lex_less`, or the lower ``y``), so two
elements sharing an edge produce bit-identical outlines and every pixel centre goes to exactly
one of them: a closed scene leaves no hole. The edge created by the horizon clip has no
neighbour on the other side; the true region extends down to the rim there, while a polyline
chord would cut inside the circle by ``1 - cos(δ/2)`` and miss the outermost pixel centres.
So a horizon edge is replaced by a chain pushed out of the disc (radial spikes at both ends and
the inserted points scaled by ``1/cos(δ/2)``, so every chord is outside the unit circle); what
lies outside the disc is ignored anyway.

**Depth.** By default exact: for pixel direction ``d = (x, y, sqrt(1 - x² - y²))`` the distance
to the element's plane is ``t = (n_e·q) / (n_e·d)``; the buffer stores ``1/t`` (larger is nearer),
which is linear in ``d`` and needs no division per pixel. ``plane_depth=True`` reproduces the
paper's eq. 5 instead: ``|v|`` interpolated over the disc by the plane through three projected
vertices (exact only as a ranking of well-separated surfaces). On the item buffer an element
replaces a pixel's winner only when it is nearer by more than :data:`DEPTH_TIE` (relative), so
ties, coplanar neighbours above all, go to the element with the lower index whatever the units
and placement, and results are deterministic.

**Weights.** Every disc pixel carries the same weight ``w = 1 / n_disc`` with ``n_disc`` the
number of pixel centres inside the unit circle (replacing the paper's ``4/(π R²)``, eqs. 6–7):
the weights sum to exactly 1, each pixel has one winner, so ``Σ_j F_j <= 1`` always, ``= 1`` in a
closed scene.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import element_planes, lex_less, orthonormal_basis, scene_diagonal
from daskrad.kernels.tolerances import DEPTH_TIE


@jit
def disc_pixels(resolution):
    """Pixel-centre coordinates and the disc mask of an ``R × R`` buffer over ``[-1, 1]²``.

    Returns
    -------
    centre : (R,) float64
        ``-1 + (2i + 1)/R``, the x (column) and y (row) coordinate of pixel centres.
    dz : (R*R,) float64
        ``sqrt(1 - x² - y²)`` at each pixel centre (row-major, ``index = row*R + column``), or
        ``-1`` where the centre lies outside the unit circle. No centre lies exactly on the
        circle: with ``a = 2i + 1 - R`` a centre is ``(a, b)/R``; for even ``R``, ``a`` and ``b``
        are odd and ``a² + b² ≡ 2 (mod 4)`` while ``R² ≡ 0``; for odd ``R`` they are even and
        ``a² + b²`` is even while ``R²`` is odd. So inside/outside is never a round-off call.
    n_disc : int
        Number of centres strictly inside the unit circle.
    """
    r = resolution
    centre = np.empty(r)
    for i in range(r):
        centre[i] = -1.0 + (2.0 * i + 1.0) / r
    dz = np.empty(r * r)
    n_disc = 0
    for j in range(r):
        for i in range(r):
            q = 1.0 - centre[i] * centre[i] - centre[j] * centre[j]
            if q > 0.0:
                dz[j * r + i] = np.sqrt(q)
                n_disc += 1
            else:
                dz[j * r + i] = -1.0
    return centre, dz, n_disc


@jit
def split_table(edge_angle):
    """Table for :func:`_emit_edge`: ``[0]`` is ``sin(thr)``, ``[k]`` is ``cos(k·thr)`` for
    ``1 <= k < K`` and ``[K] = -2`` (``K = ceil(π/thr)``: no straight edge subtends more), so the
    piece count of an edge follows from its cosine by a search, with no trigonometry per edge.
    ``edge_angle`` (= thr) in radians, in ``(0, π/2]``."""
    k_max = int(np.ceil(np.pi / edge_angle))
    tab = np.empty(k_max + 1)
    tab[0] = np.sin(edge_angle)
    for k in range(1, k_max):
        tab[k] = np.cos(k * edge_angle)
    tab[k_max] = -2.0
    return tab


@jit_leaf
def _emit_edge(ax, ay, az, bx, by, bz, horizon, cos_thr, tab, xs, ys, m):
    """Append the projected polyline of the edge ``a → b`` (without ``b``) to ``xs, ys``.

    Returns the new length. ``horizon`` marks the edge made by the horizon clip, which is
    pushed out of the disc (see the module docstring). ``tab`` is :func:`split_table`.

    The edge subtends ``θ`` at the origin; it is split into ``n = ceil(θ/thr)`` pieces (eq. 4):
    points at the angles ``k·thr`` (``k < n``) from the canonical endpoint ``c``, so every piece
    subtends ``thr`` except the last, which subtends ``θ - (n-1) thr <= thr``. The point of the
    edge at angle ``φ`` from ``c`` projects to the unit vector ``cos φ ĉ + sin φ ê`` (``ê`` the unit
    vector perpendicular to ``ĉ`` in the plane through the edge and the origin), so the
    projection (eqs. 1–3) is just its ``(x, y)``: no point on the edge, no square root per point;
    ``cos(k·thr), sin(k·thr)`` follow by the rotation recurrence (round-off ``~k ε``).
    """
    ra = np.sqrt(ax * ax + ay * ay + az * az)
    rb = np.sqrt(bx * bx + by * by + bz * bz)
    xs[m] = ax / ra
    ys[m] = ay / ra
    m += 1
    dot = ax * bx + ay * by + az * bz
    split = dot < cos_thr * ra * rb
    if not split and not horizon:
        return m
    # Canonical endpoint first, so a neighbour traversing b → a computes identical points.
    swap = lex_less(bx, by, bz, ax, ay, az)
    if swap:
        cx, cy, cz, rc = bx, by, bz, rb
        dx, dy, dz_ = ax, ay, az
    else:
        cx, cy, cz, rc = ax, ay, az, ra
        dx, dy, dz_ = bx, by, bz
    cos_theta = (cx * dx + cy * dy + cz * dz_) / (ra * rb)
    n = 1
    if split:
        # smallest n with cos θ >= cos(n·thr), i.e. θ <= n·thr (tab is decreasing)
        lo = 1
        hi = tab.shape[0] - 1
        while lo < hi:
            mid = (lo + hi) // 2
            if cos_theta >= tab[mid]:
                hi = mid
            else:
                lo = mid + 1
        n = max(lo, 2)
    if horizon:
        # Every chord of the pushed-out chain stays outside the unit circle: a chord
        # subtending φ lies cos(φ/2) from the centre, φ <= thr when split, θ otherwise.
        if split:
            scale = 1.0 / np.sqrt(0.5 * (1.0 + tab[1]))
        else:
            scale = 1.0 / np.sqrt(0.5 * (1.0 + min(cos_theta, 1.0)))
        # Radial spike out of a (in traversal order a first).
        xs[m] = scale * ax / ra
        ys[m] = scale * ay / ra
        m += 1
    else:
        scale = 1.0
    if n > 1:
        gx = cy * dz_ - cz * dy
        gy = cz * dx - cx * dz_
        gz = cx * dy - cy * dx
        g = np.sqrt(gx * gx + gy * gy + gz * gz)
        if g > 0.0:
            # ĉ and ê = (g × c) / (|g| |c|), both unit; g = c × d is normal to the edge's plane.
            ux = cx / rc
            uy = cy / rc
            ex = (gy * cz - gz * cy) / (g * rc)
            ey = (gz * cx - gx * cz) / (g * rc)
            cd = tab[1]
            sd = tab[0]
            ck = 1.0
            sk = 0.0
            for k in range(1, n):
                ck, sk = ck * cd - sk * sd, sk * cd + ck * sd
                pos = m + (n - 1 - k if swap else k - 1)
                xs[pos] = scale * (ck * ux + sk * ex)
                ys[pos] = scale * (ck * uy + sk * ey)
            m += n - 1
    if horizon:
        # Radial spike back in to b (b itself is emitted by the next edge).
        xs[m] = scale * bx / rb
        ys[m] = scale * by / rb
        m += 1
    return m


@jit
def project_scratch():
    """The scratch of :func:`project_element`, allocated once per shot: ``cx, cy, cz (4,)``
    float64 (the corners in the local frame), ``qx, qy, qz (5,)`` float64 and ``qclip (5,)``
    bool (the clipped polygon: a quad cut by the horizon keeps at most 5 corners)."""
    return (np.empty(4), np.empty(4), np.empty(4), np.empty(5), np.empty(5), np.empty(5),
            np.zeros(5, dtype=np.bool_))


@jit_leaf
def project_element(e, sx, sy, sz, elem_verts, enrm, eoff, lx, ly, lz, hz, cos_thr, tab,
                    cx, cy, cz, qx, qy, qz, qclip, xs, ys):
    """Steps 2–5 for element ``e``: cull, clip at ``z = hz``, split edges, project.

    ``lx, ly, lz : (V,) float64`` are the vertices in the shooter's local frame; ``cx, cy, cz
    (4,)`` are scratch. On return ``qx, qy, qz, qclip (5,)`` hold the ``m`` clipped corners
    (local frame; ``qclip`` marks points made by the horizon clip) and ``xs, ys`` the ``mm``
    points of the projected polyline (eqs. 1–4).

    Returns ``(m, mm, c)`` with ``c = n_e · (q - p) < 0`` for a front-facing element; ``mm = 0``
    when the element is culled (back-facing, at or below the horizon, degenerate after clip).
    """
    # c = n_e · (q - p) < 0  <=>  p on the lit side (one-sided receiver).
    c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
    if not c < 0.0:
        return 0, 0, c
    k = 4 if elem_verts[e, 3] >= 0 else 3
    zmax = -np.inf
    zmin = np.inf
    for a in range(k):
        vi = elem_verts[e, a]
        cx[a] = lx[vi]
        cy[a] = ly[vi]
        cz[a] = lz[vi]
        zmax = max(zmax, cz[a])
        zmin = min(zmin, cz[a])
    if zmax <= hz:
        return 0, 0, c
    # --- clip against z = hz (keep z > hz) ------------------------------------------------
    m = 0
    if zmin > hz:
        for a in range(k):
            qx[a] = cx[a]
            qy[a] = cy[a]
            qz[a] = cz[a]
            qclip[a] = False
        m = k
    else:
        for a in range(k):
            b = (a + 1) % k
            ina = cz[a] > hz
            if ina:
                qx[m] = cx[a]
                qy[m] = cy[a]
                qz[m] = cz[a]
                qclip[m] = False
                m += 1
            if ina != (cz[b] > hz):
                if lex_less(cx[a], cy[a], cz[a], cx[b], cy[b], cz[b]):
                    i0 = a
                    i1 = b
                else:
                    i0 = b
                    i1 = a
                t = (hz - cz[i0]) / (cz[i1] - cz[i0])
                qx[m] = cx[i0] + t * (cx[i1] - cx[i0])
                qy[m] = cy[i0] + t * (cy[i1] - cy[i0])
                qz[m] = hz
                qclip[m] = True
                m += 1
    if m < 3:
        return m, 0, c
    # --- projected polyline (eqs. 1–4) ----------------------------------------------------
    mm = 0
    for a in range(m):
        b = (a + 1) % m
        mm = _emit_edge(qx[a], qy[a], qz[a], qx[b], qy[b], qz[b],
                        qclip[a] and qclip[b], cos_thr, tab, xs, ys, mm)
    return m, mm, c


@jit_leaf
def depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c):
    """Nearness (larger is nearer) at disc point ``(x, y)`` as ``da x + db y + dc + de √(1-x²-y²)``.

    Exact (default): ``1/t = (n_l · d) / c`` with ``n_l = (nlx, nly, nlz)`` the element's normal
    in the local frame and ``c = n_e · (q - p)``. ``plane_depth``: minus the paper's eq. 5, ``|v|``
    interpolated linearly over the disc through three well-spread projected corners of the
    clipped polygon ``q (m,)``. Returns ``(da, db, dc, de)``.
    """
    if not plane_depth:
        return nlx / c, nly / c, 0.0, nlz / c
    dep0 = np.sqrt(qx[0] ** 2 + qy[0] ** 2 + qz[0] ** 2)
    x0 = qx[0] / dep0
    y0 = qy[0] / dep0
    best = -1.0
    i1 = 1
    for a in range(1, m):
        ra_ = np.sqrt(qx[a] ** 2 + qy[a] ** 2 + qz[a] ** 2)
        d2 = (qx[a] / ra_ - x0) ** 2 + (qy[a] / ra_ - y0) ** 2
        if d2 > best:
            best = d2
            i1 = a
    dep1 = np.sqrt(qx[i1] ** 2 + qy[i1] ** 2 + qz[i1] ** 2)
    x1 = qx[i1] / dep1 - x0
    y1 = qy[i1] / dep1 - y0
    best = -1.0
    i2 = 2
    for a in range(1, m):
        ra_ = np.sqrt(qx[a] ** 2 + qy[a] ** 2 + qz[a] ** 2)
        ar = abs(x1 * (qy[a] / ra_ - y0) - y1 * (qx[a] / ra_ - x0))
        if ar > best:
            best = ar
            i2 = a
    dep2 = np.sqrt(qx[i2] ** 2 + qy[i2] ** 2 + qz[i2] ** 2)
    x2 = qx[i2] / dep2 - x0
    y2 = qy[i2] / dep2 - y0
    det = x1 * y2 - x2 * y1
    if det != 0.0:
        da = ((dep1 - dep0) * y2 - (dep2 - dep0) * y1) / det
        db = (x1 * (dep2 - dep0) - x2 * (dep1 - dep0)) / det
    else:
        da = 0.0
        db = 0.0
    dc = dep0 - da * x0 - db * y0
    # nearness = -depth
    return -da, -db, -dc, 0.0


@jit_leaf
def fill_polygon(xs, ys, mm, e, xc, yc, ncol, nrow, x0, inv_px, y0, inv_py, mask,
                 da, db, dc, de, xcross, cnt, item, zbuf):
    """Even-odd scan conversion of the closed polyline ``xs, ys (mm,)`` into a z-buffer.

    The shared rasterizer of the hemisphere base and the hemicube faces. The buffer has
    ``nrow × ncol`` pixels, row-major; pixel ``(j, i)`` has its centre at ``(xc[i], yc[j])``,
    ``xc[i] = x0 + (i + 1/2) / inv_px`` (likewise ``y``). A pixel whose ``mask`` is negative is
    skipped (outside the unit disc); the nearness there is ``da x + db y + dc + de mask``
    (``mask = √(1-x²-y²)`` on the disc, so :func:`depth_coefficients` applies as is). Nearer
    (strictly larger) wins, so ties go to the element drawn first. Half-open rules make shared
    edges watertight (module docstring). ``xcross (nrow, >= mm)`` and ``cnt (nrow,)`` are
    scratch: each segment drops its crossings into the rows it spans (an edge table), so the
    cost is the number of segments plus crossings, not segments × rows. Returns the number of
    unmasked pixels covered.
    """
    ymin = np.inf
    ymax = -np.inf
    for a in range(mm):
        ymin = min(ymin, ys[a])
        ymax = max(ymax, ys[a])
    j0 = max(int(np.ceil((ymin - y0) * inv_py - 0.5)) - 1, 0)
    j1 = min(int(np.floor((ymax - y0) * inv_py - 0.5)) + 1, nrow - 1)
    if j0 > j1:
        return 0
    for j in range(j0, j1 + 1):
        cnt[j] = 0
    for a in range(mm):
        b = a + 1 if a + 1 < mm else 0
        # the lower endpoint first: a shared edge gives bit-identical crossings both ways
        if ys[a] < ys[b]:
            lo = a
            hi = b
        elif ys[b] < ys[a]:
            lo = b
            hi = a
        else:
            continue
        ylo = ys[lo]
        yhi = ys[hi]
        slope = (xs[hi] - xs[lo]) / (yhi - ylo)
        # candidate rows with one row of slack; the half-open test below decides exactly
        ja = max(int(np.ceil((ylo - y0) * inv_py - 0.5)) - 1, j0)
        jb = min(int(np.floor((yhi - y0) * inv_py - 0.5)) + 1, j1)
        for j in range(ja, jb + 1):
            ycj = yc[j]
            if ylo <= ycj < yhi:
                xcross[j, cnt[j]] = xs[lo] + (ycj - ylo) * slope
                cnt[j] += 1
    cov = 0
    for j in range(j0, j1 + 1):
        nc = cnt[j]
        if nc < 2:
            continue
        for a in range(1, nc):  # insertion sort: nc is almost always 2
            x = xcross[j, a]
            b = a - 1
            while b >= 0 and xcross[j, b] > x:
                xcross[j, b + 1] = xcross[j, b]
                b -= 1
            xcross[j, b + 1] = x
        row = j * ncol
        rowterm = db * yc[j] + dc
        for a in range(0, nc - 1, 2):
            i_lo = max(int(np.ceil((xcross[j, a] - x0) * inv_px - 0.5)), 0)
            i_hi = min(int(np.ceil((xcross[j, a + 1] - x0) * inv_px - 0.5)) - 1, ncol - 1)
            for i in range(i_lo, i_hi + 1):
                idx = row + i
                mv = mask[idx]
                if mv < 0.0:
                    continue
                cov += 1
                near = da * xc[i] + rowterm + de * mv
                if near > zbuf[idx]:
                    zbuf[idx] = near
                    item[idx] = e
    return cov


@jit_leaf
def in_frame(t1x, t1y, t1z, t2x, t2y, t2z, nx, ny, nz, x, y, z):
    """The vector ``(x, y, z)`` in the frame ``(t1, t2, n)``: its three dot products."""
    return (t1x * x + t1y * y + t1z * z, t2x * x + t2y * y + t2z * z,
            nx * x + ny * y + nz * z)


@jit_leaf
def frame_vertices(sx, sy, sz, t1x, t1y, t1z, t2x, t2y, t2z, nx, ny, nz, vertices, lx, ly,
                   lz):
    """``vertices (V, 3)`` relative to ``s`` in the frame ``(t1, t2, n)``, into
    ``lx, ly, lz (V,)``."""
    for v in range(vertices.shape[0]):
        lx[v], ly[v], lz[v] = in_frame(t1x, t1y, t1z, t2x, t2y, t2z, nx, ny, nz,
                                       vertices[v, 0] - sx, vertices[v, 1] - sy,
                                       vertices[v, 2] - sz)


@jit_leaf
def local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz):
    """Vertices in the shooter's frame ``(t1, t2, n)`` into ``lx, ly, lz (V,)``; returns the
    tangents ``(t1x, t1y, t1z, t2x, t2y, t2z)``."""
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(snx, sny, snz)
    frame_vertices(sx, sy, sz, t1x, t1y, t1z, t2x, t2y, t2z, snx, sny, snz, vertices, lx, ly,
                   lz)
    return t1x, t1y, t1z, t2x, t2y, t2z


@jit
def _shoot(sx, sy, sz, snx, sny, snz, vertices, elem_verts, enrm, eoff, hz,
           resolution, centre, dz, cos_thr, tab, plane_depth,
           lx, ly, lz, item, zbuf, xs, ys, xcross, cnt, won, covered, visible, gx, gy, gz,
           drawn):
    """One shot: fill ``won (E,)``, ``covered (E,)`` (int32) and ``visible (E,)`` (float64,
    the bilinear visible fraction at the centroid's direction of every element drawn), all
    zeroed by the caller; ``gx, gy, gz (E,) float64`` and ``drawn (E,) int32`` are scratch."""
    r = resolution
    half_r = 0.5 * r
    t1x, t1y, t1z, t2x, t2y, t2z = local_frame(sx, sy, sz, snx, sny, snz, vertices, lx, ly, lz)
    for k in range(r * r):
        item[k] = -1
        zbuf[k] = -np.inf
    cx, cy, cz, qx, qy, qz, qclip = project_scratch()
    rq = np.empty(5)
    n_elem = elem_verts.shape[0]
    n_small = 0
    # The per-element path below is written out in one loop (the steps of project_element,
    # depth_coefficients and fill_polygon, same arithmetic in the same order; only the depth
    # test adds the DEPTH_TIE margin): a call passing a dozen arrays costs more than the work
    # for a typical element (measured: 130-200 ns per call, Table 2 118 -> 36 ms).
    for e in range(n_elem):
        # --- cull (step 2): back-facing, wholly at or below the horizon -----------------
        c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
        if not c < 0.0:
            continue
        k = 4 if elem_verts[e, 3] >= 0 else 3
        zmax = -np.inf
        zmin = np.inf
        for a in range(k):
            vi = elem_verts[e, a]
            cx[a] = lx[vi]
            cy[a] = ly[vi]
            cz[a] = lz[vi]
            zmax = max(zmax, cz[a])
            zmin = min(zmin, cz[a])
        if zmax <= hz:
            continue
        # --- clip against z = hz (step 3), as in project_element -----------------------
        m = 0
        if zmin > hz:
            for a in range(k):
                qx[a] = cx[a]
                qy[a] = cy[a]
                qz[a] = cz[a]
                qclip[a] = False
            m = k
        else:
            for a in range(k):
                b = a + 1 if a + 1 < k else 0
                ina = cz[a] > hz
                if ina:
                    qx[m] = cx[a]
                    qy[m] = cy[a]
                    qz[m] = cz[a]
                    qclip[m] = False
                    m += 1
                if ina != (cz[b] > hz):
                    if lex_less(cx[a], cy[a], cz[a], cx[b], cy[b], cz[b]):
                        i0 = a
                        i1 = b
                    else:
                        i0 = b
                        i1 = a
                    t = (hz - cz[i0]) / (cz[i1] - cz[i0])
                    qx[m] = cx[i0] + t * (cx[i1] - cx[i0])
                    qy[m] = cy[i0] + t * (cy[i1] - cy[i0])
                    qz[m] = hz
                    qclip[m] = True
                    m += 1
        if m < 3:
            continue
        # --- projected polyline (steps 4-5): an edge that needs no split and is no horizon
        # edge contributes its first point only; the others go through _emit_edge ------------
        for a in range(m):
            rq[a] = np.sqrt(qx[a] * qx[a] + qy[a] * qy[a] + qz[a] * qz[a])
        mm = 0
        for a in range(m):
            b = a + 1 if a + 1 < m else 0
            dot = qx[a] * qx[b] + qy[a] * qy[b] + qz[a] * qz[b]
            if dot < cos_thr * rq[a] * rq[b] or (qclip[a] and qclip[b]):
                mm = _emit_edge(qx[a], qy[a], qz[a], qx[b], qy[b], qz[b],
                                qclip[a] and qclip[b], cos_thr, tab, xs, ys, mm)
            else:
                xs[mm] = qx[a] / rq[a]
                ys[mm] = qy[a] / rq[a]
                mm += 1
        nlx = t1x * enrm[e, 0] + t1y * enrm[e, 1] + t1z * enrm[e, 2]
        nly = t2x * enrm[e, 0] + t2y * enrm[e, 1] + t2z * enrm[e, 2]
        nlz = snx * enrm[e, 0] + sny * enrm[e, 1] + snz * enrm[e, 2]
        if plane_depth:
            da, db, dc, de = depth_coefficients(plane_depth, qx, qy, qz, m, nlx, nly, nlz, c)
        else:
            da = nlx / c
            db = nly / c
            dc = 0.0
            de = nlz / c
        # --- scan conversion (step 6): fill_polygon's body, written out -----------------
        cov = 0
        ymin = np.inf
        ymax = -np.inf
        for a in range(mm):
            ymin = min(ymin, ys[a])
            ymax = max(ymax, ys[a])
        j0 = max(int(np.ceil((ymin + 1.0) * half_r - 0.5)) - 1, 0)
        j1 = min(int(np.floor((ymax + 1.0) * half_r - 0.5)) + 1, r - 1)
        if j0 <= j1:
            for j in range(j0, j1 + 1):
                cnt[j] = 0
            for a in range(mm):
                b = a + 1 if a + 1 < mm else 0
                if ys[a] < ys[b]:
                    lo = a
                    hi = b
                elif ys[b] < ys[a]:
                    lo = b
                    hi = a
                else:
                    continue
                ylo = ys[lo]
                yhi = ys[hi]
                slope = (xs[hi] - xs[lo]) / (yhi - ylo)
                ja = max(int(np.ceil((ylo + 1.0) * half_r - 0.5)) - 1, j0)
                jb = min(int(np.floor((yhi + 1.0) * half_r - 0.5)) + 1, j1)
                for j in range(ja, jb + 1):
                    ycj = centre[j]
                    if ylo <= ycj < yhi:
                        xcross[j, cnt[j]] = xs[lo] + (ycj - ylo) * slope
                        cnt[j] += 1
            for j in range(j0, j1 + 1):
                nc = cnt[j]
                if nc < 2:
                    continue
                for a in range(1, nc):
                    x = xcross[j, a]
                    b = a - 1
                    while b >= 0 and xcross[j, b] > x:
                        xcross[j, b + 1] = xcross[j, b]
                        b -= 1
                    xcross[j, b + 1] = x
                row = j * r
                rowterm = db * centre[j] + dc
                for a in range(0, nc - 1, 2):
                    i_lo = max(int(np.ceil((xcross[j, a] + 1.0) * half_r - 0.5)), 0)
                    i_hi = min(int(np.ceil((xcross[j, a + 1] + 1.0) * half_r - 0.5)) - 1, r - 1)
                    for i in range(i_lo, i_hi + 1):
                        idx = row + i
                        mv = dz[idx]
                        if mv < 0.0:
                            continue
                        cov += 1
                        near = da * centre[i] + rowterm + de * mv
                        zo = zbuf[idx]
                        # nearer by more than round-off: coplanar elements (neighbours on
                        # one wall overlapping by a polyline's width along a T-junction)
                        # tie, and a tie stays with the element drawn first whatever the
                        # units, instead of going to whichever round-off favours
                        if near > zo and (zo == -np.inf or near - zo > DEPTH_TIE * abs(zo)):
                            zbuf[idx] = near
                            item[idx] = e
        covered[e] = cov
        # Remember the direction of the (clipped) centroid for the visibility test below,
        # once the buffer is complete: every element drawn gets it, not only those covering
        # no pixel centre, since an element thinner than the outline's chord error (a
        # sliver) covers centres that are chord artefacts, not its own (hemisphere_rows).
        mx = 0.0
        my = 0.0
        mz = 0.0
        for a in range(m):
            mx += qx[a]
            my += qy[a]
            mz += qz[a]
        gx[n_small] = mx
        gy[n_small] = my
        gz[n_small] = mz
        drawn[n_small] = e
        n_small += 1
    for k in range(r * r):
        if item[k] >= 0:
            won[item[k]] += 1
    # Every element drawn (the anti-aliased method uses it for the small ones, those covering no
    # pixel centre or less than a pixel of true area): the visible fraction along the direction
    # ``d`` of their centroid, interpolated bilinearly between the 2 x 2 pixel centres around ``d``.
    # At each of those pixels the element counts visible when no other element's plane lies nearer
    # along ``d`` (the pixel's winner), or when the pixel holds no information (outside the disc, or
    # empty). Bilinear weights make the fraction continuous in ``d``: a direction on a pixel
    # boundary weighs both sides by 1/2, so round-off (a change of units, a shift of the scene)
    # moves it by O(ε·R), where the nearest pixel alone flipped between 0 and 1 (issue 7). Both
    # nearnesses are exact (1/t along the same direction), also with plane_depth, so a small element
    # lying in the plane of a pixel's winner (a neighbour on the same wall) ties and counts visible
    # there.
    for slot in range(n_small):
        e = drawn[slot]
        if covered[e] > 0 and won[e] == covered[e]:
            # in front at every pixel centre it covers: visible, no test needed (most
            # elements; the test costs ~25 ns an element, 10 % of Table 2)
            visible[e] = 1.0
            continue
        mx = gx[slot]
        my = gy[slot]
        mz = gz[slot]
        norm = np.sqrt(mx * mx + my * my + mz * mz)
        if not norm > 0.0:
            continue
        mx /= norm
        my /= norm
        mz /= norm
        own = _nearness(e, mx, my, mz, sx, sy, sz, enrm, eoff, t1x, t1y, t1z, t2x, t2y, t2z,
                        snx, sny, snz)
        # pixel-centre coordinates: centre i sits at u = i
        pu = (mx + 1.0) * half_r - 0.5
        pv = (my + 1.0) * half_r - 0.5
        fi = np.floor(pu)
        fj = np.floor(pv)
        fx = pu - fi
        fy = pv - fj
        i0 = int(fi)
        j0 = int(fj)
        frac = 0.0
        last = -2
        last_vis = 1.0
        for dj in range(2):
            wy = fy if dj else 1.0 - fy
            if wy == 0.0:
                continue
            j = min(max(j0 + dj, 0), r - 1)
            for di in range(2):
                wx = fx if di else 1.0 - fx
                if wx == 0.0:
                    continue
                i = min(max(i0 + di, 0), r - 1)
                w = item[j * r + i]
                if dz[j * r + i] < 0.0 or w < 0:
                    vis = 1.0  # no information there (outside the disc, or an empty pixel)
                elif w == last:
                    vis = last_vis
                else:
                    other = _nearness(w, mx, my, mz, sx, sy, sz, enrm, eoff, t1x, t1y, t1z,
                                      t2x, t2y, t2z, snx, sny, snz)
                    vis = 0.0 if other > own * (1.0 + DEPTH_TIE) else 1.0
                    last = w
                    last_vis = vis
                frac += wx * wy * vis
        visible[e] = frac


@jit_leaf
def _nearness(e, dx, dy, dz_, sx, sy, sz, enrm, eoff, t1x, t1y, t1z, t2x, t2y, t2z,
              snx, sny, snz):
    """``1/t`` along the local unit direction ``d`` to the plane of element ``e`` (<= 0 when
    the plane lies behind)."""
    c = eoff[e] - (enrm[e, 0] * sx + enrm[e, 1] * sy + enrm[e, 2] * sz)
    if c == 0.0:
        return 0.0
    nlx, nly, nlz = in_frame(t1x, t1y, t1z, t2x, t2y, t2z, snx, sny, snz, enrm[e, 0],
                             enrm[e, 1], enrm[e, 2])
    return (nlx * dx + nly * dy + nlz * dz_) / c


@jit_leaf
def edge_capacity(edge_angle):
    """Length of the polyline buffers: a straight edge subtends < 180°, so it gives at most
    ``ceil(π/thr)`` pieces, plus the two spikes of a horizon edge; a clipped quad has at most
    5 edges."""
    per_edge = int(np.ceil(np.pi / edge_angle)) + 3
    return 5 * per_edge + 8


@jit
def hemisphere_visibility(points, normals, vertices, elem_verts, enrm, eoff, resolution,
                          edge_angle, plane_depth, horizon_eps):
    """:func:`hemisphere_shots` plus ``visible : (S, E) float64`` in ``[0, 1]``; ``enrm (E, 3),
    eoff (E,)`` are the elements' planes (:func:`element_planes`), computed once per mesh by
    the caller (per call they were an eighth of a one-point row of a 114k-element office).

    ``visible[s, e]`` is set for every element that faces the point and reaches above the
    horizon (0 for the culled ones): the fraction of the 2 x 2 pixels around the direction of
    its centroid where the element is in front (a coplanar winner ties and counts visible),
    weighted bilinearly by that direction's position, so it is continuous in the geometry (see
    :func:`_shoot`). It lets the anti-aliased method give elements too small for their pixel
    count to mean anything (no pixel centre covered, or less than
    :data:`daskrad.tolerances.SUBPIXEL_AREA_PX` of true area) their analytic form factor times
    that fraction.

    Returns ``(won, covered, n_disc, visible)``.
    """
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    n_vert = vertices.shape[0]
    r = resolution
    hz = max(horizon_eps * scene_diagonal(vertices), 1e-300)
    centre, dz, n_disc = disc_pixels(r)
    # Buffers allocated once per call, reused by every shot and element.
    item = np.empty(r * r, dtype=np.int32)
    zbuf = np.empty(r * r)
    lx = np.empty(n_vert)
    ly = np.empty(n_vert)
    lz = np.empty(n_vert)
    cap = edge_capacity(edge_angle)
    xs = np.empty(cap)
    ys = np.empty(cap)
    xcross = np.empty((r, cap))
    cnt = np.zeros(r, dtype=np.int64)
    gx = np.empty(n_elem)
    gy = np.empty(n_elem)
    gz = np.empty(n_elem)
    drawn = np.empty(n_elem, dtype=np.int32)
    won = np.zeros((n_shot, n_elem), dtype=np.int32)
    covered = np.zeros((n_shot, n_elem), dtype=np.int32)
    visible = np.zeros((n_shot, n_elem))
    cos_thr = np.cos(edge_angle)
    tab = split_table(edge_angle)
    for s in range(n_shot):
        _shoot(points[s, 0], points[s, 1], points[s, 2],
               normals[s, 0], normals[s, 1], normals[s, 2],
               vertices, elem_verts, enrm, eoff, hz, r, centre, dz, cos_thr, tab,
               plane_depth, lx, ly, lz, item, zbuf, xs, ys, xcross, cnt, won[s], covered[s],
               visible[s], gx, gy, gz, drawn)
    return won, covered, n_disc, visible


@jit
def hemisphere_shots(points, normals, vertices, elem_verts, resolution, edge_angle,
                     plane_depth, horizon_eps):
    """Hemisphere-base item buffer from each shooting point to all elements (docs/design.md §2).

    Parameters
    ----------
    points : (S, 3) float64
        Positions of the differential shooting areas.
    normals : (S, 3) float64
        Their unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        Corner indices, counter-clockwise seen from the lit side (planar convex polygons);
        ``-1`` in column 3 for a triangle.
    resolution : int
        Side ``R`` of the item buffer over ``[-1, 1]²``.
    edge_angle : float
        Threshold angle, **radians**, each polyline piece of a projected edge may subtend
        (eq. 4).
    plane_depth : bool
        Depth by the paper's eq. 5 instead of the exact ray–plane distance.
    horizon_eps : float
        Clip height above the tangent plane, relative to the scene's bounding-box diagonal.

    Returns
    -------
    won : (S, E) int32
        Pixels each element owns after hidden-surface removal; ``F = won / n_disc``.
    covered : (S, E) int32
        Disc pixels each element covers before the depth test (``won <= covered``).
    n_disc : int
        Pixel centres inside the unit circle; every disc pixel weighs ``1/n_disc``, so the
        weights sum to exactly 1 (``Σ_j F_j <= 1``, ``= 1`` in a closed scene).
    """
    enrm, eoff = element_planes(vertices, elem_verts)
    won, covered, n_disc, _ = hemisphere_visibility(points, normals, vertices, elem_verts,
                                                    enrm, eoff, resolution, edge_angle,
                                                    plane_depth, horizon_eps)
    return won, covered, n_disc


@jit
def conserve_rows(rows, closed):
    """Scale ``rows (S, E) float64`` in place so a shot never sends more than the shooter
    holds (docs/design.md §2), and return them: a row summing to more than 1 is scaled to 1,
    a row marked in ``closed (S,) bool`` (every disc pixel won: every direction above the
    horizon sees some element, so the exact row sums to 1) to exactly 1 when it sums to more
    than 0. Each row is summed in element order, the same on any split."""
    for s in range(rows.shape[0]):
        total = 0.0
        for e in range(rows.shape[1]):
            total += rows[s, e]
        if (closed[s] and total > 0.0) or total > 1.0:
            scale = 1.0 / max(total, 1e-300)
            for e in range(rows.shape[1]):
                rows[s, e] *= scale
    return rows


@jit
def anti_aliased_rows(won, covered, visible, lam, n_disc, subpixel_px):
    """``(S, E) float64``: the default method's rows from the raster's counts and Lambert's
    factors (:func:`daskrad.formfactor.methods.hemisphere_rows` gives the why), conserved
    (:func:`conserve_rows`, closed where the shooter won every disc pixel).

    ``F = lam · won / covered`` where the element covers a pixel centre and at least
    ``subpixel_px`` pixels of true area (``lam · n_disc``), else ``lam · visible``.
    ``won, covered : (S, E) int32``, ``visible, lam : (S, E) float64``. One pass over the
    rows instead of a dozen array operations, without the GIL (graz: ~6 ms of numpy a row of
    89,160 elements, held under the GIL the Dask workers share).
    """
    n_shot, n_elem = won.shape
    out = np.empty((n_shot, n_elem))
    closed = np.zeros(n_shot, dtype=np.bool_)
    for s in range(n_shot):
        n_won = 0
        for e in range(n_elem):
            w = won[s, e]
            n_won += w
            c = covered[s, e]
            f = lam[s, e]
            if c > 0 and not (f * n_disc < subpixel_px):
                out[s, e] = f * (w / max(c, 1))
            else:
                out[s, e] = f * visible[s, e]
        closed[s] = n_won == n_disc
    return conserve_rows(out, closed)
