"""The per-pixel pass (paper eq. 9; issue 5, item 4): direct light recomputed per pixel."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from daskrad import render
from daskrad.formfactor import analytic_rows
from daskrad.scene import Camera, scene_from_arrays
from tests.helpers import render_context

LIGHT = np.array([-0.35, 2.0, 0.15])
INTENSITY = 3.0
RHO = 0.5
SQ = (0.13, 1.13, 0.21, 1.21)  # blocker: x0, x1, z0, z1 at y = 1


def _blocker_scene(size=48):
    """A 4 × 4 floor (ρ 0.5, facing up) and a black 1 × 1 blocker at y = 1 facing down, under
    a point light: the floor's only light is direct (the blocker reflects nothing), so its
    exact radiance is ``ρ I cosθ / (π r²)`` outside the shadow and 0 inside."""
    x0, x1, z0, z1 = SQ
    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [x0, 1, z0], [x1, 1, z0], [x1, 1, z1], [x0, 1, z1]], float)
    cam = Camera(eye=np.array([0.3, 6.0, 0.4]), look_at=np.array([0.3, 0.0, 0.4]),
                 up=np.array([0.0, 0.0, 1.0]), fov=42.0, width=size, height=size)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                             diffuse=[[RHO] * 3, [0.0] * 3], emission=[[0.0] * 3] * 2,
                             camera=cam, point_lights=(LIGHT[None], [[INTENSITY] * 3]))


def _render(ctx, tile=render.TILE):
    cam = ctx.camera
    image = np.zeros((cam.height, cam.width, 3))
    count = 0
    for rows, cols in render.tiles(cam.width, cam.height, tile):
        image[rows, cols], stats = render.render_tile_stats(ctx, rows, cols)
        count += stats["perpixel"] + stats["hard"]  # hard: point/directional light at a hit
    return image, count


def _analytic(cam):
    """Exact radiance at every pixel centre (spp 1) and whether the centre's floor point is in
    the shadow: ``(H, W)`` values, ``(H, W)`` int class (0 lit, 1 shadow, 2 blocker/miss)."""
    o, d = render.primary_rays(cam, slice(0, cam.height), slice(0, cam.width), 1)
    x0, x1, z0, z1 = SQ
    tb = (1.0 - o[:, 1]) / d[:, 1]
    pb = o + tb[:, None] * d
    on_blocker = (pb[:, 0] > x0) & (pb[:, 0] < x1) & (pb[:, 2] > z0) & (pb[:, 2] < z1)
    p = o + (-o[:, 1] / d[:, 1])[:, None] * d
    on_floor = (np.abs(p[:, 0]) < 2) & (np.abs(p[:, 2]) < 2) & ~on_blocker
    # where the segment p → light crosses y = 1
    s = (1.0 - p[:, 1]) / (LIGHT[1] - p[:, 1])
    c = p + s[:, None] * (LIGHT - p)
    shadow = (c[:, 0] > x0) & (c[:, 0] < x1) & (c[:, 2] > z0) & (c[:, 2] < z1)
    r = LIGHT - p
    r2 = (r**2).sum(axis=1)
    lit = RHO * INTENSITY * (r[:, 1] / np.sqrt(r2)) / r2 / math.pi
    value = np.where(on_floor & ~shadow, lit, 0.0)
    cls = np.where(on_floor, np.where(shadow, 1, 0), 2)
    return value.reshape(cam.height, cam.width), cls.reshape(cam.height, cam.width)


def _near_edge(cls):
    """``(H, W) bool``: pixels with a 4-neighbour of another class (within a pixel of an edge)."""
    edge = np.zeros(cls.shape, bool)
    edge[1:] |= cls[1:] != cls[:-1]
    edge[:-1] |= cls[1:] != cls[:-1]
    edge[:, 1:] |= cls[:, 1:] != cls[:, :-1]
    edge[:, :-1] |= cls[:, 1:] != cls[:, :-1]
    return edge


def test_point_light_shadow_is_sharp_to_within_a_pixel():
    scene = _blocker_scene()
    ctx, _ = render_context(scene, rdiff=0.05)
    image, count = _render(ctx)
    exact, cls = _analytic(scene.camera)
    assert count > 0
    # per pixel the direct light is exact (I cosθ/r², a shadow ray): away from the shadow's
    # outline every pixel equals the analytic value to round-off; a pixel whose centre lies
    # within a pixel of the outline may differ (the hit point and the analytic centre differ
    # by the grid's edge tolerance), so the edge is sharp to within a pixel
    wrong = ~np.isclose(image[..., 0], exact, rtol=1e-9, atol=1e-12)
    assert (cls == 1).sum() > 40             # the shadow is in view
    assert not (wrong & ~_near_edge(cls)).any()
    # the Gouraud image alone blurs the edge over whole elements: many pixels more than a
    # pixel away from the outline are wrong there (the test could fail)
    plain, count0 = _render(render_context(scene, per_pixel=False)[0])
    assert count0 == 0
    wrong0 = ~np.isclose(plain[..., 0], exact, rtol=1e-9, atol=1e-12)
    assert (wrong0 & ~_near_edge(cls)).sum() > 20


def _area_scene(size=40):
    """A floor (ρ 0.5) under a small square emitter facing down, nothing in between."""
    v = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1],
                  [-0.2, 0.6, -0.2], [0.2, 0.6, -0.2], [0.2, 0.6, 0.2], [-0.2, 0.6, 0.2]])
    cam = Camera(eye=np.array([0.0, 3.0, 0.05]), look_at=np.zeros(3),
                 up=np.array([0.0, 0.0, 1.0]), fov=40.0, width=size, height=size)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                             diffuse=[[RHO] * 3, [0.0] * 3], emission=[[0] * 3, [2.0] * 3],
                             camera=cam)


def test_no_qualifying_element_costs_nothing_and_changes_no_bit():
    # (area lights only: point and directional light is recomputed at every hit, test_shadows)
    scene = _area_scene(32)
    kw = dict(patch_size=2.0, element_size=0.5, subdivide=0.0)
    plain, _ = _render(render_context(scene, per_pixel=False, **kw)[0])
    # a threshold no element reaches: the plain context comes back, no pixel is recomputed
    ctx, _ = render_context(scene, rdiff=1e9, **kw)
    assert ctx.elem_perpixel is None and ctx.lights is None and not ctx.extras
    image, count = _render(ctx)
    assert count == 0
    assert np.array_equal(image, plain)


def test_pass_changes_only_pixels_of_qualifying_elements():
    # the per-pixel path itself leaves every pixel of a non-qualifying element bit-identical
    # (area lights: the elements of eq. 9 are chosen by the spread of their direct light)
    scene = _area_scene(32)
    kw = dict(patch_size=2.0, element_size=0.5, subdivide=0.0)
    plain, _ = _render(render_context(scene, per_pixel=False, **kw)[0])
    ctx, _ = render_context(scene, rdiff=0.01, **kw)
    image, count = _render(ctx)
    o, d = render.primary_rays(ctx.camera, slice(0, 32), slice(0, 32), 1)
    from daskrad.kernels.grid import closest_hit

    _, tri, _, _ = closest_hit(ctx.grid, o, d, np.zeros(len(o)), np.full(len(o), np.inf))
    qualifies = np.zeros(len(o), bool)
    qualifies[tri >= 0] = ctx.elem_perpixel[ctx.tri_element[tri[tri >= 0]]]
    qualifies = qualifies.reshape(32, 32)
    assert 0 < count == qualifies.sum()
    assert np.array_equal(image[~qualifies], plain[~qualifies])
    assert not np.array_equal(image[qualifies], plain[qualifies])


def test_area_light_per_pixel_is_exact_unoccluded_and_tile_independent():
    # A floor under a small emitter, nothing in between: the visible fraction is exactly 1, so
    # every floor pixel of a qualifying element is ρ L F(p) (Lambert's formula at the hit).
    scene = _area_scene()
    v, cam = scene.vertices, scene.camera
    ctx, h = render_context(scene, patch_size=2.0, element_size=0.5, rdiff=0.01, subdivide=0.0)
    image, count = _render(ctx)
    assert count > 0
    o, d = render.primary_rays(cam, slice(0, 40), slice(0, 40), 1)
    p = o + (-o[:, 1] / d[:, 1])[:, None] * d
    from daskrad.kernels.grid import closest_hit

    _, tri, _, _ = closest_hit(ctx.grid, o, d, np.zeros(len(o)), np.full(len(o), np.inf))
    on_floor = (tri >= 0) & (np.abs(p[:, 0]) < 1) & (np.abs(p[:, 2]) < 1)
    on_floor &= ~((np.abs(p[:, 0]) < 0.2) & (np.abs(p[:, 2]) < 0.2))  # the emitter in front
    sel = np.zeros(len(o), bool)
    sel[on_floor] = ctx.elem_perpixel[ctx.tri_element[tri[on_floor]]]
    F = analytic_rows(p[sel], np.tile([0.0, 1.0, 0.0], (sel.sum(), 1)), v,
                      np.array([[4, 5, 6, 7]]))[:, 0]
    # indirect light is 0 (the emitter is black, the floor sees nothing else); the unoccluded
    # term is Lambert's exact formula, the visibility exactly 1: round-off only
    np.testing.assert_allclose(image.reshape(-1, 3)[sel, 0], RHO * 2.0 * F, rtol=1e-9)
    # the same bits whatever the tiling (shadow rays seeded by pixel sample, not by tile)
    whole = render.render_tile(ctx, slice(0, 40), slice(0, 40))
    small, _ = _render(ctx, tile=7)
    assert np.array_equal(whole, image) and np.array_equal(small, image)


def test_sample_ids_are_global_pixel_sample_ids():
    # the seed of a pixel sample's shadow rays: (row · W + col) · spp + sample, whatever tile
    ids = render.sample_ids(Camera(eye=np.zeros(3), look_at=np.ones(3), up=np.ones(3),
                                   fov=40.0, width=10, height=8), slice(2, 4), slice(3, 5), 4)
    assert ids.tolist() == [(r * 10 + c) * 4 + s for r in (2, 3) for c in (3, 4)
                            for s in range(4)]


def _blade_hits(n=400, blocker=None, samples=4):
    """``run(mode, probe=False)``: :func:`direct_at_hits` at ``n`` random hits on a floor
    (y = 0) under a 2 × 2 emitter (y = 2, facing down) with a thin blade (|x| < 0.02) at
    y = 1 between, every hit given ``mode`` for the light and ``samples²`` shadow rays;
    ``blocker``: more triangles in the grid. Returns ``(run, points)``."""
    from daskrad.kernels.grid import build_grid
    from daskrad.kernels.shade import direct_at_hits

    light = np.array([[-1.0, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]])      # faces down
    blade = np.array([[[-0.02, 1, -3], [0.02, 1, -3], [0.02, 1, 3]],
                      [[-0.02, 1, -3], [0.02, 1, 3], [-0.02, 1, 3]]])
    tris = [blade, light[[[0, 1, 2], [0, 2, 3]]]] + ([blocker] if blocker is not None else [])
    grid = build_grid(np.concatenate(tris))
    rng = np.random.default_rng(5)
    p = np.column_stack([rng.uniform(-1.5, 1.5, n), np.zeros(n), rng.uniform(-1.5, 1.5, n)])
    up = np.tile([0.0, 1.0, 0.0], (n, 1))
    lights = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 3)),
              light[None].copy(), np.array([4], np.int64), np.array([[0.0, -1.0, 0.0]]),
              np.array([[1.0, 2.0, 3.0]]), np.array([4.0]))

    def run(mode, probe=False):
        return direct_at_hits(grid, p, up, up, np.arange(n, dtype=np.int64),
                              np.zeros((n, 3)), np.zeros(n), 1e-7, *lights, samples,
                              np.full((n, 1), mode, np.int8), probe)[0]

    run.grid, run.lights = grid, lights
    return run, p


def test_a_light_every_corner_sees_casts_no_shadow_ray_and_keeps_the_bits_where_none_is_blocked():
    # Hits on a floor under a 2 × 2 emitter with a thin blade in between. Taken as visible
    # (LIGHT_VISIBLE), a hit gets Lambert's exact unoccluded term: the bits of tracing its rays
    # wherever none is blocked, and more than the traced value in the blade's shadow (no ray
    # was cast, so the blade is not seen): the mode is what decides.
    from daskrad.kernels.direct import LIGHT_TRACE, LIGHT_VISIBLE

    run, p = _blade_hits()
    traced, taken = run(LIGHT_TRACE), run(LIGHT_VISIBLE)
    F = np.array([lambert_polygon_at(q) for q in p])
    np.testing.assert_allclose(taken[:, 0], math.pi * F, rtol=1e-12)   # unoccluded, exact
    blocked = traced[:, 0] < taken[:, 0]
    assert blocked.any() and (~blocked).any()
    assert np.array_equal(traced[~blocked], taken[~blocked])


@pytest.mark.parametrize("samples", [3, 4, 5])
def test_shadow_probes_keep_the_traced_bits_unless_the_corner_strata_agree(samples):
    # Probing (the per-pixel pass) traces the light's four corner strata of s × s first. A ray
    # from a floor point x_p to a light point x_q crosses the blade when |x_p + x_q| < 0.04.
    # Where a corner stratum's ray is blocked and another's is not, the rest is traced with
    # the bits of no probing; where all four pass, the light is taken as free and a blade's
    # shadow on the strata between them is missed (the documented cost); where nothing is
    # blocked both are the unoccluded term.
    from daskrad.kernels.direct import LIGHT_TRACE, LIGHT_VISIBLE

    run, p = _blade_hits(samples=samples)
    traced, probed, free = run(LIGHT_TRACE), run(LIGHT_TRACE, True), run(LIGHT_VISIBLE)
    same = (probed == traced).all(axis=1)
    missed = ~same
    assert np.array_equal(probed[missed], free[missed])       # a miss: the light taken free
    shadowed = traced[:, 0] < free[:, 0]
    assert missed.any() and shadowed[missed].all()      # missed: only the blade's shadow
    assert (same & shadowed).any()         # disagreeing corners: traced, shadow and all
    # wholly hidden (a wide plate under the light): the corners agree and the answer is 0,
    # as traced
    plate = np.array([[[-3.0, 1.5, -3], [3, 1.5, -3], [3, 1.5, 3]],
                      [[-3.0, 1.5, -3], [3, 1.5, 3], [-3, 1.5, 3]]])
    run, _ = _blade_hits(blocker=plate, samples=samples)
    hidden, probed = run(LIGHT_TRACE), run(LIGHT_TRACE, True)
    assert not hidden.any() and np.array_equal(hidden, probed)



@pytest.mark.parametrize("probe", [False, True])
def test_a_batch_of_hits_has_the_bits_of_each_hit_alone(probe):
    # irradiance_one's working arrays (direct.new_scratch) and the fan's blocker cache are
    # made once per batch and carried from hit to hit: nothing of one hit may reach the next
    # (the probed corners' verdicts among them)
    from daskrad.kernels.direct import LIGHT_TRACE
    from daskrad.kernels.shade import direct_at_hits

    run, p = _blade_hits(n=120)
    batch = run(LIGHT_TRACE, probe)
    up = np.array([[0.0, 1.0, 0.0]])
    alone = np.concatenate([direct_at_hits(
        run.grid, p[i:i + 1].copy(), up, up, np.array([i], np.int64), np.zeros((1, 3)),
        np.zeros(1), 1e-7, *run.lights, 4, np.full((1, 1), LIGHT_TRACE, np.int8), probe)[0]
        for i in range(len(p))])
    assert 0 < (batch[:, 0] < batch[:, 0].max()).sum() < len(p)     # shadowed and lit hits
    assert np.array_equal(batch, alone)


@pytest.mark.parametrize("samples", [1, 2, 4])
def test_the_per_pixel_pass_has_the_vertex_pass_bits_with_lambert_after_the_rays(samples):
    # The per-pixel pass reads no class, so it computes Lambert's F of a light only after one
    # of its rays came through (need_class=False); the vertex pass computes F first. At the
    # same points, normals and seeds the irradiance must be the same bits: hits under the
    # blade and a plate (every ray blocked), in the open, and facing every way (the light
    # across the horizon, or wholly below it).
    from daskrad.kernels.direct import LIGHT_TRACE, irradiance_points

    plate = np.array([[[0.5, 1.5, -3], [3, 1.5, -3], [3, 1.5, 3]],
                      [[0.5, 1.5, -3], [3, 1.5, 3], [0.5, 1.5, 3]]])
    run, p = _blade_hits(n=600, blocker=plate, samples=samples)
    rng = np.random.default_rng(9)
    nrm = rng.normal(size=p.shape) + np.array([0.0, 1.5, 0.0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    grid, lights = run.grid, run.lights
    seeds = np.arange(len(p), dtype=np.int64)
    from daskrad.kernels.shade import direct_at_hits

    pixel = direct_at_hits(grid, p, nrm, nrm, seeds, np.zeros((len(p), 3)), np.zeros(len(p)),
                           1e-7, *lights, samples, np.full((len(p), 1), LIGHT_TRACE, np.int8))[0]
    vertex = irradiance_points(grid, p, p, nrm, seeds, 1e-7, *lights, samples)[0]
    assert np.array_equal(pixel, vertex)
    lit = vertex[:, 0] > 0
    assert lit.sum() > 100 and (~lit).sum() > 10


@pytest.mark.parametrize("probe", [False, True])
def test_the_shadow_cache_keeps_the_bits(probe):
    # each area light's rays first try the triangle that blocked its last ray: under the
    # blade and the plate half the hits are hidden by the plate, and the answer of every hit
    # is that of walking the grid for every ray
    from daskrad.kernels.direct import LIGHT_TRACE
    from daskrad.kernels.shade import direct_at_hits

    plate = np.array([[[0.5, 1.5, -3], [3, 1.5, -3], [3, 1.5, 3]],
                      [[0.5, 1.5, -3], [3, 1.5, 3], [0.5, 1.5, 3]]])
    run, p = _blade_hits(n=600, blocker=plate)
    n = len(p)
    up = np.tile([0.0, 1.0, 0.0], (n, 1))
    H = {cache: direct_at_hits(run.grid, p, up, up, np.arange(n, dtype=np.int64),
                               np.zeros((n, 3)), np.zeros(n), 1e-7, *run.lights, 4,
                               np.full((n, 1), LIGHT_TRACE, np.int8), probe, False, cache)[0]
         for cache in (False, True)}
    assert np.array_equal(H[True], H[False])
    from daskrad.kernels.direct import LIGHT_VISIBLE

    shadowed = H[True][:, 0] < run(LIGHT_VISIBLE)[:, 0]     # some ray blocked
    assert 0.3 < shadowed.mean() < 0.9


def test_shadow_rays_through_the_polygons_give_the_elements_image(monkeypatch):
    # the per-pixel pass's shadow rays walk the grid over the scene's 36 polygon triangles
    # instead of its thousands of element triangles: the same surfaces, the same image
    from daskrad.run import solve_scene
    from daskrad.scene import load_scene
    from daskrad.settings import Settings
    from tests.helpers import CORNELL

    scene = load_scene(CORNELL)
    settings = Settings(max_iterations=64, width=40, height=40)
    _, _, sol, light = solve_scene(scene, settings)
    ctx = render.for_view(render.context(scene, light, sol, settings,
                                         render.camera(scene, settings)))
    assert len(ctx.occluders.triangles) < len(ctx.grid.triangles) / 100
    polygons, count = _render(ctx)
    monkeypatch.setattr(render, "POLYGON_OCCLUDERS", False)
    elements, _ = _render(ctx)
    assert count > 1000 and np.array_equal(polygons, elements)


def test_the_views_rays_found_among_the_polygons_give_the_elements_image(monkeypatch):
    # the primary rays and the junction gather's find their hits among the scene's polygons
    # and locate them among the elements: the Cornell box (no coincident faces) gives the
    # image of walking the elements, to round-off. Its few polygons would be gathered by the
    # disc (render.gather_method), which no walk matches: by rays here
    from daskrad.run import solve_scene
    from daskrad.scene import load_scene
    from daskrad.settings import Settings
    from tests.helpers import CORNELL

    monkeypatch.setattr(render, "DISC_POLYGONS", -1)
    scene = load_scene(CORNELL)
    settings = Settings(max_iterations=64, width=40, height=40)
    _, _, sol, light = solve_scene(scene, settings)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    assert ctx.locator is None and ctx.junctions is not None
    view = render.for_view(ctx)
    assert view.locator is not None and len(view.locator) == len(ctx.grid.triangles)
    located = render.pixels(ctx)
    monkeypatch.setattr(render, "POLYGON_HITS", False)
    assert render.for_view(ctx).locator is None
    walked = render.pixels(ctx)
    assert walked.max() > 0.1
    np.testing.assert_allclose(located, walked, rtol=0, atol=1e-12 * walked.max())


@pytest.mark.parametrize("two_sided", [False, True])
def test_the_polygons_grid_covers_every_element_the_backs_of_two_sided_faces_too(two_sided):
    # a floor and a plate over it (two-sided or not): a ray from a hair above each element
    # triangle's centroid, back along its normal, meets a triangle of the occluder grid within
    # twice that hair, so the shadow rays meet every surface the elements have (a two-sided
    # plate's back elements lie TWO_SIDED_GAP of the diagonal behind its front)
    from daskrad.kernels.grid import closest_hit
    from daskrad.preprocess import preprocess
    from daskrad.settings import Settings

    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [-1, 1, -1], [-1, 1.2, 1], [1, 1.2, 1], [1, 1, -1]], float)
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                              diffuse=[[0.5] * 3] * 2, emission=[[0.0] * 3] * 2,
                              point_lights=(LIGHT[None], [[INTENSITY] * 3]),
                              two_sided=[False, two_sided])       # per material
    mesh = preprocess(scene, Settings(patch_size=1.0, element_size=0.5))
    occluders, faces = mesh.occluders
    t = mesh.triangles
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    hair = 1e-7 * scene.diagonal
    hit_t, tri, _, _ = closest_hit(occluders, t.mean(axis=1) + hair * n, -n, 0.0, 2 * hair)
    assert (tri >= 0).all()
    assert len(mesh.triangles) > 100 and len(occluders.triangles) == (6 if two_sided else 4)
    # each occluder triangle lies in the convex face it names (the face test takes a light
    # hidden behind the whole face), wound as the face
    from daskrad.kernels.geometry import within_edges

    for k, tri_k in enumerate(occluders.triangles):
        f = faces.tri_face[k]
        assert faces.start[f + 1] == faces.start[f] + 1
        nk = np.cross(tri_k[1] - tri_k[0], tri_k[2] - tri_k[0])
        nk /= np.linalg.norm(nk)
        for x in list(tri_k) + [tri_k.mean(axis=0)]:
            assert within_edges(faces.corners[f], faces.count[f], *x, *nk, -occluders.eps)
        # and not in a face it does not lie in: beyond the face's first corner
        c = faces.corners[f, :faces.count[f]]
        out = c[0] + 0.1 * (c[0] - c.mean(axis=0))
        assert not within_edges(faces.corners[f], faces.count[f], *out, *nk, -occluders.eps)


def lambert_polygon_at(q):
    from daskrad.kernels.lambert import lambert_polygon

    light = np.array([[-1.0, 2, -1], [1, 2, -1], [1, 2, 1], [-1, 2, 1]])
    return lambert_polygon(q[0], q[1], q[2], 0.0, 1.0, 0.0, light, 4)


def test_light_modes_need_every_corner_and_agreeing_t_vertices():
    from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, LIGHT_VISIBLE
    from daskrad.mesh.refine import TVertices

    V, H, T = LIGHT_VISIBLE, LIGHT_HIDDEN, LIGHT_TRACE
    # 6 vertices, 2 lights; a quad (0 1 2 3), a triangle (1 4 2) and a quad (4 5 2 1)
    ev = np.array([[0, 1, 2, 3], [1, 4, 2, -1], [4, 5, 2, 1]], np.int32)
    classes = np.array([[V, V], [V, H], [V, V], [V, V], [V, H], [T, H]], np.int8)
    modes = render.light_modes(ev, classes)
    assert modes.dtype == np.int8
    # light 0: every corner of the first two sees it; vertex 5 does not, so the third traces.
    # light 1: hidden everywhere but never taken as hidden (stacked faces: corners under one
    # another, interior lit), and one visible corner is not every corner
    assert modes.tolist() == [[V, T], [V, T], [T, T]]
    # a T-vertex (5) on the quad's edge 0-3 that disagrees on light 0 sends its ends back
    tv = TVertices(np.array([5]), np.array([0]), np.array([3]))
    assert render.light_modes(ev, classes, tv).tolist() == [[T, T], [V, T], [T, T]]


def test_light_modes_keep_the_bits_of_tracing_around_a_blocker_and_are_dropped_beyond_a_cap(
        monkeypatch):
    # A floor under a small emitter with a wide blocker between, refined where its shadow
    # falls (T-vertices and all): the blocker is large and square, so an element every corner
    # of which sees the light whole is unoccluded everywhere, and taking the light as visible
    # there gives the bits of tracing it. A mode on the wrong element (or light) would put the
    # light into the shadow and change pixels. With the classes' cap at 0 the vertex pass
    # keeps none, the context has no modes, and the image is again the same.
    from dataclasses import replace

    from daskrad import direct
    from daskrad.kernels.direct import LIGHT_TRACE, LIGHT_VISIBLE

    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [-0.2, 2, -0.2], [0.2, 2, -0.2], [0.2, 2, 0.2], [-0.2, 2, 0.2],
                  [-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], float)
    cam = Camera(eye=np.array([0.1, 6.0, 0.2]), look_at=np.zeros(3),
                 up=np.array([0.0, 0.0, 1.0]), fov=42.0, width=48, height=48)
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]]),
                              [0, 1, 2], diffuse=[[RHO] * 3, [0.0] * 3, [0.0] * 3],
                              emission=[[0] * 3, [20.0] * 3, [0] * 3], camera=cam)
    kw = dict(patch_size=1.0, element_size=0.5, rdiff=0.01)
    ctx, h = render_context(scene, **kw)
    assert h.generation > 0                              # refined along the shadow
    modes = ctx.elem_light_mode
    pp = ctx.elem_perpixel
    assert modes is not None and modes.shape == (len(h.elem_verts), len(ctx.lights.emitter_corners))
    assert (modes[pp] == LIGHT_VISIBLE).any() and (modes[pp] == LIGHT_TRACE).any()
    image, count = _render(ctx)
    assert count > 0
    traced, _ = _render(replace(ctx, elem_light_mode=None))
    assert np.array_equal(image, traced)
    # and the modes matter: every light taken as visible everywhere lights the shadow
    wrong, _ = _render(replace(ctx, elem_light_mode=np.full_like(modes, LIGHT_VISIBLE)))
    assert (wrong > image).any()
    monkeypatch.setattr(direct, "CLASSES_MAX", 0)
    capped, _ = render_context(scene, **kw)
    assert capped.elem_light_mode is None
    assert np.array_equal(_render(capped)[0], image)


@pytest.mark.parametrize("samples, probe", [(1, False), (2, False), (4, False), (4, True)])
def test_the_per_pixel_pass_reports_the_classes_of_lambert_first(samples, probe):
    # With Lambert's F after the rays, a light every ray finds blocked is still reported
    # hidden (its F is not computed): the classes are those of computing F first, and with
    # no probes those of the vertex pass, at every hit of the blade-and-plate scene in every
    # orientation; a light the modes take as visible is reported visible, one they skip as
    # TRACE
    from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, LIGHT_VISIBLE, irradiance_points
    from daskrad.kernels.shade import direct_at_hits

    plate = np.array([[[0.5, 0.5, -3], [3, 0.5, -3], [3, 0.5, 3]],
                      [[0.5, 0.5, -3], [3, 0.5, 3], [0.5, 0.5, 3]]])     # hides x > 1 whole
    run, p = _blade_hits(n=600, blocker=plate, samples=samples)
    rng = np.random.default_rng(11)
    nrm = rng.normal(size=p.shape) + np.array([0.0, 1.5, 0.0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    seeds = np.arange(len(p), dtype=np.int64)
    modes = np.full((len(p), 1), LIGHT_TRACE, np.int8)
    modes[:60] = LIGHT_VISIBLE
    modes[60:120] = LIGHT_HIDDEN
    classes = {}
    for first in (False, True):
        classes[first] = np.full((len(p), 1), -1, np.int8)
        direct_at_hits(run.grid, p, nrm, nrm, seeds, np.zeros((len(p), 3)), np.zeros(len(p)),
                       1e-7, *run.lights, samples, modes, probe, first, True, classes[first])
    assert np.array_equal(classes[False], classes[True])
    got = classes[False]
    assert (got[60:120] == LIGHT_TRACE).all()
    visible = got[:60] == LIGHT_VISIBLE
    assert visible.sum() > 20 and (got[:60][~visible] == LIGHT_TRACE).all()   # F = 0 there
    if not probe:
        vertex = irradiance_points(run.grid, p, p, nrm, seeds, 1e-7, *run.lights, samples)[1]
        assert np.array_equal(got[120:], vertex[120:])
    for c in (LIGHT_TRACE, LIGHT_VISIBLE, LIGHT_HIDDEN):
        assert (got[120:] == c).sum() > 20


def _pixel_modes_rule(modes, elem, pixel, base_elem, base_class, own):
    """The rule of :func:`daskrad.kernels.shade.pixel_modes`, written plainly."""
    from daskrad.kernels.direct import LIGHT_TRACE

    out = modes.copy()
    for i in range(len(modes)):
        k, e = pixel[i], elem[i]
        if not (base_elem[k, :own] == e).all():
            continue
        on = base_elem[k] == e
        for m in range(modes.shape[1]):
            found = set(base_class[k, on, m].tolist())
            if modes[i, m] == LIGHT_TRACE and len(found) == 1 and LIGHT_TRACE not in found:
                out[i, m] = found.pop()
    return out


def test_an_edge_sample_takes_a_light_only_where_every_base_sample_on_its_element_agrees(rng):
    from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, LIGHT_VISIBLE
    from daskrad.kernels.shade import pixel_modes

    # pixels mostly on one element, each light mostly in one class around a pixel
    P, own, n, M = 40, 4, 600, 3
    base_elem = np.where(rng.random((P, 9 * own)) < 0.97, 7,
                         rng.choice([-1, 8], size=(P, 9 * own))).astype(np.int64)
    base_class = np.repeat(rng.choice([LIGHT_TRACE, LIGHT_VISIBLE, LIGHT_HIDDEN], size=(P, 1, M),
                                      p=[0.2, 0.4, 0.4]), 9 * own, axis=1).astype(np.int8)
    flip = rng.random(base_class.shape) < 0.01
    base_class[flip] = rng.choice([LIGHT_TRACE, LIGHT_VISIBLE, LIGHT_HIDDEN], size=flip.sum())
    modes = rng.choice([LIGHT_TRACE, LIGHT_VISIBLE, LIGHT_HIDDEN], size=(n, M),
                       p=[0.8, 0.1, 0.1]).astype(np.int8)
    elem = rng.choice([7, 8], size=n, p=[0.9, 0.1]).astype(np.int64)
    pixel = rng.integers(0, P, size=n).astype(np.int64)
    out = pixel_modes(modes, elem, pixel, base_elem, base_class, own)
    assert np.array_equal(out, _pixel_modes_rule(modes, elem, pixel, base_elem, base_class, own))
    changed = out != modes
    assert changed.any() and (modes[changed] == LIGHT_TRACE).all()
    assert (out[changed] == LIGHT_VISIBLE).any() and (out[changed] == LIGHT_HIDDEN).any()
    # one sample of the pixel itself on another element, or one neighbour's sample on the
    # same element that disagrees, and nothing is taken
    k, m = pixel[0], 0
    base_elem[k] = elem[0]
    base_class[k, :, m] = LIGHT_HIDDEN
    one = (modes[:1].copy(), elem[:1], pixel[:1])
    one[0][0, m] = LIGHT_TRACE
    assert pixel_modes(*one, base_elem, base_class, own)[0, m] == LIGHT_HIDDEN
    for s, change in ((own - 1, "elem"), (own + 5, "class")):
        e2, c2 = base_elem.copy(), base_class.copy()
        if change == "elem":
            e2[k, s] = elem[0] + 1
        else:
            c2[k, s, m] = LIGHT_VISIBLE
        assert pixel_modes(*one, e2, c2, own)[0, m] == LIGHT_TRACE
    # a neighbour's sample on another element does not count
    e2 = base_elem.copy()
    e2[k, own + 5] = elem[0] + 1
    base_class[k, own + 5, m] = LIGHT_VISIBLE
    assert pixel_modes(*one, e2, base_class, own)[0, m] == LIGHT_HIDDEN


def _shadow_scene(size=36):
    """A floor (ρ 0.5) under a 0.3 × 0.3 emitter facing down, a black bar between: a
    penumbra and an umbra in view, and the emitter's and the bar's outlines."""
    v = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1],
                  [-0.15, 0.9, -0.15], [0.15, 0.9, -0.15], [0.15, 0.9, 0.15], [-0.15, 0.9, 0.15],
                  [-0.6, 0.45, -0.08], [-0.6, 0.45, 0.08], [0.6, 0.45, 0.08],
                  [0.6, 0.45, -0.08]])
    cam = Camera(eye=np.array([0.0, 3.0, 0.05]), look_at=np.zeros(3),
                 up=np.array([0.0, 0.0, 1.0]), fov=40.0, width=size, height=size)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]]),
                             [0, 1, 2], diffuse=[[RHO] * 3, [0.0] * 3, [0.0] * 3],
                             emission=[[0] * 3, [8.0] * 3, [0] * 3], camera=cam)


def test_edge_verdicts_change_only_edge_pixels_a_little_and_not_with_the_tiles(monkeypatch):
    # Without the verdicts an edge pixel has the bits of a whole image at edge_spp. With
    # them the light is taken as the base samples around the pixel found it at most of the
    # edge samples; a verdict that holds gives the traced bits (V exactly 1 or 0), so only
    # edge pixels may change, by less than the shadow rays' own noise between the two sample
    # counts; and the image does not depend on the tiling (the apron's base samples are the
    # bits their own tile computes).
    scene = _shadow_scene()
    ctx, _ = render_context(scene, patch_size=2.0, element_size=0.1, rdiff=0.01,
                            subdivide=0.0, spp=4, edge_spp=16)
    monkeypatch.setattr(render, "EDGE_VERDICTS", False)
    traced, stats = render.pixels_stats(ctx)
    full = render.render(replace(ctx, spp=16, edge_spp=0))
    base = render.render(replace(ctx, edge_spp=0))
    edge = (traced != base).any(axis=2)
    assert 0 < edge.sum() <= stats["edges"] < traced.shape[0] * traced.shape[1] // 2
    np.testing.assert_array_equal(traced[edge], full[edge])
    assert stats["verdicts"] == 0
    monkeypatch.setattr(render, "EDGE_VERDICTS", True)
    image, stats = render.pixels_stats(ctx)
    assert stats["verdicts"] > 100          # the penumbra itself is traced: its pixels disagree
    changed = (image != traced).any(axis=2)
    assert not (changed & ~edge).any()
    assert np.array_equal(image[~edge], base[~edge])
    noise = np.sqrt(((full - base)[edge] ** 2).mean())
    assert np.sqrt(((image - traced)[edge] ** 2).mean()) < 0.5 * noise
    small, _ = _render(ctx, tile=7)
    assert np.array_equal(small, image)
