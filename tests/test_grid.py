"""The uniform voxel grid (daskrad.kernels.grid) against brute force over every triangle.

The grid and the brute force share one ray–triangle test, so for the same triangle they return
bit-identical ``t``; they may differ only in which of two triangles hit at (nearly) the same
``t`` is reported (a ray through a shared edge), and then the two ``t`` agree to rounding.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from daskrad.kernels import grid as G

# Two triangles hit "at the same t" (a shared edge or vertex, or coplanar overlapping ones)
# compute t from different vertex data: the difference is rounding, far below 1e-9 relative.
T_RTOL = 1e-9


# ------------------------------------------------------------------------------------------
# Scenes and rays.


def soup(rng, n, offset=0.0, flat_axis=None, size=10.0):
    """Random triangles in a box of side ``size``: sizes log-uniform from 1e-6·size (tiny) to
    2·size (huge, sticking out of the box); optionally far from the origin or flat."""
    centres = rng.uniform(0.0, size, (n, 1, 3))
    scale = size * 10.0 ** rng.uniform(-6.0, np.log10(2.0), (n, 1, 1))
    tris = centres + scale * rng.normal(size=(n, 3, 3))
    if flat_axis is not None:
        tris[:, :, flat_axis] = 0.25 * size
    return tris + offset


def height_field(m, rng=None, offset=0.0):
    """A gridded surface over ``[0, m]²``: two triangles per unit square, z from a smooth
    function (random heights when ``rng`` is given). Returns (triangles, vertex heights)."""
    x, y = np.meshgrid(np.arange(m + 1.0), np.arange(m + 1.0), indexing="ij")
    z = 0.3 * np.sin(x) * np.cos(0.7 * y) if rng is None else rng.uniform(-0.5, 0.5, x.shape)
    p = np.stack([x, y, z], axis=-1)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    tris = np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3),
                           np.stack([a, c, d], -2).reshape(-1, 3, 3)])
    return tris + offset, z


def closed_box(m):
    """The surface of the unit cube, each face split into an m×m lattice of triangle pairs."""
    s = np.linspace(0.0, 1.0, m + 1)
    u, v = np.meshgrid(s, s, indexing="ij")
    faces = []
    for axis in range(3):
        for side in (0.0, 1.0):
            p = np.empty(u.shape + (3,))
            p[..., axis] = side
            p[..., (axis + 1) % 3] = u
            p[..., (axis + 2) % 3] = v
            a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
            faces.append(np.stack([a, b, c], -2).reshape(-1, 3, 3))
            faces.append(np.stack([a, c, d], -2).reshape(-1, 3, 3))
    return np.concatenate(faces)


def random_dirs(rng, n):
    d = rng.normal(size=(n, 3))
    return d * 10.0 ** rng.uniform(-2, 2, (n, 1))  # not unit: t is in units of |d|


def rays_random(rng, grid, n):
    lo = grid.origin
    hi = grid.origin + grid.dims * grid.cell
    span = hi - lo
    o = rng.uniform(lo - 0.3 * span, hi + 0.3 * span, (n, 3))
    return o, random_dirs(rng, n)


def rays_on_surface(rng, grid, n):
    tris = grid.triangles
    k = rng.integers(0, len(tris), n)
    w = rng.dirichlet(np.ones(3), n)
    o = np.einsum("nk,nkj->nj", w, tris[k])
    return o, random_dirs(rng, n)


def rays_on_cell_boundaries(rng, grid, n):
    """Origins on cell-boundary planes (two or three coordinates), directions with zero
    components (axis-parallel, or in a coordinate plane), so rays run along cell faces/edges."""
    idx = np.stack([rng.integers(0, int(grid.dims[a]) + 1, n) for a in range(3)], axis=1)
    o = grid.origin + idx * grid.cell
    free = rng.integers(0, 3, n)  # one coordinate of the origin anywhere in the box
    o[np.arange(n), free] = rng.uniform(grid.origin[free],
                                        grid.origin[free] + grid.dims[free] * grid.cell[free])
    d = rng.normal(size=(n, 3))
    zeros = rng.random((n, 3)) < 0.6
    d[zeros] = 0.0
    d[np.arange(n), free] = np.where(zeros.all(axis=1), 1.0, d[np.arange(n), free])
    d[~d.any(axis=1), 0] = 1.0
    return o, d


RAYS = {"random": rays_random, "surface": rays_on_surface, "boundary": rays_on_cell_boundaries}


def limits(rng, n, kind):
    if kind == "open":
        return np.zeros(n), np.full(n, np.inf)
    tmin = rng.uniform(0.0, 0.5, n) * (rng.random(n) < 0.5)
    return tmin, tmin + 10.0 ** rng.uniform(-3, 1, n)


# ------------------------------------------------------------------------------------------
# Checks.


def assert_agree(grid, o, d, tmin, tmax):
    """Closest and any hit through the grid equal brute force over every triangle."""
    tg, ig, ug, vg = G.closest_hit(grid, o, d, tmin, tmax)
    tb, ib, _, _ = G.closest_hit_brute(grid, o, d, tmin, tmax)
    assert tg.dtype == np.float64 and ig.dtype == np.int32
    np.testing.assert_array_equal(ig >= 0, ib >= 0)
    assert np.all(np.isinf(tg[ig < 0])) and np.all(ig[tg == np.inf] == -1)
    same = ig == ib
    np.testing.assert_array_equal(tg[same], tb[same])  # one shared test: bit-identical
    np.testing.assert_allclose(tg[~same], tb[~same], rtol=T_RTOL, atol=0)
    hit = ig >= 0
    assert np.all((tg[hit] > tmin[hit]) & (tg[hit] < tmax[hit]))
    # The barycentrics give the hit point: P = (1-u-v) V0 + u V1 + v V2 = o + t d. Both sides
    # are computed from the same float64 data; 1e-9 of the scene diagonal covers rounding.
    tri = grid.triangles[ig[hit]]
    u, v = ug[hit, None], vg[hit, None]
    p = (1 - u - v) * tri[:, 0] + u * tri[:, 1] + v * tri[:, 2]
    q = o[hit] + tg[hit, None] * d[hit]
    diag = np.linalg.norm(grid.dims * grid.cell)
    scale = diag + np.abs(grid.origin).max()
    np.testing.assert_allclose(p, q, rtol=0, atol=1e-9 * scale)
    ag = G.any_hit(grid, o, d, tmin, tmax)
    ab = G.any_hit_brute(grid, o, d, tmin, tmax)
    assert ag.dtype == np.bool_
    # Exact: both use the same test with the same limits (the issue allows disagreement
    # within eps of tmin/tmax; sharing the test makes even that impossible).
    np.testing.assert_array_equal(ag, ab)
    np.testing.assert_array_equal(ag, hit)  # any hit <=> some closest hit in (tmin, tmax)
    return hit


def registered_pairs(grid):
    """(cell, triangle) pairs of the grid's CSR lists."""
    counts = np.diff(grid.cell_start)
    cells = np.repeat(np.arange(len(counts)), counts)
    return cells, grid.cell_items.astype(np.int64)


