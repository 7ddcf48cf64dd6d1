"""One convex face that hides a whole area light (issue 12, item 5: the direct light of
interiors with many luminaires).

Most vertex-light pairs of a furnished interior are wholly hidden (RenderPark's office: 83 %),
and about two thirds of those by a single wall, floor or desk top. :func:`face_hides` proves
such a pair hidden by one ray and a few point-in-polygon tests, exactly, where the window
method (:mod:`daskrad.kernels.arealight`) searches the pyramid to the light and rasterizes its
occluders. Where it proves nothing, the window method runs as before. The face that last hid a
light is tried first, without the ray (:func:`face_hides`'s ``hint``): RenderPark's office's
direct pass (``graz.obj``, 293,004 vertices × 32 emitter patches, 2 threads, two alternated
runs each) went 25.3 / 25.1 → 21.4 / 21.2 s, and the one vertex whose irradiance changed
(1.5e-4 → 0) lost the raster's error: 200 × 200 shadow rays find that light hidden.

Not used by the shadow rays: at RenderPark's office's vertices it saved 7 % of the ``rays``
area method's time (hidden lights block their rays early, cheaply), and at the per-pixel
pass's hits, mostly lit by the lights of the room in view, it proved 4 % of the pairs and
cost more than it saved (+4 %).

A face is an input polygon (a triangle or a planar convex quad). The direct pass's occluder
grid holds the polygons' own triangles, one piece per face
(:func:`daskrad.preprocess.occluders`); over a grid of the elements, a face is the union of its
patches (:func:`daskrad.direct.polygon_faces`).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.geometry import within_edges
from daskrad.kernels.grid import NO_FAN, closest_hit_fan


class Faces(NamedTuple):
    """The convex planar faces the occluder grid's triangles tile (:func:`face_hides`).

    tri_face : (T,) int32
        The face of each of the grid's triangles; ``-1``: none (proves nothing).
    start : (F + 1,) int64
        Face ``f`` is the union of the convex pieces ``start[f]:start[f + 1]``.
    corners : (P, 4, 3) float64
        The pieces (the polygon itself, or its patches), counter-clockwise about their
        face's normal; ``count (P,) int64`` corners each (3 or 4).
    """

    tri_face: np.ndarray
    start: np.ndarray
    corners: np.ndarray
    count: np.ndarray


def no_faces(n_triangles: int) -> Faces:
    """Faces that prove nothing: the window method alone."""
    return Faces(np.full(n_triangles, -1, np.int32), np.zeros(1, np.int64),
                 np.zeros((0, 4, 3)), np.zeros(0, np.int64))


#: Rays :func:`faces_hide` casts at most beyond the light's corners, each to a part of the
#: light no face found so far hides (0: no proof by several faces).
UNION_RAYS = 4

#: Room for the parts of the light not yet hidden (:func:`faces_hide`): pieces, corners each.
_PIECES = 48
_CORNERS = 24


@jit_leaf
def _in_face(faces, f, x, y, z, nx, ny, nz, eps):
    """Whether the point ``(x, y, z)`` in face ``f``'s plane (unit normal ``n``) lies in one of
    its pieces, within ``eps`` of its edges (a point on an edge two pieces share is in both)."""
    for q in range(faces.start[f], faces.start[f + 1]):
        if within_edges(faces.corners[q], faces.count[q], x, y, z, nx, ny, nz, -eps):
            return True
    return False


@jit
def face_hides(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, hint=-1,
               union=UNION_RAYS):
    """:func:`face_hides_fan` with rays that remember the last four triangles they tested
    (:data:`daskrad.kernels.grid.NO_FAN`): the same answer."""
    return face_hides_fan(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, hint,
                          union, NO_FAN)


@jit
def face_hides_fan(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, hint, union, fan):
    """The triangle of a convex face of the scene that hides the whole light from the eye
    ``e``, or -1 when none is found.

    ``faces``: :class:`Faces` (none: -1 at once). The ray from ``e`` to the light's first
    corner is traced to its closest hit, a triangle of face ``f``; then
    :func:`face_proves`. ``hint``: a triangle of the grid whose face is tried first, without
    the ray (the face that last hid this light from a point nearby: a wall hides a luminaire
    of the next room from every vertex of the wall, and one ray costs as much as 40 tests of
    a face); -1: none. Any face that passes the test hides the light, whether or not it is
    the nearest, so a proof through the hint is as exact as one through the ray. What the hint
    changes: the time, and, where the remembered face proves a light hidden that the ray's
    face does not, ``V = 0`` instead of the window method's raster (which can let a pixel
    through a face that covers the whole light).

    One ray and three point-in-face tests instead of the pyramid's search: in a furnished
    interior most vertex-light pairs are wholly hidden (RenderPark's office: 83 %) and about
    two thirds of those by a single wall, floor or desk top. Where no single face does, and
    the first corner's crossing lies above the horizon, the faces several rays meet may
    together (:func:`faces_hide`, ``union`` rays beyond the corners; 0: not tried); the
    first corner's triangle is then the answer (the hint the caller remembers). -1 whenever
    it cannot prove it; the caller then runs the window method.

    ``fan``: scratch of :func:`daskrad.kernels.grid.new_fan` for ``grid``, never aimed (it
    culls nothing): its rays test each triangle once, however many cells hold it (the same
    answers).
    """
    if faces.corners.shape[0] == 0:
        return -1
    for a in range(count):
        if not (n[0] * (corners[a, 0] - ex) + n[1] * (corners[a, 1] - ey)
                + n[2] * (corners[a, 2] - ez)) > hz:
            return -1
    if hint >= 0 and face_proves(grid, faces, hint, ex, ey, ez, n, corners, count, en, off,
                                 hz, -1.0):
        return hint
    o = np.empty(3)
    d = np.empty(3)
    o[0] = ex
    o[1] = ey
    o[2] = ez
    d[0] = corners[0, 0] - ex
    d[1] = corners[0, 1] - ey
    d[2] = corners[0, 2] - ez
    t, k, _, _ = closest_hit_fan(grid, fan, o, d, 0.0, 1.0)
    if k < 0:
        return -1
    if face_proves(grid, faces, k, ex, ey, ez, n, corners, count, en, off, hz, t):
        return k
    # several faces, when the first one's crossing is above the horizon (below it, the eye
    # sits at a junction with that face: the window method's rule, whose clipping decides)
    if (union > 0 and t * (n[0] * d[0] + n[1] * d[1] + n[2] * d[2]) > hz
            and faces_hide(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, k,
                           union, fan)):
        return k
    return -1


@jit_leaf
def _plane(tri, ex, ey, ez):
    """The unit normal ``(fx, fy, fz)`` of triangle ``tri (3, 3)`` (its winding's side) and
    the signed distance ``fd`` of its plane from ``e`` along it; all zero for a degenerate
    triangle (no plane: the callers prove nothing with it)."""
    ux = tri[1, 0] - tri[0, 0]
    uy = tri[1, 1] - tri[0, 1]
    uz = tri[1, 2] - tri[0, 2]
    vx = tri[2, 0] - tri[0, 0]
    vy = tri[2, 1] - tri[0, 1]
    vz = tri[2, 2] - tri[0, 2]
    fx = uy * vz - uz * vy
    fy = uz * vx - ux * vz
    fz = ux * vy - uy * vx
    fl = np.sqrt(fx * fx + fy * fy + fz * fz)
    if not fl > 0.0:
        return 0.0, 0.0, 0.0, 0.0
    fx /= fl
    fy /= fl
    fz /= fl
    fd = fx * tri[0, 0] + fy * tri[0, 1] + fz * tri[0, 2] - (fx * ex + fy * ey + fz * ez)
    return fx, fy, fz, fd


@jit_leaf
def face_proves(grid, faces, k, ex, ey, ez, n, corners, count, en, off, hz, t0):
    """Whether the face of the grid's triangle ``k`` hides the whole light from ``e``.

    When every corner's ray crosses the face's plane inside the face, above the horizon
    (height over ``e`` along ``n`` above ``hz``) and nearer than the light, the plane
    separates ``e`` from the whole light and the pyramid's section by it, the convex hull of
    the crossings, lies in the convex face: every ray from ``e`` to the light is blocked,
    ``V = 0`` exactly. The gap to the light along any such ray is at least ``(1 − max t) h``,
    ``t`` the crossings' parameters (``1/t`` is affine over the light, so ``t`` is largest at
    a corner) and ``h`` the eye's height over the light's plane; it must exceed ``2 off`` (the
    raster's rule: an occluder hides only what lies more than ``off`` in front of the light).
    The caller has checked that the light lies wholly above the horizon, so that the window
    method would see all of it.

    ``t0``: the parameter where the ray to the first corner hits triangle ``k`` (that corner's
    crossing, known inside the face), or negative to test that corner like the others.
    """
    f = faces.tri_face[k]
    if f < 0:
        return False
    fx, fy, fz, fd = _plane(grid.triangles[k], ex, ey, ez)
    if fx == 0.0 and fy == 0.0 and fz == 0.0:
        return False
    t_max = 0.0
    for a in range(count):
        dx = corners[a, 0] - ex
        dy = corners[a, 1] - ey
        dz = corners[a, 2] - ez
        if a > 0 or not t0 >= 0.0:
            dn = fx * dx + fy * dy + fz * dz
            if dn == 0.0:
                return False
            t = fd / dn
            if not (t > 0.0 and t < 1.0):
                return False
            if not _in_face(faces, f, ex + t * dx, ey + t * dy, ez + t * dz, fx, fy, fz,
                            grid.eps):
                return False
        else:
            t = t0
        if not t * (n[0] * dx + n[1] * dy + n[2] * dz) > hz:
            return False
        t_max = max(t_max, t)
    h = en[0] * (ex - corners[0, 0]) + en[1] * (ey - corners[0, 1]) + en[2] * (ez - corners[0, 2])
    return (1.0 - t_max) * h > 2.0 * off



@jit
def faces_hide(grid, faces, ex, ey, ez, n, corners, count, en, off, hz, k0, extra, fan):
    """Whether several faces of the scene together hide the whole light from the eye ``e``:
    the faces of the grid's triangle ``k0`` (the first corner's hit), of the closest hits of
    the rays to the light's other corners, and of up to ``extra`` rays more, each to the
    centroid of a part of the light no face found so far hides. A free ray, or a ray that
    meets a face already counted where it hides nothing, ends the proof (False).

    What a face hides is exact: the light points ``q`` whose segment from ``e`` crosses the
    face's plane inside the face (within ``grid.eps`` of its edges, as the ray test counts a
    hit), above the horizon and more than ``2 off`` before the light (the rules of
    :func:`face_proves`). Each rule is a half-space in ``q`` (the crossing's parameter
    ``t = fd / f·(q − e)`` has the sign of ``fd`` there, so ``t < 1 − 2 off / h`` and
    ``t · n·(q − e) > hz`` are linear in ``q``; the edges are the planes through ``e`` and
    each edge, tilted so that the margin is ``eps`` within the face's plane), so a face
    hides a convex part of the light. The parts left are the light
    less each such convex set, in convex pieces (clipped by each half-space in turn:
    Sutherland–Hodgman), and the light is hidden when none is left (pieces of area below
    ``eps²`` are none). A single face that hides it all is :func:`face_proves`; this is for
    the lights behind two walls meeting at a corner, a wall and a ceiling, a cabinet's side
    and its top (RenderPark's office: 28 % of the pairs the window method found hidden and
    no single face does; most of the others have the eye at a junction with a face, where
    the window method's rules decide)."""
    h = en[0] * (ex - corners[0, 0]) + en[1] * (ey - corners[0, 1]) + en[2] * (ez - corners[0, 2])
    if not h > 0.0:
        # the eye at or behind the light's plane (possible when the vertex is within
        # off of it): c1 would exceed 1 and let faces beyond the light count
        return False
    c1 = 1.0 - 2.0 * off / h
    if not c1 > 0.0:
        return False
    cur = np.empty((_PIECES, _CORNERS, 3))
    cc = np.zeros(_PIECES, np.int64)
    nxt = np.empty((_PIECES, _CORNERS, 3))
    nc = np.zeros(_PIECES, np.int64)
    rest = np.empty((_CORNERS, 3))
    tmp = np.empty((_CORNERS, 3))
    hs = np.empty((6, 4))
    used = np.empty(count + extra, np.int64)
    for a in range(count):
        for x in range(3):
            cur[0, a, x] = corners[a, x]
    cc[0] = count
    npc = 1
    tiny = grid.eps * grid.eps
    o = np.empty(3)
    d = np.empty(3)
    o[0] = ex
    o[1] = ey
    o[2] = ez
    n_used = 0
    for a in range(count + extra):
        if a == 0:
            k = k0
        else:
            if a < count:
                for x in range(3):
                    d[x] = corners[a, x] - o[x]
            else:                       # the centroid of the first piece left
                for x in range(3):
                    s = 0.0
                    for z in range(cc[0]):
                        s += cur[0, z, x]
                    d[x] = s / cc[0] - o[x]
            k = closest_hit_fan(grid, fan, o, d, 0.0, 1.0)[1]
            if k < 0:
                return False
        f = faces.tri_face[k]
        if f < 0:
            return False
        seen = False
        for b in range(n_used):
            if used[b] == f:
                seen = True
        if seen:
            if a >= count:              # it hides nothing of that piece: no proof
                return False
            continue
        used[n_used] = f
        n_used += 1
        npc = _less_face(grid, faces, k, ex, ey, ez, n, c1, hz, cur, cc, npc, hs, nxt, nc,
                         rest, tmp, tiny)
        if npc <= 0:
            return npc == 0
    return False


@jit_leaf
def _less_face(grid, faces, k, ex, ey, ez, n, c1, hz, cur, cc, npc, hs, nxt, nc, rest, tmp,
               tiny):
    """The pieces ``cur[:npc]`` (``cc`` corners each) less the part of the light the face of
    grid triangle ``k`` hides (:func:`faces_hide`); returns their new count, -1 when they do
    not fit. ``hs (6, 4)``, ``nxt``, ``nc``, ``rest``, ``tmp``: scratch."""
    f = faces.tri_face[k]
    fx, fy, fz, fd = _plane(grid.triangles[k], ex, ey, ez)
    if fx == 0.0 and fy == 0.0 and fz == 0.0:
        return npc
    if fd == 0.0:
        return npc
    sg = 1.0 if fd > 0.0 else -1.0
    afd = abs(fd)
    # hs[j]: the half-space hs[j, :3] · (q − e) + hs[j, 3] ≥ 0 (the edges' eps margin is in
    # their normals, below)
    # the crossing more than 2 off before the light: t < c1
    hs[0, 0] = c1 * sg * fx
    hs[0, 1] = c1 * sg * fy
    hs[0, 2] = c1 * sg * fz
    hs[0, 3] = -afd
    # the crossing above the horizon: t n·(q − e) > hz
    hs[1, 0] = afd * n[0] - hz * sg * fx
    hs[1, 1] = afd * n[1] - hz * sg * fy
    hs[1, 2] = afd * n[2] - hz * sg * fz
    hs[1, 3] = 0.0
    for q in range(faces.start[f], faces.start[f + 1]):
        pc = faces.count[q]
        pcs = faces.corners[q]
        gx = 0.0
        gy = 0.0
        gz = 0.0
        for a in range(pc):
            gx += pcs[a, 0] / pc
            gy += pcs[a, 1] / pc
            gz += pcs[a, 2] / pc
        nh = 2
        for a in range(pc):
            # the plane through e and the edge, its unit normal w towards the piece. The
            # crossing x = e + t (q - e) lies within eps of the edge in the face's plane
            # when w·(x - e) >= -eps sin(θ), θ the angle between that plane and the face's:
            # sin(θ) = |fd| / ρ, ρ the eye's distance from the edge's line. With
            # t = fd / f·(q - e) that is (w + (eps / ρ) sg f)·(q - e) >= 0, linear in q
            # (a margin on w alone would be eps / sin(θ) wide in the face at grazing eyes)
            b = a + 1 if a + 1 < pc else 0
            ax = pcs[a, 0] - ex
            ay = pcs[a, 1] - ey
            az = pcs[a, 2] - ez
            bx = pcs[b, 0] - ex
            by = pcs[b, 1] - ey
            bz = pcs[b, 2] - ez
            wx = ay * bz - az * by
            wy = az * bx - ax * bz
            wz = ax * by - ay * bx
            wl = np.sqrt(wx * wx + wy * wy + wz * wz)
            if not wl > 0.0:
                break                   # the eye in the edge's line: the piece hides nothing
            lx = pcs[b, 0] - pcs[a, 0]
            ly = pcs[b, 1] - pcs[a, 1]
            lz = pcs[b, 2] - pcs[a, 2]
            m = grid.eps * np.sqrt(lx * lx + ly * ly + lz * lz) / wl * sg  # eps/ρ sg
            if wx * (gx - ex) + wy * (gy - ey) + wz * (gz - ez) < 0.0:
                wl = -wl
            hs[nh, 0] = wx / wl + m * fx
            hs[nh, 1] = wy / wl + m * fy
            hs[nh, 2] = wz / wl + m * fz
            hs[nh, 3] = 0.0
            nh += 1
        if nh < 2 + pc:
            continue
        nn = 0
        for P in range(npc):
            # P less the convex set: the part outside the first half-space, then of the rest
            # inside it the part outside the second, ... (disjoint convex pieces)
            rm = cc[P]
            for a in range(rm):
                for x in range(3):
                    rest[a, x] = cur[P, a, x]
            for j in range(nh):
                if nn >= nxt.shape[0]:
                    return -1
                o = _clip(rest, rm, hs[j], ex, ey, ez, -1.0, nxt[nn])
                if o < 0:
                    return -1
                if o >= 3 and _area(nxt[nn], o) > tiny:
                    nc[nn] = o
                    nn += 1
                rm = _clip(rest, rm, hs[j], ex, ey, ez, 1.0, tmp)
                if rm < 0:
                    return -1
                for z in range(rm):
                    for x in range(3):
                        rest[z, x] = tmp[z, x]
                if rm < 3:
                    break
        for P in range(nn):
            cc[P] = nc[P]
            for z in range(nc[P]):
                for x in range(3):
                    cur[P, z, x] = nxt[P, z, x]
        npc = nn
        if npc == 0:
            return 0
    return npc


@jit_leaf
def _clip(src, m, hs, ex, ey, ez, side, dst):
    """Sutherland–Hodgman: the part of the convex polygon ``src[:m]`` inside (``side`` 1:
    ``hs[:3] · (x − e) + hs[3] ≥ 0``) or outside (``side`` −1: ``≤ 0``) a
    half-space, written to ``dst``; its corner count, -1 when it does not fit."""
    nd = 0
    for a in range(m):
        b = a + 1 if a + 1 < m else 0
        sa = side * (hs[0] * (src[a, 0] - ex) + hs[1] * (src[a, 1] - ey)
                     + hs[2] * (src[a, 2] - ez) + hs[3])
        sb = side * (hs[0] * (src[b, 0] - ex) + hs[1] * (src[b, 1] - ey)
                     + hs[2] * (src[b, 2] - ez) + hs[3])
        if sa >= 0.0:
            if nd >= dst.shape[0]:
                return -1
            for x in range(3):
                dst[nd, x] = src[a, x]
            nd += 1
        if (sa >= 0.0) != (sb >= 0.0):
            if nd >= dst.shape[0]:
                return -1
            r = sa / (sa - sb)
            for x in range(3):
                dst[nd, x] = src[a, x] + r * (src[b, x] - src[a, x])
            nd += 1
    return nd


@jit_leaf
def _area(poly, m):
    """Twice the area of the planar polygon ``poly[:m]`` (|Newell vector|)."""
    sx = 0.0
    sy = 0.0
    sz = 0.0
    for a in range(1, m - 1):
        ux = poly[a, 0] - poly[0, 0]
        uy = poly[a, 1] - poly[0, 1]
        uz = poly[a, 2] - poly[0, 2]
        vx = poly[a + 1, 0] - poly[0, 0]
        vy = poly[a + 1, 1] - poly[0, 1]
        vz = poly[a + 1, 2] - poly[0, 2]
        sx += uy * vz - uz * vy
        sy += uz * vx - ux * vz
        sz += ux * vy - uy * vx
    return np.sqrt(sx * sx + sy * sy + sz * sz)
