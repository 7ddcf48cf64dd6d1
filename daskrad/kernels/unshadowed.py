"""Elements no shadow ray can be blocked from: the per-pixel pass skips their shadow rays.

A pixel on an element of the per-pixel pass (paper eq. 9) traces ``samples²`` shadow rays to
every area light and one to every point light (:func:`daskrad.kernels.direct.irradiance_one`);
on the Cornell box 83 % of those hits see every light wholly (the spread that selected their
element is the light's fall-off near it, not a shadow). Each shadow ray of a hit ``p`` on
element ``e`` runs from ``o = p + off·n_e`` to a point ``q`` of the light, for ``t`` in
``(off/|d|, 1 − off/|d|)``; so every ray of every pixel of ``e`` lies in the convex hull ``K``
of ``e``'s corners lifted by ``off`` and the light's corners. If no triangle of the scene comes
near ``K``, every such ray misses, and the rays can be skipped with the same bits (the
irradiance is then the unoccluded one, computed the same way).

A triangle is proved clear of ``K`` by a separating plane, with a margin of ``off/2`` far
above the ray test's edge tolerance (``grid.eps``) and round-off:

- a supporting plane of ``K`` (through three of its points, every point on one side): the
  triangle lies wholly beyond it;
- for an area light, its own plane: no traced point of a ray comes closer to it than
  ``h_o · off/|d| >= h_min · off / d_max`` (``h_min`` the lowest lifted corner above the
  light's plane, ``d_max`` the longest corner-to-corner distance), so a triangle lying lower
  than half that (the light's own triangles, the ceiling around it) cannot be hit.

Anything not proved clear keeps the element's shadow rays: the test only ever answers
"certainly unblocked". For a directional light ``K`` is the prism swept by the lifted element
towards the light until it leaves the grid's box (nothing lies beyond).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf


@jit_leaf
def _hull_planes(pts, n_pts, planes):
    """Supporting planes of the points ``pts[:n_pts]`` into ``planes (m, 5)``: unit normal
    ``k``, offset ``kd`` and ``low = min_i (k·p_i − kd) <= 0`` (how far the points reach
    below it; round-off), every point at ``k·p − kd >= low``. Returns how many."""
    count = 0
    for a in range(n_pts):
        for b in range(a + 1, n_pts):
            for c in range(b + 1, n_pts):
                ux = pts[b, 0] - pts[a, 0]
                uy = pts[b, 1] - pts[a, 1]
                uz = pts[b, 2] - pts[a, 2]
                vx = pts[c, 0] - pts[a, 0]
                vy = pts[c, 1] - pts[a, 1]
                vz = pts[c, 2] - pts[a, 2]
                kx = uy * vz - uz * vy
                ky = uz * vx - ux * vz
                kz = ux * vy - uy * vx
                norm = np.sqrt(kx * kx + ky * ky + kz * kz)
                if not norm > 0.0:
                    continue
                kx /= norm
                ky /= norm
                kz /= norm
                kd = kx * pts[a, 0] + ky * pts[a, 1] + kz * pts[a, 2]
                lo = 0.0
                hi = 0.0
                for i in range(n_pts):
                    s = kx * pts[i, 0] + ky * pts[i, 1] + kz * pts[i, 2] - kd
                    lo = min(lo, s)
                    hi = max(hi, s)
                # a supporting plane has the points on one side, up to round-off
                tol = 1e-9 * (hi - lo) + 1e-300
                if lo >= -tol:
                    planes[count, 0] = kx
                    planes[count, 1] = ky
                    planes[count, 2] = kz
                    planes[count, 3] = kd
                    planes[count, 4] = lo
                    count += 1
                elif hi <= tol:
                    planes[count, 0] = -kx
                    planes[count, 1] = -ky
                    planes[count, 2] = -kz
                    planes[count, 3] = -kd
                    planes[count, 4] = -hi
                    count += 1
    return count


@jit
def _clear(grid, pts, n_pts, planes, light_n, light_d, light_below, margin, stamp, sid):
    """Whether every triangle of ``grid`` is separated from the hull of ``pts[:n_pts]`` (by a
    supporting plane, or, when ``light_below > 0``, by lying below ``light_below`` over the
    light's plane ``light_n · x = light_d``)."""
    n_pl = _hull_planes(pts, n_pts, planes)
    lo = np.empty(3)
    hi = np.empty(3)
    for k in range(3):
        lo[k] = np.inf
        hi[k] = -np.inf
        for i in range(n_pts):
            lo[k] = min(lo[k], pts[i, k])
            hi[k] = max(hi[k], pts[i, k])
    origin, cell, dims = grid.origin, grid.cell, grid.dims
    r0 = np.empty(3, np.int64)
    r1 = np.empty(3, np.int64)
    for k in range(3):
        a = (lo[k] - margin - origin[k]) / cell[k]
        b = (hi[k] + margin - origin[k]) / cell[k]
        a = min(max(a, -1.0), dims[k] + 1.0)
        b = min(max(b, -1.0), dims[k] + 1.0)
        r0[k] = max(0, min(dims[k] - 1, int(np.floor(a))))
        r1[k] = max(0, min(dims[k] - 1, int(np.floor(b))))
    tris = grid.triangles
    for kk in range(r0[2], r1[2] + 1):
        for jj in range(r0[1], r1[1] + 1):
            for ii in range(r0[0], r1[0] + 1):
                c = (kk * dims[1] + jj) * dims[0] + ii
                for q in range(grid.cell_start[c], grid.cell_start[c + 1]):
                    t = grid.cell_items[q]
                    if stamp[t] == sid:
                        continue
                    stamp[t] = sid
                    if light_below > 0.0:
                        top = -np.inf
                        for v in range(3):
                            top = max(top, light_n[0] * tris[t, v, 0] + light_n[1] * tris[t, v, 1]
                                      + light_n[2] * tris[t, v, 2] - light_d)
                        if top < light_below:
                            continue
                    separated = False
                    for a in range(n_pl):
                        top = -np.inf
                        for v in range(3):
                            top = max(top, planes[a, 0] * tris[t, v, 0]
                                      + planes[a, 1] * tris[t, v, 1]
                                      + planes[a, 2] * tris[t, v, 2] - planes[a, 3])
                        if top < planes[a, 4] - margin:
                            separated = True
                            break
                    if not separated:
                        return False
    return True


@jit
def unshadowed_elements(grid, vertices, elem_verts, elem_normal, wanted, off, pl_pos, dl_dir,
                        em_corners, em_count, em_normal):
    """``(E,) bool``: elements of ``wanted (E,) bool`` from whose every point (lifted by
    ``off`` along ``elem_normal``) no shadow ray to any point light ``pl_pos (L, 3)``,
    directional light (unit travel directions ``dl_dir (D, 3)``) or area light
    (``em_corners (M, 4, 3)``, ``em_count (M,)``, ``em_normal (M, 3)``) can be blocked by a
    triangle of ``grid`` (see the module docstring). ``elem_verts (E, 4)``, ``-1`` for a
    triangle's fourth corner."""
    n_elem = elem_verts.shape[0]
    out = np.zeros(n_elem, np.bool_)
    stamp = np.full(grid.triangles.shape[0], -1, np.int64)
    pts = np.empty((8, 3))
    planes = np.empty((56, 5))
    zero = np.zeros(3)
    margin = 0.5 * off
    # a ray towards a directional light leaves the grid's box (every triangle is inside it)
    # within this length: the box's diagonal
    reach = 0.0
    for x in range(3):
        reach += (grid.dims[x] * grid.cell[x]) ** 2
    reach = np.sqrt(reach) + 2.0 * off
    sid = 0
    for e in range(n_elem):
        if not wanted[e]:
            continue
        k = 4 if elem_verts[e, 3] >= 0 else 3
        for a in range(k):
            for x in range(3):
                pts[a, x] = vertices[elem_verts[e, a], x] + off * elem_normal[e, x]
        ok = True
        for li in range(pl_pos.shape[0]):
            for x in range(3):
                pts[k, x] = pl_pos[li, x]
            sid += 1
            if not _clear(grid, pts, k + 1, planes, zero, 0.0, 0.0, margin, stamp, sid):
                ok = False
                break
        if not ok:
            continue
        for li in range(dl_dir.shape[0]):
            for a in range(k):
                for x in range(3):
                    pts[k + a, x] = pts[a, x] - reach * dl_dir[li, x]
            sid += 1
            if not _clear(grid, pts, 2 * k, planes, zero, 0.0, 0.0, margin, stamp, sid):
                ok = False
                break
        if not ok:
            continue
        for m in range(em_corners.shape[0]):
            cnt = em_count[m]
            en = em_normal[m]
            ed = (en[0] * em_corners[m, 0, 0] + en[1] * em_corners[m, 0, 1]
                  + en[2] * em_corners[m, 0, 2])
            h_min = np.inf
            d_max = 0.0
            for a in range(k):
                h_min = min(h_min, en[0] * pts[a, 0] + en[1] * pts[a, 1] + en[2] * pts[a, 2] - ed)
                for b in range(cnt):
                    dx = pts[a, 0] - em_corners[m, b, 0]
                    dy = pts[a, 1] - em_corners[m, b, 1]
                    dz = pts[a, 2] - em_corners[m, b, 2]
                    d_max = max(d_max, np.sqrt(dx * dx + dy * dy + dz * dz))
            # traced points stay above h_min · off / d_max over the light's plane (half of
            # it, against round-off; nothing when that is within the ray test's tolerance)
            below = 0.5 * h_min * off / d_max if h_min > 0.0 and d_max > 0.0 else 0.0
            if below <= 16.0 * grid.eps:
                below = 0.0
            for b in range(cnt):
                for x in range(3):
                    pts[k + b, x] = em_corners[m, b, x]
            sid += 1
            if not _clear(grid, pts, k + cnt, planes, en, ed, below, margin, stamp, sid):
                ok = False
                break
        out[e] = ok
    return out