def cell_of(grid, p):
    """Linear cell index of points p (n, 3), clamped into the grid."""
    ijk = np.floor((p - grid.origin) / grid.cell).astype(np.int64)
    ijk = np.clip(ijk, 0, grid.dims - 1)
    nx, ny, _ = grid.dims
    return (ijk[:, 2] * ny + ijk[:, 1]) * nx + ijk[:, 0]


# ------------------------------------------------------------------------------------------
# Property tests against brute force.


@settings(max_examples=40, deadline=None, derandomize=True)
@given(
    seed=st.integers(0, 2**32 - 1),
    n_tris=st.sampled_from([1, 7, 60, 400]),
    placement=st.sampled_from(["near", "far", "flat"]),
    ray_kind=st.sampled_from(sorted(RAYS)),
    limit_kind=st.sampled_from(["open", "limited"]),
    density=st.sampled_from([0.5, 2.0, 20.0]),
    rel_eps=st.sampled_from([1e-12, 1e-5]),
)
def test_soup_matches_brute_force(seed, n_tris, placement, ray_kind, limit_kind, density,
                                  rel_eps):
    # Hypothesis draws the seed (and prints it on failure), so a case replays exactly.
    rng = np.random.default_rng(seed)
    offset = 1e5 if placement == "far" else 0.0
    flat = int(rng.integers(3)) if placement == "flat" else None
    tris = soup(rng, n_tris, offset=offset, flat_axis=flat)
    grid = G.build_grid(tris, rel_eps=rel_eps, density=density)
    o, d = RAYS[ray_kind](rng, grid, 300)
    tmin, tmax = limits(rng, 300, limit_kind)
    assert_agree(grid, o, d, tmin, tmax)


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2**32 - 1), m=st.sampled_from([3, 10, 25]),
       ray_kind=st.sampled_from(sorted(RAYS)), far=st.booleans())
def test_height_field_matches_brute_force(seed, m, ray_kind, far):
    rng = np.random.default_rng(seed)
    tris, _ = height_field(m, rng, offset=np.array([1e4, -3e4, 2e4]) if far else 0.0)
    grid = G.build_grid(tris)
    o, d = RAYS[ray_kind](rng, grid, 400)
    assert_agree(grid, o, d, *limits(rng, 400, "open"))


def test_rng_soups_many_rays(rng):
    # One larger scene of each placement with many rays of every kind at once.
    for offset, flat in ((0.0, None), (-7e6, None), (0.0, 2), (3e3, 0)):
        grid = G.build_grid(soup(rng, 1500, offset=offset, flat_axis=flat))
        for make, kind in itertools.product(RAYS.values(), ("open", "limited")):
            o, d = make(rng, grid, 2000)
            hit = assert_agree(grid, o, d, *limits(rng, 2000, kind))
            assert 0.0 < hit.mean() < 1.0  # both outcomes are exercised


# ------------------------------------------------------------------------------------------
# Watertightness and exact answers.


def test_height_field_rays_through_vertices_and_edges_hit(rng):
    # Rays straight down onto lattice vertices (shared by 6 triangles), edge midpoints and
    # random points: none may slip through, and at a vertex t is the exact height drop.
    m = 12
    tris, z = height_field(m)
    grid = G.build_grid(tris, density=4.0)
    vx, vy = np.meshgrid(np.arange(1.0, m), np.arange(1.0, m), indexing="ij")
    pts = [np.stack([vx.ravel(), vy.ravel()], 1),
           np.stack([vx.ravel() + 0.5, vy.ravel()], 1),
           np.stack([vx.ravel(), vy.ravel() + 0.5], 1),
           np.stack([vx.ravel() + 0.5, vy.ravel() + 0.5], 1),  # the diagonal edges
           rng.uniform(0, m, (500, 2))]
    xy = np.concatenate(pts)
    o = np.column_stack([xy, np.full(len(xy), 5.0)])
    d = np.tile([0.0, 0.0, -2.0], (len(xy), 1))  # |d| = 2: t is half the drop
    t, tri, _, _ = G.closest_hit(grid, o, d, np.zeros(len(xy)), np.full(len(xy), np.inf))
    assert np.all(tri >= 0)
    nv = vx.size
    # 5 - z at a vertex, halved; rounding of the 1e-12-relative edge tolerance only.
    np.testing.assert_allclose(t[:nv], (5.0 - z[1:m, 1:m].ravel()) / 2.0, rtol=1e-12)
    assert G.any_hit(grid, o, d, 0.0, np.inf).all()
    assert_agree(grid, o, d, np.zeros(len(xy)), np.full(len(xy), np.inf))


