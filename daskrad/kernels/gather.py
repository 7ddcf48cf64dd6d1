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
from daskrad.kernels.grid import any_hit_one, closest_hit_one
from daskrad.kernels.pathtrace import tangent_frame


@jit
def _direction(n, t, s, u, v):
    """Cosine-distributed direction about ``n`` for ``(u, v) ∈ [0, 1)²``."""
    r = math.sqrt(u)
    phi = 2.0 * math.pi * v
    z = math.sqrt(max(0.0, 1.0 - u))
    return (r * math.cos(phi)) * t + (r * math.sin(phi)) * s + z * n


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
        for k in range(side * side):
            d = _direction(nrm, t, s, ((k % side) + 0.5) / side, ((k // side) + 0.5) / side)
            if any_hit_one(grid, o, d, off, reach):
                out[i] = True
                break
    return out


@jit
def gather_radiance(grid, tri_verts, tri_element, elem_normal, vertex_radiance, elem_exclude,
                    points, normals, seeds, off, side):
    """``(n, 3) float64``: the mean radiance seen from each point over ``side²`` stratified,
    jittered, cosine-distributed rays (irradiance ``H = π ·`` this).

    Parameters
    ----------
    tri_verts : (T, 3) int, tri_element : (T,) int
        The grid triangles' vertices and elements; ``elem_normal (E, 3)`` their lit side.
    vertex_radiance : (V, 3) float64
        Radiance interpolated over the hit triangle (Gouraud); a back face or a miss is 0.
    elem_exclude : (E, 3) float64
        Radiance taken off a hit on that element (its emission, already counted as direct).
    points, normals : (n, 3) float64; seeds : (n,) int64 jitter seeds; off : the ray offset.

    Serial: the callers split the points into ranges run side by side (threads in-process,
    ``gather-…`` tasks on a cluster); each point's sum is the same whatever the split.
    """
    n = points.shape[0]
    out = np.zeros((n, 3))
    ss = side * side
    for i in range(n):
        nrm = normals[i]
        t, s = tangent_frame(nrm)
        o = points[i] + off * nrm
        acc = np.zeros(3)
        for k in range(ss):
            u = ((k % side) + hash01(seeds[i], 2 * k)) / side
            v = ((k // side) + hash01(seeds[i], 2 * k + 1)) / side
            d = _direction(nrm, t, s, u, v)
            th, tri, bu, bv = closest_hit_one(grid, o, d, off, np.inf)
            if tri < 0:
                continue
            e = tri_element[tri]
            en = elem_normal[e]
            if d[0] * en[0] + d[1] * en[1] + d[2] * en[2] >= 0.0:
                continue
            w0 = 1.0 - bu - bv
            for c in range(3):
                acc[c] += (w0 * vertex_radiance[tri_verts[tri, 0], c]
                           + bu * vertex_radiance[tri_verts[tri, 1], c]
                           + bv * vertex_radiance[tri_verts[tri, 2], c]
                           - elem_exclude[e, c])
        for c in range(3):
            out[i, c] = acc[c] / ss
    return out
