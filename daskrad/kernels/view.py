"""The view's closest hits by an item buffer over the screen (issue 12, item 3: "a cheaper pass
where the item buffer only decides visibility").

Every primary ray leaves the camera's eye ``o``. A ray of direction ``d`` (``d · f > 0``, ``f``
the view's forward axis) sits at the screen point ``(x, y) = (d · r, d · u) / (d · f)``; a point
``P`` in front of the eye at ``((P − o) · r, (P − o) · u) / ((P − o) · f)``. A ray can only hit
a triangle whose projection holds its screen point. So the polygon triangles are projected once
per batch of rays into a grid of screen bins (:func:`view_bins`: each triangle listed in every
bin its projection's bounding box reaches), and each ray tests only the triangles of its bin
(:func:`view_hits`), with the grid walk's own Möller–Trumbore (``grid.intersect``) in the same
order-free way: the closest ``t`` is the least ``t`` over the triangles the ray hits, which is
what the walk of the polygons' grid returns (:func:`daskrad.kernels.grid.closest_hit_located`),
then located among the elements by the same :func:`daskrad.kernels.grid.locate_hit`. The same
``(t, tri, u, v)``, bit for bit, provided every triangle the ray hits is in its bin; the
projection is made conservative for that:

- the walk counts a hit up to ``eps`` outside a triangle's edge lines: the triangle with every
  edge line moved out by ``eps`` is the triangle scaled about its incentre by ``1 + eps / ρ``
  (``ρ`` its inradius), so those corners (at twice the tolerance) are projected, not the
  triangle's own (where ``eps`` is a small share of a triangle's depth, the widening below
  holds it as well);
- each corner's projection is widened far beyond the round-off of ``X / Z`` and of a
  coordinate (:data:`WIDEN`, ``tol``), and a triangle with no inradius to speak of is listed
  everywhere;
- a triangle that reaches the eye's plane is clipped at a depth ``zc`` (:data:`NEAR`): the part
  beyond is projected; a ray of the batch meets the part at depths ``0 < Z < zc`` only within
  ``reach · zc`` of the view's axis (``reach`` the rays' largest screen coordinate), so a
  triangle whose part there comes that close is listed in every bin (geometry touching the
  eye), and one wholly behind the eye's plane in none;
- a bin's triangles are tested nearest first (by the least depth of their projected part), and
  a ray stops where the next one lies deeper than its hit, by :data:`DEPTH_SLACK`.

A ray with ``d · f <= 0`` (never a primary ray of the camera), or whose direction or screen
point is not finite, walks the polygons' grid (:func:`daskrad.kernels.grid.closest_hit_located`).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.grid import NO_FAN, closest_hit_located, intersect, locate_hit
from daskrad.kernels.tolerances import COORD_ROUND

#: Relative widening of each projected corner (far above the round-off of ``X / Z``).
WIDEN = 1e-7
#: Depths below this share of the scene's extent count as near the eye's plane
#: (:func:`triangle_boxes`).
NEAR = 1e-4
#: Relative slack of the nearest-first stop: a triangle is passed over only where its least
#: depth exceeds the hit's ``t · d · f`` by this much (far above the round-off of ``t``, where
#: the walk's own answer does not depend on round-off either).
DEPTH_SLACK = 1e-6
#: Rays per bin aimed at (:func:`bin_counts`).
RAYS_PER_BIN = 48


@jit_leaf
def _clip(X, Y, Z, m, zc, above, oX, oY, oZ):
    """Sutherland–Hodgman: the polygon ``X, Y, Z [:m]`` clipped to ``Z >= zc`` (``above``) or
    ``Z <= zc``, into ``oX, oY, oZ``; returns its corner count (at most ``m + 1``)."""
    k = 0
    for a in range(m):
        b = a + 1 if a + 1 < m else 0
        ina = Z[a] >= zc if above else Z[a] <= zc
        inb = Z[b] >= zc if above else Z[b] <= zc
        if ina:
            oX[k] = X[a]
            oY[k] = Y[a]
            oZ[k] = Z[a]
            k += 1
        if ina != inb:
            s = (zc - Z[a]) / (Z[b] - Z[a])
            oX[k] = X[a] + s * (X[b] - X[a])
            oY[k] = Y[a] + s * (Y[b] - Y[a])
            oZ[k] = zc
            k += 1
    return k


@jit
def triangle_boxes(tris, eps, o, r, u, f, zc, reach, tol):
    """``(lo (T, 2), hi (T, 2), kind (T,) int8, near_z (T,))``: each triangle's screen bounding
    box, the triangle grown by the walk's edge tolerance ``eps`` (scaled about its incentre)
    and widened for round-off; ``kind`` 0 boxed, 1 everywhere, -1 nowhere; ``near_z`` the least
    depth ``Z = (P − o) · f`` of the grown triangle's boxed part (-inf for the others).

    The part at depths ``Z >= zc`` is projected. A ray of the batch (screen points within
    ``reach`` of the centre in ``x`` and ``y``) meets a point at depth ``0 < Z < zc`` only
    within ``reach · zc`` of the eye's axis: a triangle whose part at those depths comes that
    close is listed everywhere (geometry touching the eye; and a degenerate triangle), one
    wholly behind the eye's plane nowhere. ``tol``: the round-off of a coordinate (a corner
    of the grown triangle, in the view's frame), added to every margin."""
    n = tris.shape[0]
    lo = np.empty((n, 2))
    hi = np.empty((n, 2))
    kind = np.zeros(n, np.int8)
    near_z = np.full(n, -np.inf)
    X = np.empty(3)
    Y = np.empty(3)
    Z = np.empty(3)
    cX = np.empty(5)
    cY = np.empty(5)
    cZ = np.empty(5)
    dX = np.empty(5)
    dY = np.empty(5)
    dZ = np.empty(5)
    # |X| <= reach · Z at a hit with Z <= zc, each coordinate off by tol
    box = reach * (zc + tol) * (1.0 + 1e-6) + tol
    for t in range(n):
        ax, ay, az = tris[t, 0, 0], tris[t, 0, 1], tris[t, 0, 2]
        bx, by, bz = tris[t, 1, 0], tris[t, 1, 1], tris[t, 1, 2]
        cx, cy, cz = tris[t, 2, 0], tris[t, 2, 1], tris[t, 2, 2]
        la = np.sqrt((bx - cx) ** 2 + (by - cy) ** 2 + (bz - cz) ** 2)   # opposite a
        lb = np.sqrt((ax - cx) ** 2 + (ay - cy) ** 2 + (az - cz) ** 2)
        lc = np.sqrt((ax - bx) ** 2 + (ay - by) ** 2 + (az - bz) ** 2)
        per = la + lb + lc
        nx = (by - ay) * (cz - az) - (bz - az) * (cy - ay)
        ny = (bz - az) * (cx - ax) - (bx - ax) * (cz - az)
        nz = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        area2 = np.sqrt(nx * nx + ny * ny + nz * nz)         # twice the area
        rho = area2 / per if per > 0.0 else 0.0              # inradius: A / (per / 2)
        if not rho > 1e-9 * per:
            kind[t] = 1                                      # a sliver: everywhere
            continue
        ix = (la * ax + lb * bx + lc * cx) / per
        iy = (la * ay + lb * by + lc * cy) / per
        iz = (la * az + lb * bz + lc * cz) / per
        s = (1.0 + 2.0 * eps / rho) * (1.0 + 1e-9)           # 2 eps: the test's own slack
        zmax = -np.inf
        for k in range(3):
            wx = ix + s * (tris[t, k, 0] - ix) - o[0]
            wy = iy + s * (tris[t, k, 1] - iy) - o[1]
            wz = iz + s * (tris[t, k, 2] - iz) - o[2]
            X[k] = wx * r[0] + wy * r[1] + wz * r[2]
            Y[k] = wx * u[0] + wy * u[1] + wz * u[2]
            Z[k] = wx * f[0] + wy * f[1] + wz * f[2]
            zmax = max(zmax, Z[k])
        if zmax < -tol:
            kind[t] = -1                                     # wholly behind the eye
            continue
        # the part at 0 <= Z <= zc (and the round-off about it): does it come within the
        # batch's rays' reach of the axis?
        m = _clip(X, Y, Z, 3, zc + tol, False, dX, dY, dZ)
        m = _clip(dX, dY, dZ, m, -tol, True, cX, cY, cZ)
        if m:
            x0 = y0 = np.inf
            x1 = y1 = -np.inf
            for a in range(m):
                x0 = min(x0, cX[a])
                x1 = max(x1, cX[a])
                y0 = min(y0, cY[a])
                y1 = max(y1, cY[a])
            if x0 <= box and x1 >= -box and y0 <= box and y1 >= -box:
                kind[t] = 1
                continue
        m = _clip(X, Y, Z, 3, zc, True, cX, cY, cZ)
        if m == 0:
            kind[t] = -1
            continue
        x0 = y0 = zlo = np.inf
        x1 = y1 = -np.inf
        for a in range(m):
            x = cX[a] / cZ[a]
            y = cY[a] / cZ[a]
            # the relative error of X / Z, a few ulps of |P − o| / Z, and the coordinates'
            g = (WIDEN * (abs(cX[a]) + abs(cY[a]) + cZ[a]) + 4.0 * tol) \
                * (1.0 + abs(x) + abs(y)) / cZ[a]
            x0 = min(x0, x - g)
            x1 = max(x1, x + g)
            y0 = min(y0, y - g)
            y1 = max(y1, y + g)
            zlo = min(zlo, cZ[a] - tol)
        lo[t, 0] = x0
        lo[t, 1] = y0
        hi[t, 0] = x1
        hi[t, 1] = y1
        near_z[t] = zlo
    return lo, hi, kind, near_z


