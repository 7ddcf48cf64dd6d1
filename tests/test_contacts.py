"""The contact-edge search (``kernels/contacts.py``) against the rule it implements, tested on
every pair.

:func:`contact_edges` bins the edges in a uniform grid and tests only the edges of the cells a
polygon's box meets. The grid must only prune: the pairs it returns are compared, with
``np.array_equal``, with a brute-force loop over all ``Q · K`` (polygon, edge) pairs written
here from the kernel's docstring (same sums in the same order, so the same bits). The scenes
put many contacts where the grid could lose them: blocks standing on a floor of tiles and on
each other (edges along cell boundaries, shared by several cells), a triangle as large as the
scene (its box meets every cell), and a flat scene (no extent along one axis).
"""

from __future__ import annotations

import numpy as np
import pytest

from daskrad.kernels.contacts import contact_edges


def _quad(p, u, v):
    """The quad ``p, p+u, p+u+v, p+v`` (normal along ``u × v``)."""
    p, u, v = (np.asarray(x, float) for x in (p, u, v))
    return [p, p + u, p + u + v, p + v]


def blocks_scene(rng, n_blocks: int = 12):
    """A 4 × 4 tiled floor at z = 0, blocks standing on it (the first half) or stacked on an
    earlier block (their feet exactly in its top's plane), and a few random triangles.
    Returns ``(corners (Q, 4, 3), is_quad (Q,))``; a triangle repeats its third corner."""
    polys = [_quad((x, y, 0.0), (1, 0, 0), (0, 1, 0)) for x in range(4) for y in range(4)]
    tops = [0.0]
    for k in range(n_blocks):
        x, y = rng.uniform(0.0, 3.5, 2)
        w, d, h = rng.uniform(0.1, 1.0, 3)
        z = 0.0 if k < n_blocks // 2 else tops[rng.integers(len(tops))]
        polys += [_quad((x, y, z), (w, 0, 0), (0, 0, h)),
                  _quad((x + w, y, z), (0, d, 0), (0, 0, h)),
                  _quad((x + w, y + d, z), (-w, 0, 0), (0, 0, h)),
                  _quad((x, y + d, z), (0, -d, 0), (0, 0, h)),
                  _quad((x, y, z + h), (w, 0, 0), (0, d, 0))]
        tops.append(z + h)
    quads = len(polys)
    for _ in range(6):
        t = rng.uniform(0.0, 4.0, (3, 3))
        polys.append([t[0], t[1], t[2], t[2]])
    is_quad = np.arange(len(polys)) < quads
    return np.array(polys), is_quad


def kernel_inputs(corners, is_quad):
    """Unit normals and every polygon edge (3 per triangle, 4 per quad) with its owner."""
    tri = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals = tri / np.linalg.norm(tri, axis=1, keepdims=True)
    nxt = corners[:, [1, 2, 3, 0]]
    keep = np.ones((len(corners), 4), bool)
    keep[~is_quad, 2] = False                  # a triangle's empty edge c2 → c2
    owner = np.broadcast_to(np.arange(len(corners))[:, None], keep.shape)
    return (normals, np.ascontiguousarray(corners[keep]), np.ascontiguousarray(nxt[keep]),
            owner[keep].astype(np.int64))


