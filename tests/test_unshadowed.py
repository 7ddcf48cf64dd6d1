"""Elements no shadow ray can be blocked from (issue 12, item 3): the per-pixel pass skips
their rays with the same bits, and an element with an occluder between it and a light is never
marked."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.kernels.grid import build_grid
from daskrad.kernels.unshadowed import unshadowed_elements
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene, scene_from_arrays
from daskrad.settings import Settings
from tests.helpers import SCENES

SMALL = Settings(patch_size=100.0, element_size=40.0, resolution=64, tolerance=1e-2,
                 width=48, height=48, spp=2, workers=0)


@pytest.mark.parametrize("scene_name", ["cornell_box.obj", "lit_room.obj"])
def test_skipping_the_rays_of_unshadowed_elements_gives_the_same_bits(scene_name):
    scene = load_scene(SCENES / scene_name)
    settings = SMALL if scene_name == "cornell_box.obj" else SMALL.replace(
        patch_size=1.0, element_size=0.25)
    ex = InProcess(threads=1)
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    sol = solve.radiosity(light, settings, ex)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    assert ctx.elem_unshadowed is not None and ctx.elem_unshadowed.any()
    assert not ctx.elem_unshadowed[~ctx.elem_perpixel].any()     # only where rays are traced
    traced = dataclasses.replace(ctx, elem_unshadowed=None, open_grid=None)
    stats = {"perpixel": 0, "specular": 0, "mirror": 0}
    for rows, cols in render.tiles(ctx.camera.width, ctx.camera.height, 16):
        a, sa = render.render_tile_stats(ctx, rows, cols)
        b, _ = render.render_tile_stats(traced, rows, cols)
        np.testing.assert_array_equal(a, b)
        stats = {k: stats[k] + sa[k] for k in stats}
    assert stats["perpixel"] > 0


def _floor_and_block(light_kind: str):
    """A 4 × 4 floor of 16 quads under a 0.6 × 0.6 card hanging at y = 1 over its middle, lit
    from above by a point light, a directional light or an emitting quad at y = 2."""
    verts, quads = [], []
    for i in range(5):
        for j in range(5):
            verts.append([i - 2.0, 0.0, j - 2.0])
    for i in range(4):
        for j in range(4):
            a = i * 5 + j
            quads.append([a, a + 1, a + 6, a + 5])            # normal +y (up)
    base = len(verts)
    verts += [[-0.3, 1.0, -0.3], [0.3, 1.0, -0.3], [0.3, 1.0, 0.3], [-0.3, 1.0, 0.3]]
    quads.append([base, base + 1, base + 2, base + 3])        # the card, facing down
    mats = [0] * 17
    emission = [[0.0] * 3]
    if light_kind == "area":
        base = len(verts)
        verts += [[-0.2, 2.0, -0.2], [0.2, 2.0, -0.2], [0.2, 2.0, 0.2], [-0.2, 2.0, 0.2]]
        quads.append([base, base + 1, base + 2, base + 3])    # facing down
        mats.append(1)
        emission.append([5.0] * 3)
    kw = {}
    if light_kind == "point":
        kw["point_lights"] = (np.array([[0.0, 2.0, 0.0]]), np.array([[1.0, 1.0, 1.0]]))
    if light_kind == "directional":
        kw["directional_lights"] = (np.array([[0.0, -1.0, 0.0]]), np.array([[1.0, 1.0, 1.0]]))
    diffuse = [[0.5] * 3] * len(emission)
    return scene_from_arrays(np.array(verts), np.array(quads), mats, diffuse, emission, **kw)


@pytest.mark.parametrize("kind", ["point", "directional", "area"])
def test_elements_under_the_card_are_not_marked_and_open_ones_are(kind):
    scene = _floor_and_block(kind)
    verts = scene.vertices
    ev = np.asarray(scene.polygons[:16], np.int32)
    tris = np.concatenate([verts[scene.polygons[:, [0, 1, 2]]],
                           verts[scene.polygons[:, [0, 2, 3]]]])
    grid = build_grid(tris)
    normal = np.tile([0.0, 1.0, 0.0], (16, 1))
    ctx = direct.make_context(scene, _hierarchy_of(scene), grid)
    free = unshadowed_elements(grid, verts, ev, normal, np.ones(16, bool), 1e-6,
                               ctx.point_position, np.ascontiguousarray(ctx.dir_direction),
                               ctx.emitter_corners, ctx.emitter_count, ctx.emitter_normal)
    centre = verts[ev].mean(axis=1)
    under = (np.abs(centre[:, 0]) < 1.0) & (np.abs(centre[:, 2]) < 1.0)   # the middle four
    assert not free[under].any()
    if kind == "directional":          # straight down: the card shades the middle four only
        assert free[~under].all()
    else:                              # from a small light 2 above: the far corners are open
        corner = (np.abs(centre[:, 0]) > 1.0) & (np.abs(centre[:, 2]) > 1.0)
        assert free[corner].all()


def _hierarchy_of(scene):
    from daskrad.mesh import build_hierarchy

    return build_hierarchy(scene, 10.0, 10.0)