@jit
def view_bins(lo, hi, kind, order, x0, y0, x1, y1, inv_w, inv_h, nbx, nby):
    """``(start (nbx·nby + 1,), items)``: the triangles listed in each screen bin, in the order
    ``order`` (nearest first): a boxed one (``kind`` 0) in every bin its box reaches (bin
    ``(i, j)`` covers ``x0 + [i, i + 1) / inv_w`` by ``y0 + [j, j + 1) / inv_h``, the edge
    bins reaching on to infinity), one of ``kind`` 1 in every bin. A box that misses the rays'
    range ``[x0, x1] × [y0, y1]`` is in no bin: no ray of the batch can hit its triangle.
    :func:`view_hits` passes the order of :func:`triangle_boxes`' ``near_z``, -inf for
    ``kind`` 1: those come first in every bin, where its nearest-first stop never passes one
    over."""
    n = kind.shape[0]
    nb = nbx * nby
    count = np.zeros(nb + 1, np.int64)
    for fill_in in range(2):        # count, then fill
        if fill_in:
            for b in range(nb):
                count[b + 1] += count[b]
            items = np.empty(count[nb], np.int32)
            at = count[:nb].copy()
        else:
            items = np.empty(0, np.int32)
            at = count[:0]
        for q in range(n):
            t = order[q]
            if kind[t] == 1:
                i0, i1, j0, j1 = 0, nbx - 1, 0, nby - 1
            elif kind[t] == 0 and not (hi[t, 0] < x0 or lo[t, 0] > x1 or hi[t, 1] < y0
                                       or lo[t, 1] > y1):
                i0, i1, j0, j1 = _bin_range(lo[t, 0], lo[t, 1], hi[t, 0], hi[t, 1], x0, y0,
                                            inv_w, inv_h, nbx, nby)
            else:
                continue
            for j in range(j0, j1 + 1):
                for i in range(i0, i1 + 1):
                    b = j * nbx + i
                    if fill_in:
                        items[at[b]] = t
                        at[b] += 1
                    else:
                        count[b + 1] += 1
    return count, items