def all_pairs(corners, is_quad, normals, a, b, owner, tol):
    """The docstring's rule over every (polygon, edge) pair, polygon by polygon, edges
    increasing."""
    lo = corners.min(axis=1) - tol
    hi = corners.max(axis=1) + tol
    off = (normals[:, 0] * corners[:, 0, 0] + normals[:, 1] * corners[:, 0, 1]
           + normals[:, 2] * corners[:, 0, 2])
    out = []
    for i, n in enumerate(normals):
        if not n @ n > 0.5:
            continue
        j = owner
        box = (np.maximum(a, b) >= lo[i]).all(axis=1) & (np.minimum(a, b) <= hi[i]).all(axis=1)
        da = n[0] * a[:, 0] + n[1] * a[:, 1] + n[2] * a[:, 2] - off[i]
        db = n[0] * b[:, 0] + n[1] * b[:, 1] + n[2] * b[:, 2] - off[i]
        nn = n[0] * normals[j, 0] + n[1] * normals[j, 1] + n[2] * normals[j, 2]
        c = corners[j]        # a triangle's fourth corner is its third: the same top
        top = (n[0] * c[:, :, 0] + n[1] * c[:, :, 1] + n[2] * c[:, :, 2] - off[i]).max(axis=1)
        hit = ((j != i) & box & (np.abs(da) <= tol) & (np.abs(db) <= tol)
               & (np.abs(nn) < 1.0 - 1e-6) & (top > tol))
        out += [(i, e) for e in np.flatnonzero(hit)]
    return np.array(out, np.int64).reshape(-1, 2)


def check(corners, is_quad, tol):
    normals, a, b, owner = kernel_inputs(corners, is_quad)
    got = contact_edges(corners, is_quad, normals, a, b, owner, tol)
    want = all_pairs(corners, is_quad, normals, a, b, owner, tol)
    assert got.dtype == np.int64 and np.array_equal(got, want)
    return got


@pytest.mark.parametrize("seed", range(4))
def test_grid_finds_every_contact(seed):
    """Blocks on a tiled floor and on each other: the grid's pairs are all pairs' (and there
    are many: each of the six blocks on the floor has four feet, each on one tile or more)."""
    corners, is_quad = blocks_scene(np.random.default_rng(seed))
    pairs = check(corners, is_quad, 1e-6 * 6.0)
    assert len(pairs) >= 4 * 6


def test_a_polygon_over_every_cell():
    """A triangle as large as the scene, with blocks standing on it: its box meets every cell
    of the grid, and an edge of a cell list several times must count once."""
    corners, is_quad = blocks_scene(np.random.default_rng(7), n_blocks=20)
    big = np.array([[[-1.0, -1.0, 0.0], [9.0, -1.0, 0.0], [-1.0, 9.0, 0.0], [-1.0, 9.0, 0.0]]])
    pairs = check(np.concatenate([big, corners]), np.concatenate([[False], is_quad]), 1e-6)
    on_big = pairs[pairs[:, 0] == 0, 1]
    assert len(on_big) >= 4 and len(np.unique(on_big)) == len(on_big)


def test_flat_scene_has_no_contacts():
    """Every polygon in the plane z = 0: the grid has one cell along z, and coplanar edges are
    no contacts (parallel planes)."""
    rng = np.random.default_rng(3)
    t = np.concatenate([rng.uniform(0.0, 1.0, (50, 3, 2)), np.zeros((50, 3, 1))], axis=2)
    corners = t[:, [0, 1, 2, 2]]
    assert len(check(corners, np.zeros(50, bool), 1e-6)) == 0


