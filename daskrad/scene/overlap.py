"""Coplanar overlapping faces: two faces in one plane, lit on the same side, sharing area.

Such a pair z-fights (issue 7): wherever they overlap, every form factor, shadow ray and pixel
picks one of the two by round-off; the hidden one still shoots its emission and receives
nothing, which measured 50 % furnace error under a "rug" lying in the floor's plane. The input
is ambiguous (which face is the surface there?), so :func:`daskrad.scene.validate` refuses it
and names the two faces. Faces that merely share an edge or a corner, coplanar faces that are
disjoint (the Cornell ceiling's pieces around the light), and back-to-back faces (opposite
orientation: the two sides of a plate; the light in the ceiling's hole) are not overlaps.

Cost: candidate pairs come from bucketing planes (normal and offset quantized on five shifted
grids, so two planes closer than a fifth of a cell always share a bucket in one of them), then
a sweep over bounding boxes inside strips of each bucket; only pairs whose boxes overlap reach
the exact test. A scene whose planes are all different costs O(Q log Q), and so does a plane
tiled by faces of similar size (measured: 80,000 triangles in one plane, 4 s). Faces of very
different sizes in one plane make wide strips: at worst O(m^1.5) box pairs for m faces,
processed in bounded chunks.
"""

from __future__ import annotations

import numpy as np

from daskrad import tolerances

#: Candidate pairs tested per chunk (bounds the memory of a plane tiled by many faces).
CHUNK = 1 << 20


def _corners(vertices: np.ndarray, polygons: np.ndarray) -> np.ndarray:
    """``(Q, 4, 3) float64``; a triangle repeats its third corner."""
    return vertices[np.where(polygons >= 0, polygons, polygons[:, 2:3])]


def _distinct(x: np.ndarray) -> np.ndarray:
    """Sorted distinct values (sorting beats numpy's hashed ``unique`` on millions of int64)."""
    x = np.sort(x)
    return x[np.concatenate([[True], x[1:] != x[:-1]])] if len(x) else x


def _unit_normals(c: np.ndarray) -> np.ndarray:
    """``(Q, 3)`` unit normals from the diagonals (exact for planar quads and triangles)."""
    n = np.cross(c[:, 2] - c[:, 0], c[:, 3] - c[:, 1])
    tri = (c[:, 3] == c[:, 2]).all(axis=1)
    n[tri] = np.cross(c[tri, 1] - c[tri, 0], c[tri, 2] - c[tri, 0])
    length = np.linalg.norm(n, axis=1)
    return n / np.where(length > 0, length, 1.0)[:, None]


def _sweep(group: np.ndarray, lo: np.ndarray, hi: np.ndarray, eps: float):
    """Chunks ``(a, b)`` of index pairs in one group whose ``[lo, hi]`` intervals meet
    (within ``eps``), each pair once.

    Sort by (group, lo); for the face at sorted position ``s`` the partners are the following
    positions of its group whose ``lo <= hi_s + eps``. Ranks of ``lo`` make (group, lo) one
    integer key, so one ``searchsorted`` finds the end of every face's run.
    """
    n = len(group)
    order = np.lexsort((lo, group))
    g, lo_s, hi_s = group[order], lo[order], hi[order]
    values = np.sort(lo)
    key = g * (n + 1) + np.searchsorted(values, lo_s, side="left")
    query = g * (n + 1) + np.searchsorted(values, hi_s + eps, side="right")
    end = np.searchsorted(key, query, side="left")
    count = np.maximum(end - np.arange(n) - 1, 0)
    start = 0
    total = np.cumsum(count)
    while start < n:
        # positions [start, stop) give at most CHUNK pairs (at least one position)
        base = total[start - 1] if start else 0
        stop = max(int(np.searchsorted(total, base + CHUNK, side="right")), start + 1)
        k = count[start:stop]
        s = np.repeat(np.arange(start, stop), k)
        offset = np.arange(int(k.sum())) - np.repeat(np.cumsum(k) - k, k)
        yield order[s], order[s + 1 + offset]
        start = stop


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
    _, strip = np.unique(both, axis=0, return_inverse=True)
    return strip.reshape(-1), u


def _overlap(c, n, a, b, eps) -> np.ndarray:
    """``(k,) bool``: faces ``a`` and ``b`` (same orientation, coplanar within ``eps``) share
    a region wider than ``eps`` in every direction.

    Separating axes of two convex polygons in one plane: the in-plane normals of their edges.
    Touching along an edge or at a corner leaves an axis with overlap ``<= eps``: separate.
    """
    ca, cb = c[a], c[b]                                          # (k, 4, 3)
    both = np.concatenate([ca, cb], axis=1)                      # (k, 8, 3)
    edges = np.concatenate([np.roll(ca, -1, axis=1) - ca, np.roll(cb, -1, axis=1) - cb],
                           axis=1)
    axes = np.cross(edges, n[a][:, None, :])                     # in-plane edge normals
    length = np.linalg.norm(axes, axis=2)
    valid = length > 0                                           # a triangle's empty edge
    axes = axes / np.where(valid, length, 1.0)[..., None]
    proj = np.einsum("kax,kcx->kac", axes, both)                 # (k, 8 axes, 8 corners)
    pa, pb = proj[:, :, :4], proj[:, :, 4:]
    depth = (np.minimum(pa.max(axis=2), pb.max(axis=2))
             - np.maximum(pa.min(axis=2), pb.min(axis=2)))
    return ((depth > eps) | ~valid).all(axis=1)


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
    for shift in range(5):
        key = np.floor(params + shift / 5).astype(np.int64)
        _, group = np.unique(key, axis=0, return_inverse=True)
        group = group.reshape(-1)
        shared = np.bincount(group)[group] >= 2
        if not shared.any():
            continue
        sub = idx[shared]
        strip, u = _strips(group[sub], key[sub, :3] + 0.5 - shift / 5, lo[sub], hi[sub])
        twice = np.concatenate([sub, sub])
        lo_u = np.tile(lo[sub, u], 2)
        hi_u = np.tile(hi[sub, u], 2)
        for a, b in _sweep(strip, lo_u, hi_u, eps):
            a, b = twice[a], twice[b]
            keep = ((lo[a] <= hi[b] + eps) & (lo[b] <= hi[a] + eps)).all(axis=1)
            keep &= (a != b) & (np.einsum("ij,ij->i", n[a], n[b]) > 0)
            # one code per pair: the shifted grids and strips find a pair several times
            found.append(_distinct(np.minimum(a, b)[keep] * q + np.maximum(a, b)[keep]))
    codes = _distinct(np.concatenate(found)) if found else np.zeros(0, np.int64)
    hits = []
    for k in range(0, len(codes), CHUNK):
        a, b = np.divmod(codes[k:k + CHUNK], q)
        # every corner of each within eps of the other's plane
        da = np.abs(np.einsum("kcx,kx->kc", c[b] - centre[a][:, None], n[a])).max(axis=1)
        db = np.abs(np.einsum("kcx,kx->kc", c[a] - centre[b][:, None], n[b])).max(axis=1)
        keep = (da <= eps) & (db <= eps)
        a, b = a[keep], b[keep]
        hits.append(np.column_stack([a, b])[_overlap(c, n, a, b, eps)])
    if not hits:
        return np.zeros((0, 2), np.int64)
    return np.concatenate(hits).astype(np.int64)
