"""The junction gather as a sparse operator (:mod:`daskrad.kernels.gather`): by rays
(:func:`~daskrad.kernels.gather.gather_operator`, walking the elements or found among the
polygons) and by the hemisphere base (:func:`~daskrad.kernels.gather.disc_operator`).

The directions of a vertex are cast once and every pass of the gather is ``G · L``: its rows
must be what the directions saw, exactly (closed room: every one meets a front face), a form
factor in expectation, and independent of how the vertices are split into tasks.
"""

from __future__ import annotations

import numpy as np
import pytest

from daskrad import render
from daskrad.formfactor import edge_split_angle, element_grid
from daskrad.kernels.gather import apply_operator, disc_operator, gather_operator
from daskrad.kernels.grid import NO_LOCATOR, build_grid, locator
from daskrad.kernels.lambert import lambert_polygon
from daskrad.scene.corners import split_quads
from daskrad.testing import closed_box, merge

SIDE = 24
#: The disc's side: ~573 pixels on the disc against SIDE² = 576 rays.
DISC = 27
#: The ways a row is found: rays walking the elements' grid, rays found among the faces and
#: located among the elements, the faces projected onto the hemisphere base.
WAYS = ["walk", "located", "disc"]


def _operator(vertices, elem_verts, faces, points, way, exclude=None, first_seed=0):
    """The operator rows of ``points`` (facing up) among the elements ``elem_verts`` of
    ``vertices``, whose surfaces are the quads ``faces`` (their corner coordinates, (F, 4, 3),
    the polygons a ray's hit is found among); the seeds are ``first_seed + row``, as vertex
    ids would be."""
    grid, owner = element_grid(vertices, elem_verts)
    tri, _ = split_quads(elem_verts)
    normal = np.cross(vertices[elem_verts[:, 1]] - vertices[elem_verts[:, 0]],
                      vertices[elem_verts[:, 3]] - vertices[elem_verts[:, 0]])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    points = np.ascontiguousarray(points, dtype=np.float64)
    normals = np.tile([0.0, 0.0, 1.0], (len(points), 1))
    exclude = np.zeros((len(elem_verts), 3)) if exclude is None else exclude
    seeds = np.arange(first_seed, first_seed + len(points), dtype=np.int64)
    quads = np.arange(4 * len(faces)).reshape(-1, 4)
    ftri, _ = split_quads(quads)
    polygons = build_grid(faces.reshape(-1, 3)[ftri])
    args = (grid, np.ascontiguousarray(tri), np.asarray(owner), normal, exclude, len(vertices),
            points, normals, seeds, 1e-9)
    if way == "disc":
        return disc_operator(*args, DISC, edge_split_angle(DISC, render.DISC_SAGITTA_PX),
                             1e-9, polygons, locator(grid.triangles))
    if way == "located":
        return gather_operator(*args, SIDE, polygons, locator(grid.triangles), True)
    return gather_operator(*args, SIDE, grid, NO_LOCATOR, False)


def _box_faces():
    """The unit box's 6 faces as quads ``(6, 4, 3)``, lit sides inwards."""
    faces, quads = closed_box(1)
    return faces[quads]


def _box_operator(points, way="walk", n=4, exclude=None, first_seed=0):
    """:func:`_operator` in the closed unit box with ``n × n`` elements a face."""
    vertices, elem_verts = closed_box(n)
    return _operator(vertices, elem_verts, _box_faces(), points, way, exclude,
                     first_seed), vertices, elem_verts


def _floor_points(rng, k):
    return np.column_stack([rng.uniform(0.05, 0.95, (k, 2)), np.zeros(k)])


