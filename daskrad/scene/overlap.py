"""Coplanar overlapping faces: two faces in one plane, lit on the same side, sharing area.

Such a pair z-fights (issue 7): wherever they overlap, every form factor, shadow ray and pixel
picks one of the two by round-off; the hidden one still shoots its emission and receives
nothing, which measured 50 % furnace error under a "rug" lying in the floor's plane. The input
is ambiguous (which face is the surface there?), so :func:`daskrad.scene.validate` refuses it
and names the two faces. Faces that merely share an edge or a corner, coplanar faces that are
disjoint (the Cornell ceiling's pieces around the light), and back-to-back faces (opposite
orientation: the two sides of a plate; the light in the ceiling's hole) are not overlaps.

Cost: candidate pairs come from bucketing planes (normal and offset quantized on five shifted
grids, so two planes closer than a fifth of a cell always share a bucket in one of them; a
bucket whose faces already shared one bucket of an earlier grid is not swept again), then a
sweep over bounding boxes inside strips of each bucket, in one numba loop that tests each pair
of meeting boxes exactly (:func:`daskrad.kernels.overlap.sweep_overlaps`) without listing the
candidates. A scene whose planes are all different costs O(Q log Q), and so does a plane tiled
by faces of similar size (measured, issue 13: 100,000 triangles in one plane, 1.0 s; 100,000
scattered small triangles with 35,630 overlapping pairs, 0.6 s). The cost is O(pairs of
meeting boxes) in general: faces of very different sizes in one plane make wide strips, and a
fan of n slivers around one corner has n²/2 meeting boxes (10⁴ slivers: 11 s), which is why
:func:`daskrad.scene.polygons.faces_to_polygons` never fans a big polygon.
"""

from __future__ import annotations

import numpy as np

from daskrad import tolerances
from daskrad.kernels.overlap import sweep_overlaps


def _corners(vertices: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """``(Q, 4, 3) float64``; a triangle repeats its third corner."""
    return vertices[np.where(polygons >= 0, polygons, polygons[:, 2:3])]


def _distinct(x: np.ndarray) -> np.ndarray:
    """Sorted distinct values (sorting beats numpy's hashed ``unique`` on millions of int64)."""
    x = np.sort(x)
    return x[np.concatenate([[True], x[1:] != x[:-1]])] if len(x) else x


def _row_ids(rows: np.ndarray) -> np.ndarray:
    """``(n,) int64`` ids of the distinct rows of ``rows (n, k)`` int64, equal rows equal ids
    (a lexsort: ``np.unique(axis=0)`` sorts a structured view, 10× slower on 10⁵ rows)."""
    order = np.lexsort(rows.T[::-1])
    s = rows[order]
    new = np.concatenate([[True], (s[1:] != s[:-1]).any(axis=1)])
    ids = np.empty(len(rows), np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def _within_one(group: np.ndarray, old: np.ndarray) -> np.ndarray:
    """``(Q,) bool``: faces whose ``group`` holds faces of a single ``old`` group only."""
    lo = np.full(group.max() + 1, np.iinfo(np.int64).max)
    hi = np.full(group.max() + 1, np.iinfo(np.int64).min)
    np.minimum.at(lo, group, old)
    np.maximum.at(hi, group, old)
    return (lo == hi)[group]


def _unit_normals(c: np.ndarray) -> np.ndarray:
    """``(Q, 3)`` unit normals from the diagonals (exact for planar quads and triangles)."""
    n = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1])
    tri = (c[:, 3] == c[:, 2]).all(axis=1)
    n[tri] = np.cross(c[tri, 1] - c[tri, 0], c[tri, 2] - c[tri, 0])
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


def _sweep_ends(group: np.ndarray, lo: np.ndarray, hi: np.ndarray, eps: float):
    """Sweep order and run ends of the intervals ``[lo, hi]`` in each group.

    Sort by (group, lo); the face at sorted position ``s`` meets the following positions of
    its group whose ``lo <= hi_s + eps``, i.e. positions ``s + 1 .. end[s] - 1``. Ranks of
    ``lo`` make (group, lo) one integer key, so one ``searchsorted`` finds every run's end.

    Returns ``order (m,)`` and ``end (m,)`` int64.
    """
    n = len(group)
    order = np.lexsort((lo, group))
    g, lo_s, hi_s = group[order], lo[order], hi[order]
    values = np.sort(lo)
    key = g * (n + 1) + np.searchsorted(values, lo_s, side="left")
    query = g * (n + 1) + np.searchsorted(values, hi_s + eps, side="right")
    end = np.searchsorted(key, query, side="left")
    return order, np.maximum(end, np.arange(n) + 1).astype(np.int64)


