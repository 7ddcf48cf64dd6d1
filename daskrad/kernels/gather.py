"""Final gather at vertices beside a junction (issue 14, item 3).

Element radiosity is constant per element, so a vertex's value (the mean of its elements) is
the light of points half an element away. Beside a junction — the foot of a block's face on a
lit floor, the floor along a wall — the light changes within that half element: at the foot,
the lit floor fills half the hemisphere at zero distance. There the vertex's indirect light is
gathered instead: the radiance the solution shows (Gouraud over the grid triangles) along
stratified cosine-distributed rays, ``H = π · mean(L)``.
"""

from __future__ import annotations

import math

import numpy as np
from numba import prange

from daskrad.kernels._jit import jit, jit_leaf, jit_parallel
from daskrad.kernels.direct import hash01
from daskrad.kernels.geometry import element_planes, orthonormal_basis, scene_diagonal
from daskrad.kernels.grid import (
    NO_FAN,
    aim_fan,
    any_hit_one,
    closest_hit_fan,
    closest_hit_located,
    locate_hit,
    new_fan,
)
from daskrad.kernels.hemisphere import (
    edge_capacity,
    fill_polygon,
    frame_vertices,
    in_frame,
    project_element,
    project_scratch,
    split_table,
)
from daskrad.kernels.pathtrace import tangent_frame


@jit_leaf
def cosine_direction(d, n, t, s, u, v):
    """The cosine-distributed direction about ``n`` for ``(u, v) ∈ [0, 1)²``, written to
    ``d (3,)`` (``t, s``: tangents completing ``n``). Into a buffer, from scalars: the array
    expression made five arrays a ray, 10 % of the Cornell box's gather (the same bits)."""
    r = math.sqrt(u)
    phi = 2.0 * math.pi * v
    z = math.sqrt(max(0.0, 1.0 - u))
    a = r * math.cos(phi)
    b = r * math.sin(phi)
    for x in range(3):
        d[x] = a * t[x] + b * s[x] + z * n[x]