def test_closed_box_no_ray_escapes(rng):
    # Every ray from inside a closed, lattice-tessellated cube hits it, including rays aimed
    # exactly at lattice vertices and edges, and the hit lies on the cube's surface.
    m = 6
    grid = G.build_grid(closed_box(m))
    n = 3000
    o = rng.uniform(0.05, 0.95, (n, 3))
    target = rng.integers(0, m + 1, (n, 3)) / m
    face = rng.integers(0, 3, n)
    target[np.arange(n), face] = rng.integers(0, 2, n)  # a lattice point on the surface
    d = np.where(rng.random((n, 1)) < 0.5, target - o, rng.normal(size=(n, 3)))
    t, tri, _, _ = G.closest_hit(grid, o, d, np.zeros(n), np.full(n, np.inf))
    assert np.all(tri >= 0)
    p = o + t[:, None] * d
    # On the surface: some coordinate at 0 or 1 to rounding (t from a 1e-12-tolerant test).
    dist = np.minimum(np.abs(p), np.abs(p - 1.0)).min(axis=1)
    assert dist.max() < 1e-12
    assert_agree(grid, o, d, np.zeros(n), np.full(n, np.inf))


def test_hit_beyond_cell_exit_is_not_accepted():
    # The classic grid bug: a long slanted triangle A (on the plane y = x / 10) lies in the
    # ray's first cell, but the ray at y = 0.3 meets it only at x = 3; a small triangle B at
    # x = 2 is closer. Accepting A's hit while walking the first cell would return A.
    a = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, 2.0], [10.0, 1.0, 0.5]])
    b = np.array([[2.0, 0.2, 0.0], [2.0, 0.4, 0.0], [2.0, 0.3, 1.0]])
    grid = G.build_grid(np.stack([a, b]), density=200.0)
    o = np.array([[0.01, 0.3, 0.5]])
    d = np.array([[1.0, 0.0, 0.0]])
    first = cell_of(grid, o)[0]
    in_first = grid.cell_items[grid.cell_start[first]:grid.cell_start[first + 1]]
    assert 0 in in_first and 1 not in in_first  # the trap is set
    t, tri, _, _ = G.closest_hit(grid, o, d, [0.0], [np.inf])
    # x = 2 exactly; t = 2 - 0.01 to one rounding.
    assert tri[0] == 1 and np.isclose(t[0], 2.0 - 0.01, rtol=1e-14)
    # Without B the ray hits A at x = 3.
    t, tri, _, _ = G.closest_hit(G.build_grid(a[None], density=200.0), o, d, [0.0], [np.inf])
    assert tri[0] == 0 and np.isclose(t[0], 3.0 - 0.01, rtol=1e-12)


@pytest.mark.parametrize("axis", [0, 1])
def test_edge_tolerance_hits_are_found_across_a_cell_boundary(axis):
    # A triangle whose edge lies eps/2 short of a cell-boundary plane: a ray 3/4 eps from the
    # edge, on the far side of the plane, hits by the edge tolerance, although the triangle
    # itself does not reach that cell. The grid must still find it (registration margin).
    rel_eps = 1e-6
    corners = np.array([[[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]],
                        [[10, 10, 10], [10 - 1e-3, 10, 10], [10, 10 - 1e-3, 10]]], float)
    probe = np.concatenate([corners, corners[:1]])  # same bounding box and count: same grid
    g0 = G.build_grid(probe, rel_eps=rel_eps, density=200.0)
    k = int(g0.dims[axis]) // 2
    plane = g0.origin[axis] + k * g0.cell[axis]  # the DDA's own boundary expression
    eps = g0.eps
    edge = plane - 0.5 * eps
    tri = np.array([[edge, 2.0, 5.0], [edge, 8.0, 5.0], [edge - 1.0, 5.0, 5.0]])
    if axis == 1:
        tri = tri[:, [1, 0, 2]]
    grid = G.build_grid(np.concatenate([corners, tri[None]]), rel_eps=rel_eps, density=200.0)
    np.testing.assert_array_equal(grid.dims, g0.dims)
    assert grid.eps == eps
    xs = np.array([edge + 0.75 * eps, edge + 1.5 * eps, edge - 0.25 * eps])
    o = np.tile([5.0, 5.0, 9.0], (3, 1))
    o[:, axis] = xs
    assert np.all(np.floor((xs[:2] - grid.origin[axis]) / grid.cell[axis]) == k)
    d = np.tile([0.0, 0.0, -1.0], (3, 1))
    t, tri_id, _, _ = G.closest_hit(grid, o, d, 0.0, np.inf)
    np.testing.assert_array_equal(tri_id, [2, -1, 2])  # within eps, beyond eps, inside
    assert_agree(grid, o, d, np.zeros(3), np.full(3, np.inf))