@pytest.mark.parametrize("way", WAYS)
def test_in_a_closed_room_every_ray_is_counted_once(rng, way):
    # every direction from the floor meets a wall, ceiling or floor from inside (a front
    # face), so each row's weights (barycentric, over the directions) sum to 1 and a uniform
    # radiance is gathered exactly; the emission taken off is the mean over the directions,
    # here uniform too
    points = _floor_points(rng, 7)
    E = 6 * 16
    (indptr, cols, weights, excluded), vertices, _ = _box_operator(
        points, way, exclude=np.full((E, 3), 0.25))
    rows = np.add.reduceat(weights, indptr[:-1])
    np.testing.assert_allclose(rows, 1.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(excluded, 0.25, rtol=0, atol=1e-12)
    L = np.full((len(vertices), 3), 2.0)
    np.testing.assert_allclose(apply_operator(indptr, cols, weights, L), 2.0, atol=1e-12)
    # a vertex appears once per row (merged), so the row is as long as the vertices seen
    for i in range(len(points)):
        row = cols[indptr[i]:indptr[i + 1]]
        assert len(np.unique(row)) == len(row)


@pytest.mark.parametrize("way", WAYS)
@pytest.mark.parametrize("wall", ["ceiling", "x0"])
def test_a_walls_radiance_gathers_its_form_factor(rng, wall, way):
    # radiance 1 at one face's vertices (each face of the box has its own vertices, so
    # Gouraud gives 1 on that face and 0 elsewhere): G · L is the fraction of cosine-weighted
    # directions that meet the face, whose expectation is Lambert's point-to-polygon factor.
    # 576 stratified rays, ~48 strata on the face's outline each off by at most 1: σ ≲ 0.006,
    # so 0.02; the disc's ~573 pixels, ~50 along the outline, each in or out by its centre:
    # the same bound
    points = _floor_points(rng, 5)
    (indptr, cols, weights, _), vertices, elem_verts = _box_operator(points, way)
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


@pytest.mark.parametrize("way", WAYS)
def test_the_rows_do_not_depend_on_the_split(rng, way):
    # a task's rows are those of the same vertices in one call: the same bits (the jitter, or
    # the disc's turn and shift, is seeded by the vertex id, the rows are merged per vertex
    # in the order of its directions)
    points = _floor_points(rng, 9)
    whole, _, _ = _box_operator(points, way)
    a, _, _ = _box_operator(points[:4], way)
    b, _, _ = _box_operator(points[4:], way, first_seed=4)
    np.testing.assert_array_equal(whole[0], np.concatenate([a[0], b[0][1:] + a[0][-1]]))
    for k in (1, 2, 3):
        np.testing.assert_array_equal(whole[k], np.concatenate([a[k], b[k]]))
    # and another seed gives other rays (the test can fail)
    c, _, _ = _box_operator(points[4:], way, first_seed=5)
    assert not np.array_equal(b[2], c[2])


def test_rays_found_among_the_faces_gather_what_the_elements_walk_gathers(rng):
    # the box's 6 faces (12 triangles) find each ray's hit, the elements' triangles locate it:
    # the same rows to round-off (the box has no coincident faces, where the two may differ)
    points = _floor_points(rng, 6)
    walked, vertices, _ = _box_operator(points)
    located, _, _ = _box_operator(points, "located")
    L = rng.random((len(vertices), 3))
    np.testing.assert_allclose(apply_operator(located[0], located[1], located[2], L),
                               apply_operator(walked[0], walked[1], walked[2], L),
                               rtol=0, atol=1e-12)
    np.testing.assert_allclose(located[3], walked[3], atol=1e-12)
    assert len(located[1]) > 6 * 16


@pytest.mark.parametrize("way", WAYS)
def test_a_face_turned_away_hides_what_lies_behind_it(rng, way):
    # a one-sided panel at half height, lit side up, between floor points and the ceiling:
    # seen from below it is a back face, which shows no radiance yet hides the ceiling behind
    # it. From points with x, y in [0.4, 0.6] the panel [0.3, 0.7]² at z = 0.5 hides a part
    # of the ceiling it covers exactly (its shadow on z = 1 stays within the ceiling), so the
    # ceiling's light gathered is F(ceiling) - F(panel), Lambert's both; a gather that drew
    # no back face would give F(ceiling), 0.15 more here. Tolerance as for one wall's form
    # factor (the panel's outline adds ~30 boundary directions)
    box_v, box_e = closed_box(4)
    panel = np.array([[0.3, 0.3, 0.5], [0.7, 0.3, 0.5], [0.7, 0.7, 0.5], [0.3, 0.7, 0.5]])
    vertices, elem_verts = merge((box_v, box_e), (panel, np.array([[0, 1, 2, 3]], np.int32)))
    faces = np.concatenate([_box_faces(), panel[None]])
    points = np.column_stack([rng.uniform(0.4, 0.6, (5, 2)), np.zeros(5)])
    indptr, cols, weights, _ = _operator(vertices, elem_verts, faces, points, way)
    L = np.zeros((len(vertices), 3))
    L[np.unique(elem_verts[16:32])] = 1.0          # the ceiling's vertices
    got = apply_operator(indptr, cols, weights, L)[:, 0]
    ceiling = np.array([[0, 0, 1], [0, 1, 1], [1, 1, 1], [1, 0, 1]], float)
    below = panel[::-1]                              # facing the points
    exact = [lambert_polygon(*p, 0.0, 0.0, 1.0, ceiling, 4)
             - lambert_polygon(*p, 0.0, 0.0, 1.0, below, 4) for p in points]
    np.testing.assert_allclose(got, exact, atol=0.02)
    # the panel's vertices: a back face shows nothing
    L[:] = 0.0
    L[-4:] = 1.0
    assert np.all(apply_operator(indptr, cols, weights, L) == 0.0)


@pytest.mark.parametrize("way", ["located", "disc"])
def test_two_faces_back_to_back_show_the_one_facing_the_point(rng, way):
    # a tilted panel of two one-sided faces back to back (as converted papers are), the one
    # lit upwards 1e-10 below the other: seen from the floor it is a back face nearer than
    # the front one, so it wins every depth test (by far more than round-off, yet well within
    # the location's plane tolerance, ~1e-8 here). The face towards the points must show:
    # every direction meets a front face, the rows sum to 1, and the panel's underside
    # gathers its form factor
    box_v, box_e = closed_box(4)
    corners = np.array([[0.3, 0.3, 0.5], [0.7, 0.3, 0.54], [0.7, 0.7, 0.54], [0.3, 0.7, 0.5]])
    lowered = corners - [0.0, 0.0, 1e-10]
    up = np.array([[0, 1, 2, 3]], np.int32)
    down = up[:, ::-1].copy()
    vertices, elem_verts = merge((box_v, box_e), (lowered, up), (corners, down))
    faces = np.concatenate([_box_faces(), lowered[None], corners[::-1][None]])
    points = np.column_stack([rng.uniform(0.2, 0.8, (24, 2)), np.zeros(24)])
    indptr, cols, weights, _ = _operator(vertices, elem_verts, faces, points, way)
    np.testing.assert_allclose(np.add.reduceat(weights, indptr[:-1]), 1.0, rtol=0, atol=1e-12)
    L = np.zeros((len(vertices), 3))
    L[-4:] = 1.0                                     # the face lit downwards
    seen = apply_operator(indptr, cols, weights, L)[:, 0]
    below = corners[::-1]                            # its corners as the points see them
    exact = [lambert_polygon(*p, 0.0, 0.0, 1.0, below, 4) for p in points]
    np.testing.assert_allclose(seen, exact, atol=0.02)   # as one wall's form factor
    assert min(exact) > 0.05


def test_the_gather_method_follows_the_polygon_count(rng):
    # the disc projects every polygon from every vertex: for few polygons; the rays for many
    few = build_grid(rng.random((render.DISC_POLYGONS, 3, 3)))
    many = build_grid(rng.random((render.DISC_POLYGONS + 1, 3, 3)))
    assert render.gather_method(few) == "disc"
    assert render.gather_method(many) == "rays"
    assert render.gather_method(None) == "rays"      # no polygons: the elements are walked
    assert set(render.GATHER_METHODS) == {"rays", "disc"}
    # the disc is finer for a scene of more polygons (a furnished room's small objects)
    simple = build_grid(rng.random((render.DISC_SIMPLE, 3, 3)))
    assert render.gather_side(simple) == render.DISC_SIDE_SIMPLE < render.DISC_SIDE
    assert render.gather_side(few) == render.DISC_SIDE
    assert render.gather_side(many) == render.gather_side(None) == render.GATHER_SIDE