@jit_leaf
def _bin_range(ax, ay, bx, by, x0, y0, inv_w, inv_h, nbx, nby):
    """The bins ``i0..i1, j0..j1`` a box reaches, clamped (the edge bins reach on)."""
    i0 = _bin(ax, x0, inv_w, nbx)
    i1 = _bin(bx, x0, inv_w, nbx)
    j0 = _bin(ay, y0, inv_h, nby)
    j1 = _bin(by, y0, inv_h, nby)
    return i0, i1, j0, j1


@jit_leaf
def _bin(x, x0, inv, n):
    g = (x - x0) * inv
    if not g > 0.0:              # also NaN: the first bin
        return 0
    if g >= n:
        return n - 1
    return int(g)


@jit
def view_hits(polygons, grid, loc, o, directions, r, u, f, nbx, nby):
    """``(t, tri, u, v)`` of every ray from ``o`` along ``directions (n, 3)``, as
    :func:`daskrad.kernels.grid.closest_hit_located` gives them through ``polygons`` (``tmin``
    0, ``tmax`` inf), found through ``nbx × nby`` screen bins over the rays' own screen range in
    the frame ``(r, u, f)`` (orthonormal, ``f`` forward)."""
    n = directions.shape[0]
    t_out = np.full(n, np.inf)
    tri_out = np.full(n, -1, np.int32)
    u_out = np.zeros(n)
    v_out = np.zeros(n)
    sx = np.empty(n)
    sy = np.empty(n)
    sz = np.empty(n)
    ok = np.zeros(n, np.bool_)
    x0 = y0 = np.inf
    x1 = y1 = -np.inf
    for k in range(n):
        dz = directions[k, 0] * f[0] + directions[k, 1] * f[1] + directions[k, 2] * f[2]
        if not (dz > 0.0 and np.isfinite(dz)):
            continue
        sz[k] = dz
        sx[k] = (directions[k, 0] * r[0] + directions[k, 1] * r[1] + directions[k, 2] * r[2]) / dz
        sy[k] = (directions[k, 0] * u[0] + directions[k, 1] * u[1] + directions[k, 2] * u[2]) / dz
        if not (np.isfinite(sx[k]) and np.isfinite(sy[k])):
            continue
        ok[k] = True
        x0 = min(x0, sx[k])
        x1 = max(x1, sx[k])
        y0 = min(y0, sy[k])
        y1 = max(y1, sy[k])
    tris, eps = polygons.triangles, polygons.eps
    if x0 <= x1:
        # depths below zc are near the eye's plane (a ten-thousandth of the grid's extent);
        # tol: a coordinate's round-off, relative to the largest (grid.COORD_ROUND)
        ext = polygons.cell * polygons.dims
        zc = NEAR * np.sqrt(ext[0] ** 2 + ext[1] ** 2 + ext[2] ** 2)
        big = 0.0
        for a in range(3):
            big = max(big, abs(polygons.origin[a]), abs(polygons.origin[a] + ext[a]))
            big = max(big, abs(o[a]))
        tol = 64.0 * COORD_ROUND * big
        screen = max(abs(x0), abs(x1), abs(y0), abs(y1))
        lo, hi, kind, near_z = triangle_boxes(tris, eps, o, r, u, f, zc, screen, tol)
        inv_w = nbx / (x1 - x0) if x1 > x0 else 0.0
        inv_h = nby / (y1 - y0) if y1 > y0 else 0.0
        order = np.argsort(near_z, kind="mergesort")
        start, items = view_bins(lo, hi, kind, order, x0, y0, x1, y1, inv_w, inv_h, nbx,
                                 nby)
    else:
        start = np.zeros(1, np.int64)
        items = np.zeros(0, np.int32)
        near_z = np.zeros(0)
        inv_w = inv_h = 0.0
    for k in range(n):
        if not ok[k]:      # not in front of the eye (or not finite): the polygons' walk
            t, tri, uu, vv = closest_hit_located(polygons, NO_FAN, grid, loc, o,
                                                 directions[k], 0.0, np.inf)
        else:
            dx, dy, dz = directions[k, 0], directions[k, 1], directions[k, 2]
            b = _bin(sy[k], y0, inv_h, nby) * nbx + _bin(sx[k], x0, inv_w, nbx)
            tp = np.inf
            ptri = -1
            # nearest first: a triangle whose least depth lies deeper than the hit so far (its
            # depth along the ray, t · d · f, widened by DEPTH_SLACK) cannot be hit before it,
            # nor can any after it; those listed everywhere come first (near_z -inf)
            deepest = np.inf
            for m in range(start[b], start[b + 1]):
                tri = items[m]
                if near_z[tri] > deepest:
                    break
                hit, t, _, _ = intersect(tris, tri, o[0], o[1], o[2], dx, dy, dz, 0.0, tp,
                                         eps)
                if hit:
                    tp = t
                    ptri = tri
                    deepest = tp * sz[k] * (1.0 + DEPTH_SLACK)
            if ptri < 0:
                continue
            t, tri, uu, vv = locate_hit(grid, loc, o, directions[k], tp, 0.0, np.inf)
        t_out[k] = t
        tri_out[k] = tri
        u_out[k] = uu
        v_out[k] = vv
    return t_out, tri_out, u_out, v_out