@jit_parallel
def near_surface(grid, points, normals, off, reach, side):
    """``(n,) bool``: another surface lies within ``reach`` of the point in its hemisphere
    (one of ``side²`` stratified cosine-distributed rays from ``points + off · normals``
    hits within ``reach``)."""
    n = points.shape[0]
    out = np.zeros(n, np.bool_)
    for i in prange(n):
        nrm = normals[i]
        t, s = tangent_frame(nrm)
        o = points[i] + off * nrm
        d = np.empty(3)
        for k in range(side * side):
            cosine_direction(d, nrm, t, s, ((k % side) + 0.5) / side, ((k // side) + 0.5) / side)
            if any_hit_one(grid, o, d, off, reach):
                out[i] = True
                break
    return out


@jit
def gather_operator(grid, tri_verts, tri_element, elem_normal, elem_exclude, n_vertices,
                    points, normals, seeds, off, side, polygons, loc, located):
    """The gather as a sparse linear operator: ``mean(L)`` seen from each point over ``side²``
    stratified, jittered, cosine-distributed rays is ``G · L − x`` for any vertex radiance
    ``L (V, 3)`` (Gouraud over the hit triangle is linear in ``L``), so the rays are cast once
    and every pass of the gather (the first, then the corrections that gather the change the
    last one made) is a sparse product (:func:`apply_operator`).

    Parameters
    ----------
    tri_verts : (T, 3) int, tri_element : (T,) int
        The grid triangles' vertices and elements; ``elem_normal (E, 3)`` their lit side: a
        ray that meets a back face, or nothing, sees no radiance.
    elem_exclude : (E, 3) float64
        Radiance taken off a hit on that element (its emission, already counted as direct).
    n_vertices : int
        ``V``, the number of mesh vertices ``L`` is given at.
    points, normals : (n, 3) float64; seeds : (n,) int64 jitter seeds; off : the ray offset.
    polygons : Grid, loc : (T, 13) float64, located : bool
        With ``located``, each ray's hit is found among the scene's polygons (their grid)
        and located among ``grid``'s triangles (``loc``: :func:`daskrad.kernels.grid.locator`
        of them), :func:`daskrad.kernels.grid.closest_hit_located`; else ``grid`` is walked
        (``polygons`` and ``loc`` unread).

    Returns
    -------
    indptr : (n + 1,) int64, cols : (nnz,) int64, weights : (nnz,) float64
        Row ``i`` of ``G`` in CSR form: the barycentric weights of every hit, summed per mesh
        vertex in the order the vertices were first hit, over ``side²`` (a point's row sums
        to its fraction of rays that saw a front face).
    excluded : (n, 3) float64
        ``x``: the mean of ``elem_exclude`` over each point's rays.

    Serial: the callers split the points into ranges run side by side (threads in-process,
    ``gather-…`` tasks on a cluster); each point's row is the same whatever the split.
    """
    n = points.shape[0]
    ss = side * side
    cap = 3 * ss
    indptr = np.zeros(n + 1, np.int64)
    cols = np.empty(n * cap, np.int64)
    weights = np.empty(n * cap)
    excluded = np.zeros((n, 3))
    slot = np.full(n_vertices, -1, np.int64)   # where a vertex sits in the current row
    walked = polygons if located else grid
    fan = new_fan(walked)   # every ray of a point rises above its tangent plane
    nnz = 0
    d = np.empty(3)
    for i in range(n):
        nrm = normals[i]
        t, s = tangent_frame(nrm)
        o = points[i] + off * nrm
        aim_fan(fan, walked, o, nrm, off)
        row = nnz
        for k in range(ss):
            u = ((k % side) + hash01(seeds[i], 2 * k)) / side
            v = ((k // side) + hash01(seeds[i], 2 * k + 1)) / side
            cosine_direction(d, nrm, t, s, u, v)
            if located:
                th, tri, bu, bv = closest_hit_located(polygons, fan, grid, loc, o, d, off,
                                                      np.inf)
            else:
                th, tri, bu, bv = closest_hit_fan(grid, fan, o, d, off, np.inf)
            nnz = _add_hit(i, tri, bu, bv, d, tri_verts, tri_element, elem_normal,
                           elem_exclude, slot, cols, weights, excluded, nnz)
        _end_row(i, row, nnz, ss, slot, cols, weights, excluded, indptr)
    return indptr, cols[:nnz].copy(), weights[:nnz].copy(), excluded


@jit_leaf
def _add_hit(i, tri, bu, bv, d, tri_verts, tri_element, elem_normal, elem_exclude, slot,
             cols, weights, excluded, nnz):
    """Add the hit ``(tri, bu, bv)`` of a ray of direction ``d`` to row ``i`` (its
    barycentric weights, summed per vertex in the order the vertices were first hit; ``slot``
    where a vertex sits in the row, -1 if not yet); a miss (``tri < 0``) or a back face adds
    nothing. Returns the new ``nnz``."""
    if tri < 0:
        return nnz
    e = tri_element[tri]
    en = elem_normal[e]
    if d[0] * en[0] + d[1] * en[1] + d[2] * en[2] >= 0.0:
        return nnz
    for c in range(3):
        excluded[i, c] += elem_exclude[e, c]
    for corner in range(3):
        w = 1.0 - bu - bv if corner == 0 else (bu if corner == 1 else bv)
        vtx = tri_verts[tri, corner]
        if slot[vtx] < 0:
            slot[vtx] = nnz
            cols[nnz] = vtx
            weights[nnz] = w
            nnz += 1
        else:
            weights[slot[vtx]] += w
    return nnz


@jit_leaf
def _end_row(i, row, nnz, count, slot, cols, weights, excluded, indptr):
    """Close row ``i`` (entries ``[row, nnz)``): each weight and the excluded emission over
    the ``count`` rays of a point, ``slot`` cleared for the next row."""
    for k in range(row, nnz):
        slot[cols[k]] = -1
        weights[k] /= count
    for c in range(3):
        excluded[i, c] /= count
    indptr[i + 1] = nnz


@jit
def disc_operator(grid, tri_verts, tri_element, elem_normal, elem_exclude, n_vertices,
                  points, normals, seeds, off, resolution, edge_angle, horizon_eps, polygons,
                  loc):
    """:func:`gather_operator` by the hemisphere base (Doi's item buffer, the form factors'
    own method, :mod:`daskrad.kernels.hemisphere`) instead of rays: from each point the
    scene's polygons (``polygons.triangles``) are projected onto the base disc of an
    ``R × R`` item buffer, ``R = resolution``, with exact depth; every disc pixel is then a
    cosine-distributed direction of weight ``1 / n_disc`` (Nusselt's analog), and the point
    its polygon shows there is located among ``grid``'s triangles
    (:func:`daskrad.kernels.grid.locate_hit`) as a ray's hit would be.

    Faces turned away from the point are drawn too, after the front faces: they hide what
    lies behind them and show nothing (a ray stops on a back face and sees no radiance).
    Where two one-sided faces coincide back to back, round-off may give the pixel to
    either; its point is located among the elements like any other, and the location takes
    the element facing the point, as it does for a ray. The pixel lattice is turned about
    the normal and shifted by a fraction of a pixel, both seeded per point (``seeds``), so
    that its centres are uniform over the disc in expectation and neighbouring points do not
    share the raster's aliasing. ``edge_angle`` (radians) splits the projected edges
    (eq. 4); ``horizon_eps`` is the horizon clip's height relative to the polygons' diagonal,
    as for the form factors (:func:`daskrad.kernels.hemisphere.hemisphere_visibility`): the
    point's own surface, ``off`` below it, is culled whole. Same returns as
    :func:`gather_operator`, every row over ``n_disc`` directions. Its cost is ``polygons``
    projections and ``n_disc`` locations a point, against ``side²`` walks of the polygons'
    grid: the cheaper for a scene of few polygons.
    """
    n = points.shape[0]
    r = resolution
    h = 2.0 / r                     # the pixel's side
    xc = np.empty(r)
    yc = np.empty(r)
    dz = np.empty(r * r)
    ptris = polygons.triangles
    P = ptris.shape[0]
    pv = np.empty((3 * P, 3))
    ev = np.full((P, 4), -1, np.int32)
    for p in range(P):
        for a in range(3):
            ev[p, a] = 3 * p + a
            for x in range(3):
                pv[3 * p + a, x] = ptris[p, a, x]
    front_n, front_off = element_planes(pv, ev)
    hz = max(horizon_eps * scene_diagonal(pv), 1e-300)
    back_n = -front_n
    back_off = -front_off
    cos_thr = math.cos(edge_angle)
    tab = split_table(edge_angle)
    cap = edge_capacity(edge_angle)
    xs = np.empty(cap)
    ys = np.empty(cap)
    xcross = np.empty((r, cap))
    cnt = np.zeros(r, np.int64)
    item = np.empty(r * r, np.int32)
    zbuf = np.empty(r * r)
    lx = np.empty(3 * P)
    ly = np.empty(3 * P)
    lz = np.empty(3 * P)
    cx, cy, cz, qx, qy, qz, qclip = project_scratch()
    inv_h = 1.0 / h
    cap_row = 3 * r * r
    indptr = np.zeros(n + 1, np.int64)
    cols = np.empty(n * cap_row, np.int64)
    weights = np.empty(n * cap_row)
    excluded = np.zeros((n, 3))
    slot = np.full(n_vertices, -1, np.int64)
    nnz = 0
    o = np.empty(3)
    d = np.empty(3)
    for i in range(n):
        nx, ny, nz = normals[i, 0], normals[i, 1], normals[i, 2]
        for x in range(3):
            o[x] = points[i, x] + off * normals[i, x]
        t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(nx, ny, nz)
        phi = 2.0 * math.pi * hash01(seeds[i], 0)
        ca = math.cos(phi)
        sa = math.sin(phi)
        ax, ay, az = ca * t1x + sa * t2x, ca * t1y + sa * t2y, ca * t1z + sa * t2z
        bx, by, bz = ca * t2x - sa * t1x, ca * t2y - sa * t1y, ca * t2z - sa * t1z
        frame_vertices(o[0], o[1], o[2], ax, ay, az, bx, by, bz, nx, ny, nz, pv, lx, ly, lz)
        # the pixel lattice shifted by a seeded fraction of a pixel: its centres are then
        # uniform over the disc in expectation, and the rim is not the same staircase at
        # every point (a fixed lattice gathered 0.3 % too little in the Cornell box). The
        # centres -1 + h (u + j), u in [0, 1), j < R cover [-1, 1) whatever the shift.
        sx = -1.0 - 0.5 * h + h * hash01(seeds[i], 1)
        sy = -1.0 - 0.5 * h + h * hash01(seeds[i], 2)
        for j in range(r):
            xc[j] = sx + (j + 0.5) * h
            yc[j] = sy + (j + 0.5) * h
        n_disc = 0
        for j in range(r):
            for k in range(r):
                q = 1.0 - xc[k] * xc[k] - yc[j] * yc[j]
                item[j * r + k] = -1
                zbuf[j * r + k] = -np.inf
                if q > 0.0:
                    dz[j * r + k] = math.sqrt(q)
                    n_disc += 1
                else:
                    dz[j * r + k] = -1.0
        for back in range(2):
            pn = back_n if back else front_n
            po = back_off if back else front_off
            for p in range(P):
                m, mm, c = project_element(p, o[0], o[1], o[2], ev, pn, po, lx, ly, lz, hz,
                                           cos_thr, tab, cx, cy, cz, qx, qy, qz, qclip, xs, ys)
                if mm == 0:
                    continue
                nlx, nly, nlz = in_frame(ax, ay, az, bx, by, bz, nx, ny, nz, pn[p, 0],
                                         pn[p, 1], pn[p, 2])
                fill_polygon(xs, ys, mm, p + back * P, xc, yc, r, r, sx, inv_h, sy, inv_h, dz,
                             nlx / c, nly / c, 0.0, nlz / c, xcross, cnt, item, zbuf)
        row = nnz
        for k in range(r * r):
            if item[k] < 0:
                continue
            x = xc[k % r]
            y = yc[k // r]
            z = dz[k]
            d[0] = x * ax + y * bx + z * nx
            d[1] = x * ay + y * by + z * ny
            d[2] = x * az + y * bz + z * nz
            tp = 1.0 / zbuf[k] if zbuf[k] > 0.0 else 0.0
            if tp > off:
                # a back face's pixel too (item >= P): where a front face coincides with it,
                # the location takes that one; else _add_hit sees a back face, which adds
                # nothing
                _, tri, bu, bv = locate_hit(grid, loc, o, d, tp, off, np.inf)
            else:
                # a grazing polygon whose chord covers a pixel past its plane, or a point
                # nearer than a ray would look (a wall through the vertex): the ray's answer
                _, tri, bu, bv = closest_hit_located(polygons, NO_FAN, grid, loc, o, d, off,
                                                     np.inf)
            nnz = _add_hit(i, tri, bu, bv, d, tri_verts, tri_element, elem_normal,
                           elem_exclude, slot, cols, weights, excluded, nnz)
        _end_row(i, row, nnz, n_disc, slot, cols, weights, excluded, indptr)
    return indptr, cols[:nnz].copy(), weights[:nnz].copy(), excluded


@jit
def apply_operator(indptr, cols, weights, values):
    """``(n, C) float64``: ``G · values`` for the CSR operator of :func:`gather_operator`
    and ``values : (V, C)``; each row summed in its stored order (the same bits on any
    split)."""
    n = indptr.shape[0] - 1
    m = values.shape[1]
    out = np.zeros((n, m))
    for i in range(n):
        for k in range(indptr[i], indptr[i + 1]):
            w = weights[k]
            for c in range(m):
                out[i, c] += w * values[cols[k], c]
    return out
