"""Small geometric helpers shared by the form-factor kernels.

All functions are numba kernels over plain floats and arrays; the tuple-returning ones are
inlined by LLVM into their callers, so they cost nothing in inner loops.
"""

from __future__ import annotations

import numpy as np

from daskrad.kernels._jit import jit, jit_leaf
from daskrad.kernels.tolerances import LEX_TIE


@jit_leaf
def orthonormal_basis(nx, ny, nz):
    """Tangent vectors ``t1, t2`` completing the unit normal ``n`` to a right-handed frame.

    Branch-free construction of Duff et al. (2017, "Building an orthonormal basis,
    revisited"): exact for every unit ``n`` including ``n = (0, 0, -1)``, and deterministic, so
    the same normal always gives bit-identical local coordinates.

    Returns ``(t1x, t1y, t1z, t2x, t2y, t2z)`` with ``t1 × t2 = n``.
    """
    sign = 1.0 if nz >= 0.0 else -1.0
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    return (
        1.0 + sign * nx * nx * a, sign * b, -sign * nx,
        b, sign + ny * ny * a, -ny,
    )


@jit_leaf
def lex_less(ax, ay, az, bx, by, bz):
    """``a < b`` lexicographically: the canonical order of an edge's two endpoints.

    Two elements sharing an edge traverse it in opposite directions; computing everything
    derived from the edge (clip points, inserted points, scanline crossings) from the
    lexicographically smaller endpoint makes both get bit-identical results, so the raster is
    watertight across shared edges.

    Coordinates equal up to round-off (``LEX_TIE``, relative; daskrad/kernels/tolerances.py) tie
    and the next one decides: an edge perpendicular to the first axis has endpoints whose first
    coordinates are equal in exact arithmetic, and letting their round-off pick the canonical
    end would move the edge's split points (eq. 4) with the scene's units (issue 7: a ceiling
    shooter seeing a wall edge along its frame's second axis changed its row by 1.5 % at
    ×1000).
    """
    tie = LEX_TIE * (abs(ax) + abs(ay) + abs(az) + abs(bx) + abs(by) + abs(bz))
    if abs(ax - bx) > tie:
        return ax < bx
    if abs(ay - by) > tie:
        return ay < by
    if abs(az - bz) > tie:
        return az < bz
    # two points within round-off of each other (an edge ~1e-12 of its coordinates long):
    # plain lexicographic order, so that exactly one of a < b, b < a holds for distinct points
    if ax != bx:
        return ax < bx
    if ay != by:
        return ay < by
    return az < bz


@jit
def element_planes(vertices, elem_verts):
    """Unit normal and plane offset of every element.

    Parameters
    ----------
    vertices : (V, 3) float64
    elem_verts : (E, 4) int32
        Corner indices, counter-clockwise seen from the lit side, ``-1`` in column 3 for a
        triangle.

    Returns
    -------
    normal : (E, 3) float64
        Unit normal on the lit side: the cross product of the diagonals for a quad (exact for
        a planar quad, the best-fit direction for a slightly warped one), of two edges for a
        triangle. Zero for a degenerate element, which then faces nothing.
    offset : (E,) float64
        ``normal · mean(corners)``: the plane is ``{x : normal · x = offset}``.
    """
    n_elem = elem_verts.shape[0]
    normal = np.zeros((n_elem, 3))
    offset = np.zeros(n_elem)
    for e in range(n_elem):
        i0 = elem_verts[e, 0]
        i1 = elem_verts[e, 1]
        i2 = elem_verts[e, 2]
        i3 = elem_verts[e, 3]
        if i3 >= 0:
            ux = vertices[i2, 0] - vertices[i0, 0]
            uy = vertices[i2, 1] - vertices[i0, 1]
            uz = vertices[i2, 2] - vertices[i0, 2]
            wx = vertices[i3, 0] - vertices[i1, 0]
            wy = vertices[i3, 1] - vertices[i1, 1]
            wz = vertices[i3, 2] - vertices[i1, 2]
            cx = (vertices[i0, 0] + vertices[i1, 0] + vertices[i2, 0] + vertices[i3, 0]) * 0.25
            cy = (vertices[i0, 1] + vertices[i1, 1] + vertices[i2, 1] + vertices[i3, 1]) * 0.25
            cz = (vertices[i0, 2] + vertices[i1, 2] + vertices[i2, 2] + vertices[i3, 2]) * 0.25
        else:
            ux = vertices[i1, 0] - vertices[i0, 0]
            uy = vertices[i1, 1] - vertices[i0, 1]
            uz = vertices[i1, 2] - vertices[i0, 2]
            wx = vertices[i2, 0] - vertices[i0, 0]
            wy = vertices[i2, 1] - vertices[i0, 1]
            wz = vertices[i2, 2] - vertices[i0, 2]
            cx = (vertices[i0, 0] + vertices[i1, 0] + vertices[i2, 0]) / 3.0
            cy = (vertices[i0, 1] + vertices[i1, 1] + vertices[i2, 1]) / 3.0
            cz = (vertices[i0, 2] + vertices[i1, 2] + vertices[i2, 2]) / 3.0
        nx = uy * wz - uz * wy
        ny = uz * wx - ux * wz
        nz = ux * wy - uy * wx
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        if length > 0.0:
            nx /= length
            ny /= length
            nz /= length
            normal[e, 0] = nx
            normal[e, 1] = ny
            normal[e, 2] = nz
            offset[e] = nx * cx + ny * cy + nz * cz
    return normal, offset


@jit_leaf
def scene_diagonal(vertices):
    """Length of the bounding-box diagonal of ``vertices (V, 3) float64`` (0 when empty)."""
    if vertices.shape[0] == 0:
        return 0.0
    lo0 = hi0 = vertices[0, 0]
    lo1 = hi1 = vertices[0, 1]
    lo2 = hi2 = vertices[0, 2]
    for i in range(1, vertices.shape[0]):
        lo0 = min(lo0, vertices[i, 0])
        hi0 = max(hi0, vertices[i, 0])
        lo1 = min(lo1, vertices[i, 1])
        hi1 = max(hi1, vertices[i, 1])
        lo2 = min(lo2, vertices[i, 2])
        hi2 = max(hi2, vertices[i, 2])
    return np.sqrt((hi0 - lo0) ** 2 + (hi1 - lo1) ** 2 + (hi2 - lo2) ** 2)


@jit_leaf
def within_edges(c, m, x, y, z, nx, ny, nz, margin):
    """Whether the point ``(x, y, z)``, in the plane of the convex polygon ``c[:m] (m, 3)``
    (counter-clockwise about the unit normal ``n``), lies at least ``margin`` (a length)
    inside every edge's line; a negative ``margin`` lets it lie that far outside. NaN: no."""
    for a in range(m):
        b = a + 1 if a + 1 < m else 0
        ux = c[b, 0] - c[a, 0]
        uy = c[b, 1] - c[a, 1]
        uz = c[b, 2] - c[a, 2]
        wx = x - c[a, 0]
        wy = y - c[a, 1]
        wz = z - c[a, 2]
        # (u × w) · n: the signed distance from the edge's line times |u|
        s = (uy * wz - uz * wy) * nx + (uz * wx - ux * wz) * ny + (ux * wy - uy * wx) * nz
        if not s >= margin * np.sqrt(ux * ux + uy * uy + uz * uz):
            return False
    return True