def test_barycentrics_and_units():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    grid = G.build_grid(tri)
    o = np.array([[0.2, 0.3, 1.0], [0.2, 0.3, -2.0], [0.6, 0.6, 1.0], [0.2, 0.3, 1.0]])
    d = np.array([[0.0, 0.0, -0.5], [0.0, 0.0, 4.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
    t, k, u, v = G.closest_hit(grid, o, d, 0.0, np.inf)
    # Exact in binary floating point up to one rounding of 0.2, 0.3 (u = x, v = y here).
    np.testing.assert_allclose(t, [2.0, 0.5, np.inf, np.inf], rtol=1e-15)
    np.testing.assert_array_equal(k, [0, 0, -1, -1])  # both sides count; outside; in-plane
    np.testing.assert_allclose(u[:2], [0.2, 0.2], rtol=1e-15)
    np.testing.assert_allclose(v[:2], [0.3, 0.3], rtol=1e-15)
    # tmin < t < tmax strictly, and any_hit respects tmax (shadow ray stops short).
    assert not G.any_hit(grid, o[:1], d[:1], 0.0, 2.0)[0]
    assert G.any_hit(grid, o[:1], d[:1], 0.0, 2.0 + 1e-9)[0]
    assert not G.any_hit(grid, o[:1], d[:1], 2.0, 3.0)[0]


def test_single_ray_functions_are_callable_from_other_kernels(rng):
    # Renderer, ray-cast form factors and direct light call the single-ray functions inside
    # their own numba loops, passing the Grid NamedTuple through.
    from numba import njit

    @njit
    def first_hits(grid, o, d):
        tri = np.empty(o.shape[0], dtype=np.int64)
        blocked = np.empty(o.shape[0], dtype=np.bool_)
        for r in range(o.shape[0]):
            tri[r] = G.closest_hit_one(grid, o[r], d[r], 0.0, np.inf)[1]
            blocked[r] = G.any_hit_one(grid, o[r], d[r], 0.0, 1.0)
        return tri, blocked

    grid = G.build_grid(soup(rng, 200))
    o, d = rays_random(rng, grid, 500)
    tri, blocked = first_hits(grid, o, d)
    np.testing.assert_array_equal(tri, G.closest_hit(grid, o, d, 0.0, np.inf)[1])
    np.testing.assert_array_equal(blocked, G.any_hit(grid, o, d, 0.0, 1.0))
    assert (tri >= 0).any() and (tri < 0).any()


def test_degenerate_inputs():
    tri = np.array([[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    grid = G.build_grid(tri)
    o = np.array([[0.2, 0.2, 1.0]] * 4)
    d = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, -1.0], [0.0, 0.0, -1.0], [0.0, 0.0, -1.0]])
    tmin = np.array([0.0, 0.0, 5.0, 0.0])
    tmax = np.array([np.inf, np.inf, 1.0, np.nan])
    t, k, _, _ = G.closest_hit(grid, o, d, tmin, tmax)
    assert np.all(k == -1) and np.all(np.isinf(t))
    assert not G.any_hit(grid, o, d, tmin, tmax).any()
    empty = G.build_grid(np.zeros((0, 3, 3)))
    assert G.closest_hit(empty, o[2:3], d[2:3], 0.0, np.inf)[1][0] == -1
    with pytest.raises(ValueError):
        G.build_grid(np.zeros((4, 3)))
    with pytest.raises(ValueError):
        G.build_grid(np.full((1, 3, 3), np.nan))


# ------------------------------------------------------------------------------------------
# Registration.


@pytest.mark.parametrize("placement", ["near", "far", "flat"])
def test_registration_covers_every_overlapped_cell(rng, placement):
    flat = 1 if placement == "flat" else None
    tris = soup(rng, 300, offset=2e5 if placement == "far" else 0.0, flat_axis=flat)
    exact = G.build_grid(tris, density=8.0)
    boxed = G.build_grid(tris, density=8.0, exact=False)
    np.testing.assert_array_equal(exact.dims, boxed.dims)
    T = len(tris)
    ec, et = registered_pairs(exact)
    bc, bt = registered_pairs(boxed)
    e_keys = np.unique(ec * T + et)
    b_keys = np.unique(bc * T + bt)
    assert len(e_keys) == len(ec) and len(b_keys) == len(bc)  # no duplicates in a cell

    # Bounding-box registration: exactly the cells the bounding box overlaps, give or take
    # cells the box only touches within the registration margin (1e-9 of the diagonal).
    lo = (tris.min(axis=1) - exact.origin) / exact.cell
    hi = (tris.max(axis=1) - exact.origin) / exact.cell
    tol = 1e-6  # in cells: far above the margin (~1e-9 diag) and rounding
    counts_min = np.prod(np.floor(hi - tol) - np.floor(lo + tol) + 1, axis=1).clip(min=0)
    counts_max = np.prod(np.floor(hi + tol) - np.floor(lo - tol) + 1, axis=1)
    got = np.bincount(bt, minlength=T)
    assert np.all(got >= counts_min) and np.all(got <= counts_max)

    # Exact registration: a subset of the bounding-box cells ...
    assert np.isin(e_keys, b_keys).all()
    # ... holding every cell that a point of the triangle lies in (dense barycentric samples,
    # vertices and edges included) ...
    s = np.linspace(0.0, 1.0, 41)
    u, v = np.meshgrid(s, s, indexing="ij")
    keep = u + v <= 1.0
    w = np.stack([1 - u[keep] - v[keep], u[keep], v[keep]], 1)
    pts = np.einsum("sk,tkj->tsj", w, tris)
    cells = cell_of(exact, pts.reshape(-1, 3)).reshape(T, -1)
    need = np.unique(cells * T + np.arange(T)[:, None])
    assert np.isin(need, e_keys).all()
    # ... and no cell that lies wholly on one side of the triangle's plane (beyond rounding).
    corners = np.array([[i, j, k] for i in (0, 1) for j in (0, 1) for k in (0, 1)], float)
    nx, ny, _ = exact.dims
    ijk = np.stack([ec % nx, (ec // nx) % ny, ec // (nx * ny)], 1)
    box = exact.origin + (ijk[:, None, :] + corners) * exact.cell  # (pairs, 8, 3)
    t = tris[et]
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    side = np.einsum("pcj,pj->pc", box - t[:, None, 0], n)
    slack = 1e-6 * np.linalg.norm(exact.dims * exact.cell)
    assert np.all((side.min(axis=1) <= slack) & (side.max(axis=1) >= -slack))
    if placement == "near":  # the test is not vacuous: SAT drops cells the box would keep
        assert len(e_keys) < len(b_keys)


@pytest.mark.parametrize("exact", [True, False])
def test_registration_is_the_same_grid_on_any_number_of_threads(rng, exact):
    # the triangles are registered side by side on numba's threads: the same lists, each
    # cell's triangles in ascending order, as one thread gives them
    import numba

    tris = soup(rng, 2000, offset=0.0, flat_axis=None)
    threads = numba.get_num_threads()
    try:
        numba.set_num_threads(1)
        one = G.build_grid(tris, density=4.0, exact=exact)
    finally:
        numba.set_num_threads(threads)
    many = G.build_grid(tris, density=4.0, exact=exact)
    np.testing.assert_array_equal(one.cell_start, many.cell_start)
    np.testing.assert_array_equal(one.cell_items, many.cell_items)
    cells, items = registered_pairs(many)
    order = np.lexsort((items, cells))
    np.testing.assert_array_equal(order, np.arange(len(items)))
    assert len(items) > len(tris)          # triangles lie in several cells: not vacuous


def test_huge_diagonal_triangle_registers_a_sheet_not_the_whole_box():
    # One triangle across the whole box on the plane x + y + z = 1.5, plus tiny ones at the
    # corners to fix the box: SAT registers ~a plane's worth of cells, not all of them.
    big = np.array([[[1.5, 0.0, 0.0], [0.0, 1.5, 0.0], [0.0, 0.0, 1.5]]])
    small = np.array([[[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]],
                      [[1, 1, 1], [1 - 1e-3, 1, 1], [1, 1 - 1e-3, 1]]], float)
    grid = G.build_grid(np.concatenate([big, small]), density=4000.0)
    nc = int(np.prod(grid.dims))
    cells, tris = registered_pairs(grid)
    n_big = int((tris == 0).sum())
    assert nc > 1000 and n_big < 0.3 * nc


# ------------------------------------------------------------------------------------------
# Fans: many rays from one origin, the surface's own triangles decided once.


def _fan_walk(shift=0.0, tmin=0.0, marks=True):
    """A numba loop casting each fan's rays with and without it; the fan is aimed at the
    origin, the rays leave from the origin moved ``shift`` along the normal, from ``tmin``.
    ``marks`` False: a fan without marks (``Fan.tested`` empty, as ``WALK_MARKS`` False makes
    them), whose walk remembers the last four triangles it tested, culled ones not taking a
    place."""
    from numba import njit

    n_marks = -1 if marks else 0

    @njit
    def walk(grid, origins, normals, dirs, tmax, primed):
        """Every ray of every fan, with and without the fan: closest (t, tri, u, v) and any
        hit before ``tmax``, and the any hit again through the fan's blocker cache (slots
        0 and 1 taken in turn, primed with the triangles ``primed``, and -1: no cache); how
        many triangles each fan found wholly below it."""
        n, k = dirs.shape[0], dirs.shape[1]
        plain = np.empty((n, k, 4))
        fanned = np.empty((n, k, 4))
        any_plain = np.empty((n, k), np.bool_)
        any_fanned = np.empty((n, k), np.bool_)
        any_cached = np.empty((n, k), np.bool_)
        below = np.zeros(n, np.int64)
        made = G.new_fan(grid, 2)
        marks = made.tested if n_marks < 0 else np.full(0, -1, np.int32)
        fan = G.Fan(made.stamp, made.key, made.origin, made.normal, made.margin, made.blocker,
                    marks, made.ray)
        fan.blocker[:] = primed
        for i in range(n):
            G.aim_fan(fan, grid, origins[i], normals[i], 1e-7)
            o = origins[i] + shift * normals[i]
            for r in range(k):
                t, tri, u, v = G.closest_hit_one(grid, o, dirs[i, r], tmin, np.inf)
                plain[i, r, 0], plain[i, r, 1], plain[i, r, 2], plain[i, r, 3] = t, tri, u, v
                t, tri, u, v = G.closest_hit_fan(grid, fan, o, dirs[i, r], tmin, np.inf)
                fanned[i, r, 0], fanned[i, r, 1], fanned[i, r, 2], fanned[i, r, 3] = \
                    t, tri, u, v
                any_plain[i, r] = G.any_hit_one(grid, o, dirs[i, r], tmin, tmax)
                any_fanned[i, r] = G.any_hit_fan(grid, fan, o, dirs[i, r], tmin, tmax)
                any_cached[i, r] = G.any_hit_cached(grid, fan, o, dirs[i, r], tmin, tmax,
                                                    r % 3 - 1)
            below[i] = (fan.stamp == 2 * fan.key[0] + 1).sum()
        return plain, fanned, any_plain, any_fanned, below, any_cached

    return walk


@pytest.mark.parametrize("marks", [True, False], ids=["marks", "registers"])
@pytest.mark.parametrize("offset", [0.0, 3e3])
def test_fan_gives_the_plain_walks_bits_and_skips_the_surface_below(rng, offset, marks):
    # Origins a ray offset above a height field (at lattice vertices, where 6 triangles meet,
    # and at random points), rays into the upper hemisphere, some grazing it, plus a soup of
    # small triangles just above, across and just below the tangent planes: the fan must find
    # exactly the hits of the plain walk, while skipping the field's triangles beneath.
    m = 10
    field, _ = height_field(m, offset=offset)
    grid0 = G.build_grid(field)
    n_fan, k = 40, 64
    xy = np.concatenate([rng.integers(1, m, (n_fan // 2, 2)).astype(float),
                         rng.uniform(0.5, m - 0.5, (n_fan - n_fan // 2, 2))])
    o = np.empty((n_fan, 3))
    nrm = np.empty((n_fan, 3))
    down = np.tile([0.0, 0.0, -20.0], (n_fan, 1))
    start = np.column_stack([xy + offset, np.full(n_fan, 10.0 + offset)])
    t, tri, _, _ = G.closest_hit(grid0, start, down, 0.0, np.inf)
    assert (tri >= 0).all()
    surface = start + t[:, None] * down
    e1 = field[tri, 1] - field[tri, 0]
    e2 = field[tri, 2] - field[tri, 0]
    nrm = np.cross(e1, e2)
    nrm *= np.sign(nrm[:, 2:3]) / np.linalg.norm(nrm, axis=1, keepdims=True)
    diag = float(np.linalg.norm(np.ptp(field.reshape(-1, 3), axis=0)))
    o = surface + 1e-7 * diag * nrm                      # the shadow rays' offset
    # small triangles about the tangent planes, half of them parallel to it, at heights of
    # ±1e-9 to ±1e-4 of the diagonal: grazing rays hit those just above
    nr = np.repeat(nrm, 8, axis=0)
    corners = rng.normal(0, 0.3, (8 * n_fan, 3, 3))
    flat = rng.random(8 * n_fan) < 0.5
    corners[flat] -= np.einsum("nkj,nj->nk", corners[flat], nr[flat])[..., None] * nr[flat, None]
    height = diag * 10.0 ** rng.uniform(-9, -4, (8 * n_fan, 1)) * rng.choice([-1.0, 1.0],
                                                                            (8 * n_fan, 1))
    soup_ = (np.repeat(o, 8, axis=0) + height * nr)[:, None] + corners
    grid = G.build_grid(np.concatenate([field, soup_]))
    # directions in each upper hemisphere: uniform, and a quarter grazing (d·n ~ 1e-9 .. 1e-3)
    d = rng.normal(size=(n_fan, k, 3))
    d -= np.minimum(np.einsum("nkj,nj->nk", d, nrm), 0.0)[..., None] * 2 * nrm[:, None]
    tang = d - np.einsum("nkj,nj->nk", d, nrm)[..., None] * nrm[:, None]
    graze = 10.0 ** rng.uniform(-9, -3, (n_fan, k // 4, 1))
    d[:, : k // 4] = tang[:, : k // 4] + graze * nrm[:, None]
    # the blocker cache starts from a field triangle under the first fan (culled) and a
    # soup triangle (most often missed); then each slot holds its last ray's blocker
    primed = np.array([int(tri[0]), len(field)], np.int64)
    plain, fanned, any_plain, any_fanned, below, any_cached = _fan_walk(marks=marks)(
        grid, o, nrm, d, 2.0, primed)
    np.testing.assert_array_equal(fanned, plain)          # t, tri, u, v: the same bits
    np.testing.assert_array_equal(any_fanned, any_plain)
    np.testing.assert_array_equal(any_cached, any_plain)
    # rays the cull does not hold for walk plainly: from another origin than the fan's (a
    # hair below it), going down, or with tmin < 0
    shifted = _fan_walk(shift=-2e-7 * diag, marks=marks)(grid, o, nrm, d, 2.0, primed)
    np.testing.assert_array_equal(shifted[1], shifted[0])
    np.testing.assert_array_equal(shifted[3], shifted[2])
    np.testing.assert_array_equal(shifted[5], shifted[2])
    down = _fan_walk(marks=marks)(grid, o, nrm, -d, 2.0, primed)
    np.testing.assert_array_equal(down[1], down[0])
    np.testing.assert_array_equal(down[5], down[2])
    assert (down[0][..., 1] >= 0).any()
    behind = _fan_walk(tmin=-1.0, marks=marks)(grid, o, nrm, d, 2.0, primed)
    np.testing.assert_array_equal(behind[1], behind[0])
    np.testing.assert_array_equal(behind[3], behind[2])
    np.testing.assert_array_equal(behind[5], behind[2])
    hit = plain[..., 1] >= 0
    assert 0.2 < hit.mean() < 1.0 and 0.0 < any_plain.mean() < 1.0
    # the soup's triangles met were hit somewhere, so the cull had something to get wrong
    assert (plain[..., 1][hit] >= len(field)).any()
    # every fan skipped triangles of the field under it (rays leave through them)
    assert (below > 0).all()


def _marked_walk():
    """A numba loop casting rays through one fan that is never aimed (nothing culled), so
    only its marks (``Fan.tested``) change the walk, beside the plain walk (the last four
    triangles remembered in registers) and the brute-force answers; the
    fan's ray numbers start at their last value with every triangle marked with the first
    number that follows, so the walk must clear the marks before it numbers a ray."""
    from numba import njit

    @njit
    def walk(grid, o, d, tmax):
        n = o.shape[0]
        marked = np.empty((n, 4))
        plain = np.empty((n, 4))
        brute = np.empty((n, 4))
        any_marked = np.empty(n, np.bool_)
        any_plain = np.empty(n, np.bool_)
        any_brute = np.empty(n, np.bool_)
        fan = G.new_fan(grid)
        fan.ray[0] = G.LAST_RAY
        fan.tested[:] = 0            # what a fan that did not clear would take for tested
        for i in range(n):
            t, tri, u, v = G.closest_hit_fan(grid, fan, o[i], d[i], 0.0, np.inf)
            marked[i, 0], marked[i, 1], marked[i, 2], marked[i, 3] = t, tri, u, v
            t, tri, u, v = G.closest_hit_one(grid, o[i], d[i], 0.0, np.inf)
            plain[i, 0], plain[i, 1], plain[i, 2], plain[i, 3] = t, tri, u, v
            t, tri, u, v = G.closest_hit_brute_one(grid, o[i], d[i], 0.0, np.inf)
            brute[i, 0], brute[i, 1], brute[i, 2], brute[i, 3] = t, tri, u, v
            any_marked[i] = G.any_hit_fan(grid, fan, o[i], d[i], 0.0, tmax)
            any_plain[i] = G.any_hit_one(grid, o[i], d[i], 0.0, tmax)
            any_brute[i] = G.any_hit_brute_one(grid, o[i], d[i], 0.0, tmax)
        return marked, plain, brute, any_marked, any_plain, any_brute, fan.ray[0]

    return walk


def test_a_fans_marks_give_the_brute_force_answers_where_big_triangles_span_many_cells(rng):
    # big triangles in a fine grid: a ray meets each in cell after cell, and tests it once
    # (its first answer stands: a miss stays a miss, a hit is the best or behind it)
    tris = rng.uniform(0.0, 10.0, (300, 1, 3)) + rng.normal(0.0, 3.0, (300, 3, 3))
    grid = G.build_grid(tris, density=64.0)
    assert len(grid.cell_items) > 40 * len(tris)           # each in many cells
    o = rng.uniform(0.0, 10.0, (2000, 3))
    d = random_dirs(rng, 2000) * rng.uniform(0.5, 20.0, (2000, 1))
    marked, plain, brute, any_marked, any_plain, any_brute, last = _marked_walk()(grid, o, d,
                                                                                  0.3)
    np.testing.assert_array_equal(marked, plain)          # t, tri, u, v: the same bits
    np.testing.assert_array_equal(any_marked, any_plain)
    np.testing.assert_array_equal(any_marked, any_brute)
    hit = brute[:, 1] >= 0
    np.testing.assert_allclose(marked[hit, 0], brute[hit, 0], rtol=T_RTOL)
    assert 0.3 < hit.mean() and 0.05 < any_brute.mean() < 0.95
    assert last == 2 * len(o) - 1        # the numbers started again from 0 after the last


def _located_scene(elements=4):
    """The unit box (lit inside) with two squares back to back at ``z = 0.5`` (one facing up,
    one down, coincident) and a lone square at ``z = 0.25`` that no element covers: the
    surfaces as polygons (one quad each, split) and as ``elements × elements`` element quads
    (split), with the triangles' lit normals."""
    from daskrad.scene.corners import split_quads
    from daskrad.testing import closed_box, grid, merge

    def square(z, up, n):
        o, u, v = [0.2, 0.2, z], [0.4, 0, 0], [0, 0.4, 0]
        return grid(o, u, v, n) if up else grid(o, v, u, n)

    def triangles(parts):
        vertices, quads = merge(*parts)
        tri, _ = split_quads(quads)
        return vertices[tri]

    polygons = triangles([closed_box(1), square(0.5, True, 1), square(0.5, False, 1),
                          grid([0.2, 0.6, 0.25], [0, 0.2, 0], [0.2, 0, 0], 1)])
    elements = triangles([closed_box(elements), square(0.5, True, 3), square(0.5, False, 3)])
    return G.build_grid(polygons), G.build_grid(elements), elements


def test_a_hit_found_among_the_polygons_is_located_on_the_elements_triangle(rng):
    # rays from inside the box: the hit found through the polygons' grid and located among
    # the element triangles is the walk's (the same t; a point both triangles hold where it
    # lies on an edge they share), but where the two squares coincide, back to back: there
    # the face towards the ray is taken, from above and from below, where the walk took
    # whichever round-off favoured
    polygons, elements, tris = _located_scene()
    loc = G.locator(elements.triangles)
    n = 4000
    o = rng.uniform(0.05, 0.95, (n, 3))
    d = rng.normal(size=(n, 3))
    # rays into the squares' corners and edges, and through the uncovered square
    d[:400] = np.array([0.2, 0.6, 0.5])[None] + rng.choice([0.0, 0.2, 0.4], (400, 1)) * \
        np.array([1.0, 0, 0]) - o[:400]
    d[400:600] = rng.uniform([0.2, 0.6, 0.25], [0.4, 0.8, 0.25], (200, 3)) - o[400:600]
    t0, tri0, _, _ = G.closest_hit(elements, o, d, 0.0, np.inf)
    t1, tri1, u, v = G.closest_hit_located_batch(polygons, loc, elements, o, d, 0.0, np.inf)
    assert (tri0 >= 0).all() and (tri1 >= 0).all()            # a closed box
    np.testing.assert_allclose(t1, t0, rtol=1e-12, atol=1e-12)
    p = o + t1[:, None] * d
    at = (1 - u - v)[:, None] * tris[tri1, 0] + u[:, None] * tris[tri1, 1] \
        + v[:, None] * tris[tri1, 2]
    np.testing.assert_allclose(at, p, atol=1e-12)           # the point, in that triangle
    assert (u >= -1e-9).all() and (v >= -1e-9).all() and (u + v <= 1 + 1e-9).all()
    normal = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    on_squares = np.abs(p[:, 2] - 0.5) < 1e-12
    on_squares &= (p[:, :2] > 0.2 - 1e-12).all(axis=1) & (p[:, :2] < 0.6 + 1e-12).all(axis=1)
    facing = np.einsum("ij,ij->i", normal[tri1], d) < 0
    q0 = o + G.closest_hit(polygons, o, d, 0.0, np.inf)[0][:, None] * d
    through = np.abs(q0[:, 2] - 0.25) < 1e-12          # met the uncovered square first
    assert on_squares.sum() > 300 and facing[on_squares & ~through].all()
    assert (tri1 == tri0)[~on_squares].mean() > 0.95       # but for shared edges
    walk_facing = np.einsum("ij,ij->i", normal[tri0], d) < 0
    assert not walk_facing[on_squares].all()               # the walk's coin: a test that fails
    # the square no element covers: the elements' walk answers, bit for bit
    tp = G.closest_hit(polygons, o, d, 0.0, np.inf)[0]
    q = o + tp[:, None] * d
    uncovered = (np.abs(q[:, 2] - 0.25) < 1e-12) & (q[:, 0] > 0.2) & (q[:, 0] < 0.4) \
        & (q[:, 1] > 0.6) & (q[:, 1] < 0.8)
    assert uncovered.sum() > 50 and (t1[uncovered] > tp[uncovered] + 1e-6).all()
    np.testing.assert_array_equal(tri1[uncovered], tri0[uncovered])
    np.testing.assert_array_equal(t1[uncovered], t0[uncovered])


@pytest.mark.parametrize("shift", [0.0, 3e7])
def test_a_twisted_quad_far_from_the_origin_is_hit_where_its_elements_are(rng, shift):
    # a quad twisted within the loader's planarity tolerance (PLANAR_QUAD of the diagonal):
    # the elements subdivide it bilinearly, the polygons split it along a diagonal, so the
    # two surfaces part by up to the twist; and the scene far from the origin, where the
    # coordinates' round-off grows. Every ray towards the quad meets it, never the wall
    # behind, at the walk's t; a degenerate element triangle (zero area, lowest id) in
    # every cell is never the one located
    from daskrad.scene.corners import split_quads
    from daskrad.testing import grid as quad_grid
    from daskrad.testing import merge

    twist = 0.9e-9 * np.sqrt(2.0)
    corners = np.array([[0, 0, 0], [1, 0, twist], [1, 1, 0], [0, 1, twist]]) + shift
    n = 8
    s_ = np.linspace(0.0, 1.0, n + 1)
    a, b = np.meshgrid(s_, s_, indexing="ij")
    bil = ((1 - a) * (1 - b))[..., None] * corners[0] + (a * (1 - b))[..., None] * corners[1] \
        + (a * b)[..., None] * corners[2] + ((1 - a) * b)[..., None] * corners[3]
    _, quads = quad_grid([0, 0, 0], [1, 0, 0], [0, 1, 0], n)
    wall_v, wall_q = quad_grid(np.array([-1.0, -1.0, -1.0]) + shift, [3, 0, 0], [0, 3, 0], 1)
    vertices, elems = merge((bil.reshape(-1, 3), quads), (wall_v, wall_q))
    tri, owner = split_quads(elems)
    degenerate = np.repeat(corners[:1], 3, axis=0)[None]
    element_tris = np.concatenate([degenerate, vertices[tri]])
    poly_tri, _ = split_quads(np.array([[0, 1, 2, 3]]))
    on_wall = np.concatenate([[False], owner == len(elems) - 1])
    wall_tris = element_tris[on_wall]
    polygons = G.build_grid(np.concatenate([corners[poly_tri], wall_tris]))
    elements = G.build_grid(element_tris)
    loc = G.locator(element_tris)
    assert np.isinf(loc[0, 12])
    m = 5000
    o = np.column_stack([rng.uniform(0, 1, (m, 2)), np.full(m, 1.0)]) + shift
    target = np.column_stack([rng.uniform(0, 1, (m, 2)), np.zeros(m)]) + shift
    d = target - o
    t0, tri0, _, _ = G.closest_hit(elements, o, d, 0.0, np.inf)
    t1, tri1, _, _ = G.closest_hit_located_batch(polygons, loc, elements, o, d, 0.0, np.inf)
    assert (tri0 > 0).all() and not on_wall[tri0].any()
    assert (tri1 > 0).all() and not on_wall[tri1].any()
    np.testing.assert_allclose(t1, t0, rtol=0, atol=1e-8)
