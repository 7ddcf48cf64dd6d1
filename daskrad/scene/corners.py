"""Corner arrays: the one definition of a polygon's triangles (docs/design.md §3).

Polygons, patches and elements are all ``corners : (n, 4) int`` arrays of vertex ids with
``-1`` in column 3 for a triangle. A planar convex quad ``(a, b, c, d)`` is the two triangles
of :data:`QUAD_HALVES`, ``(a, b, c)`` and ``(a, c, d)``: the voxel grid, the renderer's
Gouraud interpolation, the shooters' sample points, the receivers' strata and the reference
path tracer all split a quad this way, so they agree on which triangle a point lies in.
"""

from __future__ import annotations

import numpy as np

#: The corners of a quad's two triangles, split along its diagonal 0–2.
QUAD_HALVES = np.array([[0, 1, 2], [0, 2, 3]])


def is_quad(corners: np.ndarray) -> np.ndarray:
    """``(n,) bool``: rows with a fourth corner."""
    return np.asarray(corners)[:, 3] >= 0


def corner_count(corners: np.ndarray) -> np.ndarray:
    """``(n,) int64``: 3 or 4 corners per row."""
    return np.where(is_quad(corners), 4, 3).astype(np.int64)


def repeat_third(corners: np.ndarray) -> np.ndarray:
    """``(n, 4)``: the ``-1`` of a triangle replaced by its third corner, so every row indexes
    four real vertices (a triangle as a quad whose second half ``(a, c, c)`` is empty)."""
    corners = np.asarray(corners)
    return np.where(corners < 0, corners[:, 2:3], corners)


def split_quads(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every row as triangles: ``(tri (T, 3), owner (T,) int64)``.

    The first half (:data:`QUAD_HALVES` row 0) of every row in row order, then the second
    half of each quad in row order; ``owner`` is the row of each triangle.
    """
    corners = np.asarray(corners)
    quads = np.flatnonzero(is_quad(corners))
    tri = np.concatenate([corners[:, QUAD_HALVES[0]], corners[quads][:, QUAD_HALVES[1]]])
    owner = np.concatenate([np.arange(len(corners)), quads])
    return tri, owner


def real_corners(row: np.ndarray) -> np.ndarray:
    """One row's corner ids without the ``-1`` of a triangle: ``(3,)`` or ``(4,)``."""
    return row[:3] if row[3] < 0 else row
