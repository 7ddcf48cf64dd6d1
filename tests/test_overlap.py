"""The coplanar-overlap check (issue 13): its O(n log n) candidate search finds exactly the
pairs that testing every pair finds."""

from __future__ import annotations

import numpy as np
import pytest

from daskrad import tolerances
from daskrad.kernels.overlap import coplanar_overlap
from daskrad.scene.overlap import coplanar_overlaps


def _all_pairs(vertices, polygons, diag):
    """Every pair ``i < j`` facing the same way, through the exact kernel: O(n²)."""
    c = vertices[np.where(polygons >= 0, polygons, polygons[:, 2:3])]   # (Q, 4, 3)
    c = c - c.reshape(-1, 3).min(axis=0)
    n = np.cross(c[:, 1] - c[:, 0], c[:, 2] - c[:, 0])                  # corners are convex
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    i, j = np.triu_indices(len(polygons), 1)
    same = np.einsum("ij,ij->i", n[i], n[j]) > 0
    i, j = i[same], j[same]
    hit = coplanar_overlap(c, n, c.mean(axis=1), i, j, tolerances.COPLANAR * diag)
    return np.column_stack([i[hit], j[hit]])


def _soup(rng, n):
    """Triangles and quads of sizes from 1e-3 to 0.3 in five planes (two of them tilted, one
    pair 1e-12 apart: coplanar within the tolerance, and near a bucket boundary), both
    orientations, some sharing edges."""
    planes = [np.eye(3), np.eye(3)[[1, 2, 0]], np.linalg.qr(rng.normal(size=(3, 3)))[0],
              np.linalg.qr(rng.normal(size=(3, 3)))[0]]
    verts, polys = [], []
    for k in range(n):
        basis = planes[k % len(planes)]
        size = 10 ** rng.uniform(-3, -0.5)
        centre = rng.random(2)
        corners = 3 if rng.random() < 0.5 else 4
        ang = np.sort(rng.uniform(0, 2 * np.pi, corners))
        if rng.random() < 0.3:
            ang = ang[::-1]                                   # facing the other way
        uv = centre + size * np.column_stack([np.cos(ang), np.sin(ang)])
        offset = 0.5 + (1e-12 if k % 10 == 0 else 0.0)
        p = np.column_stack([uv, np.full(corners, offset)]) @ basis.T
        idx = len(np.concatenate(verts)) if verts else 0
        verts.append(p)
        polys.append(list(range(idx, idx + corners)) + [-1] * (4 - corners))
    return np.concatenate(verts), np.array(polys)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sweep_finds_exactly_the_pairs_of_the_all_pairs_test(seed):
    rng = np.random.default_rng(seed)
    v, p = _soup(rng, 600)
    diag = float(np.linalg.norm(v.max(axis=0) - v.min(axis=0)))
    expect = _all_pairs(v, p, diag)
    got = coplanar_overlaps(v, p, diag)
    assert len(expect) > 20                                   # the test means something
    np.testing.assert_array_equal(got, expect[np.lexsort(expect.T[::-1])])


def test_tiling_and_shared_edges_are_no_overlap():
    # a 30 × 30 grid of squares, each split into two triangles along a diagonal: 1800 faces
    # touching along edges and at corners, none overlapping
    k = 30
    g = np.stack(np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij"), -1)
    v = np.column_stack([g.reshape(-1, 2) / k, np.zeros((k + 1) ** 2)])
    i, j = np.divmod(np.arange(k * k), k)
    a, b = i * (k + 1) + j, (i + 1) * (k + 1) + j
    c, d = b + 1, a + 1
    tris = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    polys = np.column_stack([tris, np.full(len(tris), -1)])
    assert len(coplanar_overlaps(v, polys, np.sqrt(2))) == 0
