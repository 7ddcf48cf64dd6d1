"""The junction gather as a sparse operator (:func:`daskrad.kernels.gather.gather_operator`).

The rays of a vertex are cast once and every pass of the gather is ``G · L``: its rows must be
what the rays saw, exactly (closed room: every ray meets a front face), a form factor in
expectation, and independent of how the vertices are split into tasks.
"""

from __future__ import annotations

import numpy as np
import pytest

from daskrad.formfactor import element_grid
from daskrad.kernels.gather import apply_operator, gather_operator
from daskrad.kernels.grid import NO_LOCATOR, build_grid, locator
from daskrad.kernels.lambert import lambert_polygon
from daskrad.scene.corners import split_quads
from daskrad.testing import closed_box

SIDE = 24


def _box_operator(points, n=4, exclude=None, first_seed=0, located=False):
    """The operator rows of ``points`` (on the floor, facing up) in the closed unit box with
    ``n × n`` elements a face; the seeds are ``first_seed + row``, as vertex ids would be.
    ``located``: the rays' hits found among the box's 6 faces and located among the elements
    (:func:`daskrad.kernels.grid.closest_hit_located`)."""
    vertices, elem_verts = closed_box(n)
    grid, owner = element_grid(vertices, elem_verts)
    tri, _ = split_quads(elem_verts)
    normal = np.cross(vertices[elem_verts[:, 1]] - vertices[elem_verts[:, 0]],
                      vertices[elem_verts[:, 3]] - vertices[elem_verts[:, 0]])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    exclude = np.zeros((len(elem_verts), 3)) if exclude is None else exclude
    seeds = np.arange(first_seed, first_seed + len(points), dtype=np.int64)
    op = gather_operator(grid, np.ascontiguousarray(tri), np.asarray(owner), normal, exclude,
                         len(vertices), np.ascontiguousarray(points, dtype=np.float64),
                         normals, seeds, 1e-9, SIDE, *_polygons(located, grid), located)
    return op, vertices, elem_verts


def _polygons(located, grid):
    """``(polygons, locator)`` of the unit box's faces for :func:`gather_operator` (the
    element ``grid`` and no locator when not ``located``)."""
    if not located:
        return grid, NO_LOCATOR
    faces, quads = closed_box(1)
    tri, _ = split_quads(quads)
    return build_grid(faces[tri]), locator(grid.triangles)


def _floor_points(rng, k):
    return np.column_stack([rng.uniform(0.05, 0.95, (k, 2)), np.zeros(k)])


def test_in_a_closed_room_every_ray_is_counted_once(rng):
    # every ray from the floor meets a wall, ceiling or floor from inside (a front face), so
    # each row's weights (barycentric, over side² rays) sum to 1 and a uniform radiance is
    # gathered exactly; the emission taken off is the mean over the rays, here uniform too
    points = _floor_points(rng, 7)
    E = 6 * 16
    (indptr, cols, weights, excluded), vertices, _ = _box_operator(
        points, exclude=np.full((E, 3), 0.25))
    rows = np.add.reduceat(weights, indptr[:-1])
    np.testing.assert_allclose(rows, 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(excluded, 0.25, rtol=0, atol=1e-12)
    L = np.full((len(vertices), 3), 2.0)
    np.testing.assert_allclose(apply_operator(indptr, cols, weights, L), 2.0, atol=1e-12)
    # a vertex appears once per row (merged), so the row is as long as the vertices seen
    for i in range(len(points)):
        row = cols[indptr[i]:indptr[i + 1]]
        assert len(np.unique(row)) == len(row)


@pytest.mark.parametrize("wall", ["ceiling", "x0"])
def test_a_walls_radiance_gathers_its_form_factor(rng, wall):
    # radiance 1 at one face's vertices (each face of the box has its own vertices, so
    # Gouraud gives 1 on that face and 0 elsewhere): G · L is the fraction of cosine-weighted
    # rays that meet the face, whose expectation is Lambert's point-to-polygon factor. 576
    # stratified rays, ~48 strata on the face's outline each off by at most 1: σ ≲ 0.006, so 0.02
    points = _floor_points(rng, 5)
    (indptr, cols, weights, _), vertices, elem_verts = _box_operator(points)
    n = 16                      # elements per face, in closed_box's order
    face = {"ceiling": 1, "x0": 2}[wall]
    L = np.zeros((len(vertices), 3))
    L[np.unique(elem_verts[face * n:(face + 1) * n])] = 1.0
    got = apply_operator(indptr, cols, weights, L)[:, 0]
    square = {"ceiling": [[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]],
              "x0": [[0, 0, 0], [0, 0, 1], [0, 1, 1], [0, 1, 0]]}[wall]
    exact = [lambert_polygon(p[0], p[1], p[2], 0.0, 0.0, 1.0, np.array(square, float), 4)
             for p in points]
    np.testing.assert_allclose(got, exact, atol=0.02)
    assert 0.05 < min(exact) and max(exact) < 0.9       # a test that can fail


def test_the_rows_do_not_depend_on_the_split(rng):
    # a task's rows are those of the same vertices in one call: the same bits (the jitter is
    # seeded by the vertex id, the rows are merged per vertex in the order of its rays)
    points = _floor_points(rng, 9)
    whole, _, _ = _box_operator(points)
    a, _, _ = _box_operator(points[:4])
    b, _, _ = _box_operator(points[4:], first_seed=4)
    np.testing.assert_array_equal(whole[0], np.concatenate([a[0], b[0][1:] + a[0][-1]]))
    for k in (1, 2, 3):
        np.testing.assert_array_equal(whole[k], np.concatenate([a[k], b[k]]))
    # and another seed gives other rays (the test can fail)
    c, _, _ = _box_operator(points[4:], first_seed=5)
    assert not np.array_equal(b[2], c[2])


def test_rays_found_among_the_faces_gather_what_the_elements_walk_gathers(rng):
    # the box's 6 faces (12 triangles) find each ray's hit, the elements' triangles locate it:
    # the same rows to round-off (the box has no coincident faces, where the two may differ)
    points = _floor_points(rng, 6)
    walked, vertices, _ = _box_operator(points)
    located, _, _ = _box_operator(points, located=True)
    L = rng.random((len(vertices), 3))
    np.testing.assert_allclose(apply_operator(located[0], located[1], located[2], L),
                               apply_operator(walked[0], walked[1], walked[2], L),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(located[3], walked[3], atol=1e-12)
    assert len(located[1]) > 6 * 16
