"""Visibility for the ray-cast form factor (Wallace, Elmquist & Haines 1989).

Wallace et al. shoot from the source to each **receiving vertex**: the unoccluded point-to-area
term is analytic and visibility is decided by shadow rays. Here the analytic term is Lambert's
exact point-to-polygon formula (:mod:`daskrad.kernels.lambert`); this kernel gives the
visibility factor: the fraction of an element's sample points the shooting point sees through
the voxel grid (:mod:`daskrad.kernels.grid`).

Samples of an element: ``samples = 1`` its centroid; ``samples = n >= 2`` a regular ``n × n``
lattice of parametric points including the corners (bilinear on a quad, barycentric ``i/(n-1),
j/(n-1)`` with ``i + j <= n - 1`` on a triangle), so ``n = 2`` is exactly the receiver-vertex
method. Only samples above the shooter's tangent plane are used (the analytic term counts only
that part); when none is (a centroid below the horizon) the corners are used instead.

A shadow ray starts ``offset`` off the shooter along its normal (so it does not hit the
shooter's own polygon) and stops ``offset`` short of the sample (so it does not hit the receiver
or the elements sharing the sample vertex).
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.grid import any_hit_one


@jit_leaf
def _sample(vertices, elem_verts, e, u, v, out):
    """Point ``(u, v)`` of element ``e``: bilinear on a quad, ``c0 + u(c1-c0) + v(c2-c0)`` on a
    triangle."""
    i0 = elem_verts[e, 0]
    i1 = elem_verts[e, 1]
    i2 = elem_verts[e, 2]
    i3 = elem_verts[e, 3]
    for k in range(3):
        if i3 >= 0:
            out[k] = ((1 - u) * (1 - v) * vertices[i0, k] + u * (1 - v) * vertices[i1, k]
                      + u * v * vertices[i2, k] + (1 - u) * v * vertices[i3, k])
        else:
            out[k] = (vertices[i0, k] + u * (vertices[i1, k] - vertices[i0, k])
                      + v * (vertices[i2, k] - vertices[i0, k]))


@jit_leaf
def _visible(grid, o, q, d, offset):
    """Whether the segment from ``o`` to ``q`` (less ``offset`` at the end) is unblocked."""
    for k in range(3):
        d[k] = q[k] - o[k]
    length = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    if length <= 2.0 * offset:
        return True
    return not any_hit_one(grid, o, d, 0.0, 1.0 - offset / length)


@jit
def raycast_visibility(points, normals, vertices, elem_verts, active, grid, samples, offset):
    """Fraction of each element's samples visible from each shooting point.

    Parameters
    ----------
    points, normals : (S, 3) float64
        Shooting points and unit normals.
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        ``-1`` in column 3 for a triangle.
    active : (S, E) bool
        Pairs to trace (those with a nonzero analytic term); the others get 0.
    grid : daskrad.kernels.grid.Grid
        Voxel grid over the elements' triangles.
    samples : int
        Samples per side (module docstring).
    offset : float
        Ray offset at both ends, scene units.

    Returns
    -------
    (S, E) float64
        Visible fraction in ``[0, 1]``.
    """
    n_shot = points.shape[0]
    n_elem = elem_verts.shape[0]
    out = np.zeros((n_shot, n_elem))
    o = np.empty(3)
    q = np.empty(3)
    d = np.empty(3)
    n = samples
    for s in range(n_shot):
        for k in range(3):
            o[k] = points[s, k] + offset * normals[s, k]
        for e in range(n_elem):
            if not active[s, e]:
                continue
            tri = elem_verts[e, 3] < 0
            seen = 0
            used = 0
            for attempt in range(2):
                # attempt 0: the lattice; attempt 1 (nothing above the horizon): the corners
                m = n if attempt == 0 else 2
                for a in range(m):
                    for b in range(m):
                        if m == 1:
                            u = 1.0 / 3.0 if tri else 0.5
                            v = u
                        else:
                            u = a / (m - 1)
                            v = b / (m - 1)
                            if tri and a + b > m - 1:
                                continue
                        _sample(vertices, elem_verts, e, u, v, q)
                        h = 0.0
                        for k in range(3):
                            h += normals[s, k] * (q[k] - points[s, k])
                        if not h > offset:
                            continue
                        used += 1
                        if _visible(grid, o, q, d, offset):
                            seen += 1
                if used > 0:
                    break
            out[s, e] = seen / used if used > 0 else 1.0
    return out