def _area(piece):
    """Area of a planar polygon ``(k, 3)`` in the plane z = 0 (shoelace; counter-clockwise
    about +z is positive)."""
    x, y = piece[:, 0], piece[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cut_polygons_tiles_each_polygon_with_convex_pieces_on_one_side_of_every_line(seed):
    # Quads and triangles of the plane z = 0 (normal +z), each cut by random segments that
    # cross it from side to side (a contact edge as long as the polygon: its line is cut
    # wherever it passes). Exact properties of a BSP cut: the pieces of a polygon tile it
    # (their areas sum to its area, to round-off: coordinates of order 1, so 1e-12), each is
    # a convex quad or triangle wound like the polygon, inside it, and on one side of every
    # cutting line (within the length tolerance); a polygon no segment crosses is its own
    # piece, bit for bit.
    from daskrad.kernels.contacts import cut_polygons

    rng = np.random.default_rng(seed)
    tol = 1e-9
    polys, quads = [], []
    for k in range(20):
        c = rng.uniform(0, 10, 2)
        r = rng.uniform(0.5, 2.0)
        ang = np.sort(rng.uniform(0, 2 * np.pi, 4 if k % 3 else 3))
        pts = np.column_stack([c[0] + r * np.cos(ang), c[1] + r * np.sin(ang),
                               np.zeros(len(ang))])
        polys.append(pts if len(pts) == 4 else np.vstack([pts, pts[2:3]]))
        quads.append(len(ang) == 4)
    corners = np.ascontiguousarray(polys)
    is_quad = np.array(quads)
    normals = np.tile([0.0, 0.0, 1.0], (len(polys), 1))
    edge_a, edge_b, start, edges, lines = [], [], [0], [], {}
    for i in range(len(polys)):
        own = []
        for _ in range(int(rng.integers(0, 4)) if i % 5 else 0):   # every fifth: uncut
            c = corners[i, :3].mean(axis=0) + np.append(rng.uniform(-0.3, 0.3, 2), 0.0)
            d = np.append(rng.normal(size=2), 0.0)
            d /= np.linalg.norm(d)
            edge_a.append(c - 5 * d)
            edge_b.append(c + 5 * d)
            own.append(len(edge_a) - 1)
        edges += own
        start.append(len(edges))
        lines[i] = own
    edge_a, edge_b = np.array(edge_a), np.array(edge_b)
    out_c, out_q, parent = cut_polygons(corners, is_quad, normals, edge_a, edge_b,
                                        np.array(start, np.int64), np.array(edges, np.int64),
                                        tol)
    assert np.all(np.diff(parent) >= 0) and set(parent) == set(range(len(polys)))
    cut_any = False
    for i in range(len(polys)):
        mine = np.flatnonzero(parent == i)
        whole = corners[i, :4 if is_quad[i] else 3]
        if not lines[i]:
            assert len(mine) == 1 and np.array_equal(out_c[mine[0]], corners[i])
            continue
        cut_any |= len(mine) > 1
        pieces = [out_c[j, :4 if out_q[j] else 3] for j in mine]
        assert abs(sum(_area(p) for p in pieces) - _area(whole)) < 1e-12 * _area(whole) + 1e-12
        for p in pieces:
            assert _area(p) > 0
            for a in range(len(p)):     # convex, counter-clockwise: every turn to the left
                u, v = p[(a + 1) % len(p)] - p[a], p[(a + 2) % len(p)] - p[(a + 1) % len(p)]
                assert u[0] * v[1] - u[1] * v[0] >= -1e-12
            for e in lines[i]:          # on one side of the line (within tol)
                m = np.cross([0.0, 0.0, 1.0], edge_b[e] - edge_a[e])
                m /= np.linalg.norm(m)
                s = (p - edge_a[e]) @ m
                assert s.min() >= -1e-9 or s.max() <= 1e-9
            for q in p:                 # inside the polygon
                for a in range(len(whole)):
                    u = whole[(a + 1) % len(whole)] - whole[a]
                    w = q - whole[a]
                    assert u[0] * w[1] - u[1] * w[0] >= -1e-9
    assert cut_any
    # A contact edge cuts only a polygon it runs through: the unit square, and an edge on the
    # line y = 0.5 that stops short of it (the line crosses the square, the edge does not),
    # then one that ends halfway in (it cuts the square in two along the whole line).
    square = np.array([[[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]])
    up = np.array([[0.0, 0.0, 1.0]])
    for (a, b), pieces in ((([2.0, 0.5, 0], [3.0, 0.5, 0]), 1),
                           (([-1.0, 0.5, 0], [0.5, 0.5, 0]), 2)):
        out = cut_polygons(square, np.array([True]), up, np.array([a], float),
                           np.array([b], float), np.array([0, 1], np.int64),
                           np.array([0], np.int64), tol)
        assert len(out[2]) == pieces
        if pieces == 1:
            assert np.array_equal(out[0][0], square[0])
