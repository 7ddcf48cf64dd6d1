"""Shooters sampled at several points where an occluder is near (shooting.PENUMBRA, issue 7).

The blocker test (kernels/blockers.py) is a necessary condition for occlusion, so these tests
check both directions: it finds the occluders that are there and finds none in scenes that have
none (a convex room keeps the single centroid pass, bit for bit).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from daskrad import formfactor
from daskrad.formfactor import shooting
from daskrad.kernels.geometry import element_planes
from daskrad.mesh import build_hierarchy
from daskrad.scene import box_scene
from daskrad.scene.corners import real_corners
from daskrad.testing import stress as sc


def _context(scene, patch=0.25, element=0.125, method="hemisphere", resolution=64,
             cut_contacts=True):
    h = build_hierarchy(scene, patch, element, cut_contacts=cut_contacts)
    return h, shooting.make_context(h, method, resolution)


def _blocker_distance(ctx, p):
    """Distance to the nearest occluder of patch ``p`` in its own radii."""
    return shooting.occluder_distance(ctx, p) / ctx.patch_radius[p]


def test_a_convex_room_has_no_occluders_and_keeps_the_centroid_row_bit_for_bit():
    scene = box_scene(size=(1.0, 0.7, 1.3), diffuse=0.5, emission_per_face=1 / math.pi,
                      subdivisions=2)
    h, ctx = _context(scene)
    for p in range(h.n_patches):
        assert _blocker_distance(ctx, p) == np.inf
        points, weights = shooting.shooter_points(ctx, p)
        np.testing.assert_array_equal(points, h.patch_centroid[p][None])
        np.testing.assert_array_equal(weights, [1.0])
    # every wall's plane has the whole scene in front of it, none behind
    from daskrad.kernels.blockers import BEHIND
    assert not np.any(ctx.polygon_sides[ctx.polygon_sides >= 0] & BEHIND)


def test_the_fin_is_an_occluder_for_the_floor_beside_it_and_not_for_the_far_ceiling():
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    floor = np.flatnonzero((np.abs(h.patch_centroid[:, 1]) < 1e-12)
                           & (np.abs(h.patch_centroid[:, 0] - 0.5) < 0.2)
                           & (h.patch_centroid[:, 2] > 0.2) & (h.patch_centroid[:, 2] < 0.8))
    assert len(floor) == 4          # the floor patches touching the fin's foot, both sides
    for p in floor:
        assert _blocker_distance(ctx, p) < 0.5       # its foot touches the patch
        assert len(shooting.shooter_points(ctx, p)[0]) == 2 * len(shooting.SHOOTER_POINTS)  # 2 tri.
    # a ceiling corner patch: the fin (top at y = 0.4) is 3.9 radii away (sampled), and
    # farther than 4 when the patches are halved (the centroid alone)
    corner = np.flatnonzero((h.patch_centroid[:, 1] > 1 - 1e-12)
                            & (np.linalg.norm(h.patch_centroid[:, [0, 2]] - 0.125, axis=1)
                               < 1e-9))
    assert len(corner) == 1
    assert len(shooting.shooter_points(ctx, corner[0])[0]) == 2 * len(shooting.SHOOTER_POINTS)
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"], 0.125, 0.0625)
    corner = np.flatnonzero((h.patch_centroid[:, 1] > 1 - 1e-12)
                            & (np.linalg.norm(h.patch_centroid[:, [0, 2]] - 0.0625, axis=1)
                               < 1e-9))
    assert len(corner) == 1
    assert _blocker_distance(ctx, corner[0]) > 4.0
    assert len(shooting.shooter_points(ctx, corner[0])[0]) == 1


def test_a_search_within_a_reach_finds_the_nearest_blocker_when_it_lies_within():
    # the solver only asks whether a blocker lies within PENUMBRA radii, and passes that
    # reach so far elements are dismissed on their distance: the answer must be the full
    # search's distance when it is within the reach, and inf when it is not
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    full = np.array([shooting.occluder_distance(ctx, p) for p in range(h.n_patches)])
    assert np.isfinite(full).any() and np.isinf(full).any()
    cut = 0
    for radii in (0.5, 1.0, shooting.PENUMBRA, 16.0):
        reach = radii * ctx.patch_radius
        near = np.array([shooting.occluder_distance(ctx, p, reach[p])
                         for p in range(h.n_patches)])
        within = full < reach
        assert within.any()
        np.testing.assert_array_equal(near[within], full[within])
        assert np.isinf(near[~within]).all()
        cut += int((~within & np.isfinite(full)).sum())     # blockers beyond the reach
    assert cut > 0


def _floor_and(*quads):
    """A unit floor quad (facing +z) and two-sided quads with the given corners."""
    from daskrad.scene.validate import scene_from_arrays

    v = np.concatenate([[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], *quads]).astype(float)
    p = [[0, 1, 2, 3]]
    for k in range(len(quads)):
        p += [[4 + 4 * k + i for i in (0, 1, 2, 3)], [4 + 4 * k + i for i in (3, 2, 1, 0)]]
    return scene_from_arrays(v, np.array(p), np.zeros(len(p), int), [[0.5] * 3], [[1.0] * 3])


#: A wall standing far beyond the floor's +x edge, so that a ramp there has scene behind it.
FAR_WALL = [[3.0, 0, 0], [3.0, 1, 0], [3.0, 1, 2], [3.0, 0, 2]]


@pytest.mark.parametrize("quads, blocks", [
    ([[[0.2, 0.2, 0.3], [0.8, 0.2, 0.3], [0.8, 0.8, 0.3], [0.2, 0.8, 0.3]]], False),  # a card
    # parallel above the floor: the scene has nothing beyond its plane, so it hides nothing
    ([[[0.5, 0.2, 0.1], [0.5, 0.8, 0.1], [0.5, 0.8, 0.9], [0.5, 0.2, 0.9]]], True),  # upright
    ([[[0.2, 0.2, -0.9], [0.8, 0.2, -0.9], [0.8, 0.2, -0.1], [0.2, 0.2, -0.1]]], False),  # below
    ([[[1.0, 0, 0], [2.0, 0, 0.3], [2.0, 1, 0.3], [1.0, 1, 0]]], False),   # a ramp, 17°, with
    # nothing behind it; with a wall behind it it hides part of the wall, unless it only grazes
    ([[[1.0, 0, 0], [2.0, 0, 0.3], [2.0, 1, 0.3], [1.0, 1, 0]], FAR_WALL], True),
    ([[[1.0, 0, 0], [2.0, 0, 0.01], [2.0, 1, 0.01], [1.0, 1, 0]], FAR_WALL], False),  # 0.6°
    # a card 0.005 above the floor, parallel to it, over half of it: it hides the wall from
    # that half at any elevation (the corner-only elevation test missed it)
    ([[[0.5, -1, 0.005], [3.0, -1, 0.005], [3.0, 2, 0.005], [0.5, 2, 0.005]], FAR_WALL], True),
])
def test_an_occluder_must_rise_in_front_of_the_shooter_with_scene_behind_it(quads, blocks):
    h, ctx = _context(_floor_and(*(np.array(q, float) for q in quads)), patch=1.0,
                      element=0.5)
    floor = np.flatnonzero(h.patch_polygon == 0)
    assert len(floor) == 1
    assert (_blocker_distance(ctx, floor[0]) < np.inf) == blocks


@pytest.mark.parametrize("p", range(0, 108, 7))
def test_shooter_points_are_an_area_quadrature_of_the_patch(p):
    # weights sum to 1, the points lie in the patch's plane, and their weighted mean is its
    # centroid (sub-triangle centroids weighted by area: exact for any planar polygon)
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    points, weights = shooting.shooter_points(ctx, p)
    assert weights.sum() == pytest.approx(1.0, abs=1e-15)
    assert np.all(weights > 0)
    np.testing.assert_allclose((points - h.patch_centroid[p]) @ h.patch_normal[p], 0.0,
                               atol=1e-15)
    np.testing.assert_allclose(weights @ points, h.patch_centroid[p], atol=1e-15)


def test_sampling_the_shooter_brings_fin_rows_closer_to_area_to_area_visibility():
    # reference: the area-averaged form factor from the floor patch beside the fin, by
    # raycasting (6² rays per point) from 4² points per triangle of the patch; the row from the
    # centroid alone misses the fin's penumbra on the far wall and floor, the sampled row
    # follows it. Measured L1 distance to the reference: 0.038 (centroid), 0.0083 (sampled),
    # limit: half the centroid's
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    p = int(np.flatnonzero((np.abs(h.patch_centroid[:, 1]) < 1e-12)
                           & (np.abs(h.patch_centroid[:, 0] - 0.375) < 1e-9)
                           & (np.abs(h.patch_centroid[:, 2] - 0.375) < 1e-9))[0])
    corners = h.vertices[real_corners(h.patch_verts[p])]
    bary = shooting.strata(4)
    pts = np.concatenate([bary @ corners[[0, 1, 2]], bary @ corners[[0, 2, 3]]])
    normals = np.repeat(h.patch_normal[p][None], len(pts), axis=0)
    reference = formfactor.raycast_rows(pts, normals, h.vertices, h.elem_verts,
                                        samples=6).mean(axis=0)
    centroid = formfactor.shooter_rows(h.patch_centroid[p][None], h.patch_normal[p][None],
                                       h.vertices, h.elem_verts, method="hemisphere",
                                       resolution=64)[0]
    sampled = shooting.shoot_row(ctx, p)
    far = np.linalg.norm(h.elem_centroid - h.patch_centroid[p], axis=1) > 0.5  # not near field
    err_centroid = np.abs(centroid - reference)[far].sum()
    err_sampled = np.abs(sampled - reference)[far].sum()
    assert err_sampled < 0.5 * err_centroid, (err_sampled, err_centroid)


def test_row_cache_gives_the_bits_of_a_recomputation_within_its_budget():
    # rows of the fin scene (centroid and sampled shooters both): a second pass through the
    # cache hits every row and returns the bits shoot_row computes afresh; a budget of three
    # rows keeps at most three, the most recently used
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    ids = np.arange(0, h.n_patches, 9)
    fresh = shooting.shoot_rows(ctx, ids)
    cache = shooting.RowCache()
    shooting.shoot_rows(ctx, ids, cache)
    again = shooting.shoot_rows(ctx, ids, cache)
    assert (cache.misses, cache.hits) == (len(ids), len(ids))
    for (a, fa), (b, fb) in zip(fresh, again, strict=True):
        np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(fa, fb)
        assert not fb.flags.writeable
    budget = sum(a.nbytes + f.nbytes for a, f in fresh[-3:])
    small = shooting.RowCache(max_bytes=budget)
    shooting.shoot_rows(ctx, ids, small)
    assert small.nbytes <= budget
    shooting.shoot_rows(ctx, ids[-3:], small)
    assert small.hits == 3


def test_row_cache_budget_holds_every_row_when_they_fit_else_a_share_of_memory():
    # a row has at most E nonzeros of 12 bytes and a patch at most two rows (sampled and
    # one-point): 2P · E · 12 bytes hold every row; a process with less memory than 4× that
    # gives the cache a quarter of its memory
    h, ctx = _context(box_scene(emission_per_face=0.1))
    everything = 12 * 2 * h.n_patches * h.n_elements
    assert shooting.row_cache_bytes(ctx, 2**40) == everything
    assert shooting.row_cache_bytes(ctx, everything) == everything // 4
    # and the rows of a whole solve fit in the budget "everything" gives: all kept
    cache = shooting.RowCache(shooting.row_cache_bytes(ctx, 2**40))
    rows = shooting.shoot_rows(ctx, np.arange(h.n_patches), cache)
    assert cache.nbytes == sum(a.nbytes + f.nbytes for a, f in rows) <= everything
    shooting.shoot_rows(ctx, np.arange(h.n_patches), cache)
    assert (cache.misses, cache.hits) == (h.n_patches, h.n_patches)


def _rotation(degrees: float) -> np.ndarray:
    """A rotation by ``degrees`` about the axis (1, 2, 0.5) (Rodrigues)."""
    k = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    a = math.radians(degrees)
    return np.eye(3) + math.sin(a) * K + (1 - math.cos(a)) * K @ K


@pytest.mark.parametrize("degrees", [0.0, 37.0], ids=["upright", "tilted"])
def test_points_under_a_block_standing_on_the_shooter_are_dropped(degrees):
    # a floor (one patch, facing +z) with a closed block standing on it (four sides and a top,
    # facing out, no bottom), and a card high above: sample points of the floor under the block
    # are enclosed (every probe ray meets a face from behind) and are dropped; the rest keep
    # their area weights, renormalised. Tilted, the probes leave in the floor's own frame (a
    # frame mixed up sends some below the floor, whose front they meet: no point enclosed)
    from daskrad.scene.validate import scene_from_arrays

    lo, hi, top = np.array([0.5, 0.2]), np.array([0.8, 0.8]), 0.3
    x0, y0, x1, y1 = *lo, *hi
    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]                        # floor
    v += [[x0, y0, 0], [x1, y0, 0], [x1, y1, 0], [x0, y1, 0],               # block base
          [x0, y0, top], [x1, y0, top], [x1, y1, top], [x0, y1, top]]       # block top
    v += [[0, 0, 2], [0, 1, 2], [1, 1, 2], [1, 0, 2]]                       # card, facing -z
    b = 4
    polys = [[0, 1, 2, 3],
             [b + 4, b + 5, b + 6, b + 7],                                  # top, +z
             [b + 0, b + 1, b + 5, b + 4], [b + 1, b + 2, b + 6, b + 5],     # sides, outwards
             [b + 2, b + 3, b + 7, b + 6], [b + 3, b + 0, b + 4, b + 7],
             [12, 13, 14, 15]]
    turn = _rotation(degrees)
    scene = scene_from_arrays(np.array(v, float) @ turn.T, np.array(polys), np.zeros(7, int),
                              [[0.5] * 3], [[1.0] * 3])
    # the floor uncut: by default it is cut along the block's feet (issue 14) and no patch
    # straddles it, but a block standing just above the floor (beyond tolerances.CONTACT) is
    # not cut along and the drop must still work
    h, ctx = _context(scene, patch=1.0, element=0.25, cut_contacts=False)
    floor = int(np.flatnonzero(h.patch_polygon == 0)[0])
    corners = h.vertices[real_corners(h.patch_verts[floor])]
    bary = shooting.SHOOTER_POINTS
    every = np.concatenate([bary @ corners[[0, 1, 2]], bary @ corners[[0, 2, 3]]])
    upright = every @ turn                          # back in the block's own frame
    under = np.all((upright[:, :2] > lo) & (upright[:, :2] < hi), axis=1)
    assert 0 < under.sum() < len(every)
    points, weights = shooting.shooter_points(ctx, floor)
    kept = {tuple(np.round(q, 12)) for q in points}
    assert kept == {tuple(np.round(q, 12)) for q in every[~under]}
    assert weights.sum() == pytest.approx(1.0, abs=1e-15)
    np.testing.assert_allclose(weights, weights[0])   # the two triangles have equal areas


@pytest.mark.parametrize("up_first", [True, False])
def test_points_under_an_open_two_sided_shelf_are_kept_whatever_the_face_order(up_first):
    # a two-sided shelf (two coincident faces) 0.1 above half of the floor, open at the sides:
    # light reaches the floor under it (from its underside and from the sides), so no point is
    # dropped, whichever of the two faces comes first in the file (which one a ray meets first
    # is round-off)
    from daskrad.scene.validate import scene_from_arrays

    v = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0],
         [0.3, -0.5, 0.1], [0.8, -0.5, 0.1], [0.8, 1.5, 0.1], [0.3, 1.5, 0.1],
         [-1, -1, 2], [-1, 2, 2], [2, 2, 2], [2, -1, 2]]                  # ceiling, facing -z
    up, down = [4, 5, 6, 7], [7, 6, 5, 4]
    polys = [[0, 1, 2, 3], *([up, down] if up_first else [down, up]), [8, 9, 10, 11]]
    scene = scene_from_arrays(np.array(v, float), np.array(polys), np.zeros(4, int),
                              [[0.5] * 3], [[1.0] * 3])
    h, ctx = _context(scene, patch=1.0, element=0.5)
    # the shelf is one two-sided face, meshed as its two sides (the back appended last)
    assert scene.two_sided.tolist() == [False, True, False]
    shelf = np.abs(h.patch_centroid[:, 2] - 0.1) < 1e-3
    assert ctx.polygon_two_sided[h.patch_polygon].tolist() == shelf.tolist()
    assert len(ctx.polygon_two_sided) == 4
    floor = int(np.flatnonzero(h.patch_polygon == 0)[0])
    points, weights = shooting.shooter_points(ctx, floor)
    assert len(points) == 2 * len(shooting.SHOOTER_POINTS)
    under = (points[:, 0] > 0.3) & (points[:, 0] < 0.8)
    assert under.any()


def test_a_one_point_row_is_keyed_apart_and_leaves_from_the_mean_sample_point():
    # a floor patch beside the fin is penumbra-sampled; its one-point row (key P + p) leaves
    # from the weighted mean of its sample points and is another row than the sampled one;
    # in a convex room both keys give the centroid's row, bit for bit
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"])
    P = h.n_patches
    p = int(np.flatnonzero((np.abs(h.patch_centroid[:, 1]) < 1e-12)
                           & (np.abs(h.patch_centroid[:, 0] - 0.5) < 0.2)
                           & (h.patch_centroid[:, 2] > 0.2) & (h.patch_centroid[:, 2] < 0.8))[0])
    assert shooting.key_patch(P + p, P) == (p, False) and shooting.key_patch(p, P) == (p, True)
    points, weights = shooting.shooter_points(ctx, p)
    assert len(points) > 1
    point, weight = shooting.one_point(points, weights)
    np.testing.assert_allclose(point[0], h.patch_centroid[p], atol=1e-12)  # none enclosed
    assert weight.tolist() == [1.0]
    cache = shooting.RowCache()
    (s_ids, s_f), (o_ids, o_f) = shooting.shoot_rows(ctx, [p, P + p], cache)
    one = shooting.shoot_row(ctx, p, sampled=False)
    np.testing.assert_array_equal(o_ids, np.flatnonzero(one > 0))
    np.testing.assert_array_equal(o_f, one[o_ids])
    dense = np.zeros(h.n_elements)
    dense[s_ids] = s_f
    assert np.abs(dense - one).sum() > 1e-3                 # the fin's penumbra differs
    assert cache.misses == 2 and cache.has(p) and cache.has(P + p)
    scene = box_scene(size=(1.0, 0.7, 1.3), diffuse=0.5, emission_per_face=1 / math.pi)
    h, ctx = _context(scene)
    for q in (0, h.n_patches - 1):
        np.testing.assert_array_equal(shooting.shoot_row(ctx, q),
                                      shooting.shoot_row(ctx, q, sampled=False))


def test_the_solver_checks_its_geometry_once_when_its_context_is_made():
    # make_context refuses a NaN vertex; the rows then trust the checked arrays
    # (formfactor.checked_geometry), while any other call of a method still checks them
    import dataclasses

    from daskrad.errors import SceneError

    h, _ = _context(box_scene(emission_per_face=0.1))
    bad = dataclasses.replace(h, vertices=h.vertices.copy())
    bad.vertices[0, 0] = np.nan
    with pytest.raises(SceneError, match="finite"):
        shooting.make_context(bad, "hemisphere", 32)
    point, normal = h.patch_centroid[:1], h.patch_normal[:1]
    with pytest.raises(SceneError, match="finite"):
        formfactor.analytic_rows(point, normal, bad.vertices, bad.elem_verts)
    with formfactor.checked_geometry():
        rows = formfactor.analytic_rows(point, normal, bad.vertices, bad.elem_verts)
    assert rows.shape == (1, h.n_elements)
    with pytest.raises(SceneError, match="finite"):       # the block has ended
        formfactor.analytic_rows(point, normal, bad.vertices, bad.elem_verts)


def _receiver_average_numpy(h, ctx, p, ids):
    """``F_ji`` from receivers ``ids`` to the whole patch ``p`` in numpy (the formula
    :func:`daskrad.kernels.nearfield.receiver_factors` computes): Lambert at the centroid, or
    for a receiver within ``CLOSE`` of its size the area-weighted mean over ``STRATA²``
    points of each triangle."""
    from daskrad.scene.corners import QUAD_HALVES, repeat_third

    c, nrm = h.elem_centroid[ids], h.elem_normal[ids]
    shooter = h.patch_verts[p:p + 1]
    rel = c - h.patch_centroid[p]
    dist = np.maximum(np.abs(rel @ h.patch_normal[p]),
                      np.linalg.norm(rel, axis=1) - ctx.patch_radius[p])
    close = dist < shooting.CLOSE * np.sqrt(h.elem_area[ids])
    F = formfactor.analytic_rows(c, nrm, h.vertices, shooter)[:, 0]
    if close.any():
        halves = h.vertices[repeat_third(h.elem_verts[ids[close]])][:, QUAD_HALVES]
        area = 0.5 * np.linalg.norm(np.cross(halves[:, :, 1] - halves[:, :, 0],
                                             halves[:, :, 2] - halves[:, :, 0]), axis=2)
        bary = shooting.strata(shooting.STRATA)
        pts = np.einsum("kc,mhcx->mhkx", bary, halves).reshape(-1, 3)
        f = formfactor.analytic_rows(pts, np.repeat(nrm[close], 2 * len(bary), axis=0),
                                     h.vertices, shooter)[:, 0].reshape(-1, 2, len(bary))
        F[close] = (f.mean(axis=2) * area).sum(axis=1) / area.sum(axis=1)
    return F


def _near_field_cases():
    from daskrad.mesh import default_sizes
    from daskrad.scene import load_scene
    from daskrad.testing.stress import random_soup
    from tests.helpers import CORNELL

    cornell = load_scene(CORNELL)
    patch, element = default_sizes(cornell)
    return {"fin": (sc.degenerate_scenes()["non-manifold edge (fin)"], 0.25, 0.125, 5),
            # blocks standing on the floor: sample points behind a near face's plane
            "cornell": (cornell, patch, element, 4),
            "triangle soup": (random_soup(np.random.default_rng(7), 40), 0.2, 0.1, 1)}


@pytest.mark.parametrize("sampled", [False, True])
@pytest.mark.parametrize("case", ["fin", "cornell", "triangle soup"])
def test_the_near_field_kernel_follows_reciprocity_visibility_and_the_rows_share(case, sampled):
    # daskrad.kernels.nearfield.near_field against its formulas in numpy: the near receivers
    # (F > 0, centroid within NEAR_FIELD radii, another polygon) get F_ji · A_j / A_i ·
    # visible_j, F_ji by Lambert to the whole patch (averaged over a close receiver), visible_j
    # the raster's factor over Lambert's unoccluded one from the same points (weighted means of
    # several, a point behind the receiver adding 0), rescaled to the share they had; every
    # other factor is left as it was. Round-off apart (the kernel sums in order, numpy
    # pairwise; numpy renormalises the normals): 1e-12.
    scene, patch, element, step = _near_field_cases()[case]
    h = build_hierarchy(scene, patch, element)
    ctx = shooting.make_context(h, "hemisphere", 64)
    checked = behind = 0
    for p in range(0, h.n_patches, step):
        points, weights = shooting.shooter_points(ctx, p)
        if not sampled:
            points, weights = shooting.one_point(points, weights)
        normals = np.repeat(h.patch_normal[p][None], len(points), axis=0)
        rows = formfactor.shooter_rows(points, normals, h.vertices, h.elem_verts,
                                       method="hemisphere", resolution=64)
        raw = weights @ rows
        ids = np.flatnonzero(
            (raw > 0)
            & (np.linalg.norm(h.elem_centroid - h.patch_centroid[p], axis=1)
               < shooting.NEAR_FIELD * ctx.patch_radius[p])
            & (h.elem_polygon != h.patch_polygon[p]))
        each = formfactor.analytic_rows(points, normals, h.vertices, h.elem_verts[ids])
        behind += int((each <= 0).sum())
        unoccluded = weights @ np.maximum(each, 0.0)
        visible = np.where(unoccluded > 0, np.clip(raw[ids] / np.where(
            unoccluded > 0, unoccluded, 1.0), 0.0, 1.0), 1.0)
        exact = (_receiver_average_numpy(h, ctx, p, ids) * h.elem_area[ids]
                 / h.patch_area[p] * visible)
        expected = raw.copy()
        if exact.sum() > 0:
            expected[ids] = exact * raw[ids].sum() / exact.sum()
        got = shooting.shoot_row(ctx, p, sampled=sampled)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
        checked += len(ids) > 0 and not np.allclose(expected, raw, rtol=0, atol=1e-9)
    assert checked >= 3                 # the correction moved rows, and was held to them
    if sampled and case == "cornell":
        assert behind > 0               # some sample point lay behind a near receiver


@pytest.mark.parametrize("method", sorted(formfactor.METHODS))
def test_the_contexts_element_planes_give_the_rows_of_planes_computed_per_row(method):
    # make_context computes the elements' planes once (they were computed twice a row); a
    # context without them (made by hand) computes them in each row: the same bits, sampled
    # rows and one-point rows, on the fin scene (occluders, penumbra sampling)
    h, ctx = _context(sc.degenerate_scenes()["non-manifold edge (fin)"], method=method)
    normal, offset = element_planes(h.vertices, h.elem_verts)
    assert np.array_equal(ctx.plane_normal, normal) and np.array_equal(ctx.plane_offset, offset)
    bare = dataclasses.replace(ctx, plane_normal=None, plane_offset=None)
    for p in range(h.n_patches):
        for sampled in (True, False):
            row = shooting.shoot_row(ctx, p, sampled=sampled)
            assert np.array_equal(row, shooting.shoot_row(bare, p, sampled=sampled))
    assert row.sum() > 0
