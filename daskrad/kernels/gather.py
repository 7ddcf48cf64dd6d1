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

from daskrad.kernels._jit import jit, jit_parallel
from daskrad.kernels.direct import hash01
from daskrad.kernels.grid import aim_fan, any_hit_one, closest_hit_fan, closest_hit_located, new_fan
from daskrad.kernels.pathtrace import tangent_frame


@jit
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
            if tri < 0:
                continue
            e = tri_element[tri]
            en = elem_normal[e]
            if d[0] * en[0] + d[1] * en[1] + d[2] * en[2] >= 0.0:
                continue
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
        for k in range(row, nnz):
            slot[cols[k]] = -1
            weights[k] /= ss
        for c in range(3):
            excluded[i, c] /= ss
        indptr[i + 1] = nnz
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