def _strips(group, normal, lo, hi):
    """Cut each plane bucket into strips, so a plane tiled by many faces costs O(faces).

    ``normal`` (the bucket's cell centre, the same for all its faces) picks the sweep axis
    ``u`` and the strip axis ``w``: the two world axes most nearly in the plane. Strips are as
    wide as the bucket's widest face along ``w``, so two faces that meet have their centres in
    one strip or in neighbouring ones: each face goes into its own strip and the next.

    Returns ``(2k,) int64`` strip ids (the first k rows: own strips, then the next ones) and
    the ``(k,)`` sweep axis.
    """
    order = np.argsort(np.abs(normal), axis=1)
    u, w = order[:, 0], order[:, 1]
    rows = np.arange(len(group))
    extent = hi[rows, w] - lo[rows, w]
    width = np.zeros(group.max() + 1)
    np.maximum.at(width, group, extent)
    width = np.where(width > 0, width, 1.0)[group]
    home = np.floor(0.5 * (lo[rows, w] + hi[rows, w]) / width).astype(np.int64)
    both = np.column_stack([np.tile(group, 2), np.concatenate([home, home + 1])])
    return _row_ids(both), u


def coplanar_overlaps(vertices: np.ndarray, polygons: np.ndarray, diag: float) -> np.ndarray:
    """Pairs of polygons that lie in one plane, face the same way and overlap.

    Parameters
    ----------
    vertices : (V, 3) float64
    polygons : (Q, 4) int
        Triangles (``-1`` in column 3) and planar convex quads, no zero-area ones.
    diag : float
        The scene's scale: coplanar and overlapping mean within ``COPLANAR * diag``.

    Returns
    -------
    (k, 2) int64
        ``(i, j)`` with ``i < j``, sorted; empty when there is none.
    """
    q = len(polygons)
    if q < 2:
        return np.zeros((0, 2), np.int64)
    eps = tolerances.COPLANAR * diag
    cell = tolerances.COPLANAR_CELL
    # relative to the box's corner: offsets keep their precision in a scene far from the origin
    c = _corners(vertices, polygons)
    c = c - c.reshape(-1, 3).min(axis=0)
    n = _unit_normals(c)
    centre = c.mean(axis=1)
    params = np.column_stack([n, np.einsum("ij,ij->i", n, centre) / diag]) / cell
    lo, hi = c.min(axis=1), c.max(axis=1)
    found = []
    idx = np.arange(q)
    earlier = []
    for shift in range(5):
        key = np.floor(params + shift / 5).astype(np.int64)
        group = _row_ids(key)
        shared = np.bincount(group)[group] >= 2
        # a bucket whose faces all shared one bucket of an earlier grid was swept there: the
        # usual case (a plane far from a cell boundary lands in one bucket on every grid)
        for old in earlier:
            shared &= ~_within_one(group, old)
        earlier.append(group)
        if not shared.any():
            continue
        sub = idx[shared]
        strip, u = _strips(group[sub], key[sub, :3] + 0.5 - shift / 5, lo[sub], hi[sub])
        twice = np.concatenate([sub, sub])
        lo_u = np.tile(lo[sub, u], 2)
        hi_u = np.tile(hi[sub, u], 2)
        order, end = _sweep_ends(strip, lo_u, hi_u, eps)
        found.append(sweep_overlaps(twice[order], end, lo, hi, c, n, centre, eps))
    if not found:
        return np.zeros((0, 2), np.int64)
    pairs = np.concatenate(found)
    # one row per pair: the shifted grids and the strips find a pair several times
    codes = _distinct(pairs[:, 0] * q + pairs[:, 1])
    return np.column_stack(np.divmod(codes, q)).astype(np.int64)