def view_hits_batch(polygons, loc: np.ndarray, grid, origin: np.ndarray,
                    directions: np.ndarray):
    """:func:`daskrad.kernels.grid.closest_hit_located_batch` of rays that all leave
    ``origin (3,)`` along ``directions (n, 3)`` (``tmin`` 0, ``tmax`` inf), found through
    screen bins (:func:`view_hits`): ``(t, tri, u, v)``, the same bits. The view's forward
    axis is the rays' mean direction; a ray not in front of it walks the polygons' grid."""
    d = np.ascontiguousarray(directions, dtype=np.float64)
    mean = d.sum(axis=0)
    norm = float(np.sqrt(mean @ mean))
    f = mean / norm if norm > 0.0 and np.isfinite(norm) else np.array([0.0, 0.0, 1.0])
    # any unit vector not along f, made orthogonal: the frame's screen axes
    a = np.array([1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    r = np.cross(f, a)
    r /= np.sqrt(r @ r)
    u = np.cross(f, r)
    nbx, nby = bin_counts(len(d))
    return view_hits(polygons, grid, np.ascontiguousarray(loc, dtype=np.float64),
                     np.ascontiguousarray(origin, dtype=np.float64), d, r, u,
                     np.ascontiguousarray(f), nbx, nby)


def bin_counts(n_rays: int) -> tuple[int, int]:
    """Screen bins per side for a batch of ``n_rays`` rays: about :data:`RAYS_PER_BIN` rays a
    bin, at least one."""
    side = max(1, int(np.sqrt(n_rays / RAYS_PER_BIN)))
    return side, side
