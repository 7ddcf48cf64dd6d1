"""Area lights proved hidden from a per-pixel element (daskrad/kernels/hidden.py): the proof
is geometric (one convex face crosses every shadow ray), and skipping the proved lights' rays
gives the bits of tracing them."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from daskrad import render
from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE
from daskrad.kernels.hidden import patch_blocks, polygon_outlines
from daskrad.kernels.shade import direct_at_hits
from daskrad.scene import Camera, scene_from_arrays
from tests.helpers import render_context

OFF = 1e-3
SQUARE = np.array([[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], float)
LIGHT = np.array([[-0.2, 2, -0.2], [0.2, 2, -0.2], [0.2, 2, 0.2], [-0.2, 2, 0.2]], float)


def element(x, z, size=0.1):
    """A floor square (lifted by OFF, as the shadow rays' origins are) at ``(x, z)``."""
    s = size / 2
    return np.array([[x - s, OFF, z - s], [x + s, OFF, z - s], [x + s, OFF, z + s],
                     [x - s, OFF, z + s]])


@pytest.mark.parametrize("winding", [1, -1])
def test_a_square_blocks_exactly_the_shafts_it_crosses_whole(winding):
    sq = SQUARE[::winding].copy()
    # a segment from floor point x to the light (|x_l| <= 0.2, y = 2) crosses y = 1 at about
    # (x + x_l) / 2: inside the square (|.| < 0.5) for every point of an element whose
    # corners keep |x| < 0.8 on both axes (elements 0.1 wide: centres within 0.75)
    assert patch_blocks(element(0.0, 0.0), 4, LIGHT, 4, sq, 4, OFF, 1e-9)
    assert patch_blocks(element(0.69, -0.69), 4, LIGHT, 4, sq, 4, OFF, 1e-9)
    # one corner's shaft passes beside the square: not proved (though most rays are blocked)
    assert patch_blocks(element(0.74, 0.0), 4, LIGHT, 4, sq, 4, OFF, 1e-9)
    assert not patch_blocks(element(0.77, 0.0), 4, LIGHT, 4, sq, 4, OFF, 1e-9)
    # a light below the square's plane, or a square too close to the element's plane
    assert not patch_blocks(element(0.0, 0.0), 4, LIGHT - [0, 1.5, 0], 4, sq, 4, OFF, 1e-9)
    low = sq - [0, 1 - 2.5 * OFF, 0]
    assert not patch_blocks(element(0.0, 0.0), 4, LIGHT, 4, low, 4, OFF, 1e-9)
    assert patch_blocks(element(0.0, 0.0), 4, LIGHT, 4, sq - [0, 1 - 4 * OFF, 0], 4, OFF, 1e-9)
    # delta: the crossings must lie inside by it (the square's edge at 0.5; the farthest
    # corner's crossing at about (0.69 + 0.05 + 0.2) / 2 = 0.47)
    assert not patch_blocks(element(0.69, 0.0), 4, LIGHT, 4, sq, 4, OFF, 0.05)


def test_outlines_are_the_convex_polygons_only():
    # polygon 0: a unit square in y = 0 tiled by 4 patches (normal +y); polygon 1: an L of 3
    # unit squares (not convex); polygon 2: one triangle
    v = []

    def quad(x, z):
        base = len(v)
        v.extend([[x, 0, z], [x, 0, z + 0.5], [x + 0.5, 0, z + 0.5], [x + 0.5, 0, z]])
        return [base, base + 1, base + 2, base + 3]

    patches = [quad(0, 0), quad(0.5, 0), quad(0, 0.5), quad(0.5, 0.5),
               quad(3, 0), quad(3.5, 0), quad(3, 0.5)]
    base = len(v)
    v.extend([[5, 0, 0], [5, 0, 1], [6, 0, 0]])
    patches.append([base, base + 1, base + 2, -1])
    vertices = np.array(v, float)
    pv = np.array(patches, np.int32)
    area = np.array([0.25] * 7 + [0.5])
    normal = np.tile([0.0, 1.0, 0.0], (8, 1))
    polygon = np.array([0, 0, 0, 0, 1, 1, 1, 2])
    order = np.argsort(polygon, kind="stable")
    start = np.searchsorted(polygon[order], np.arange(4))
    outline_start, outline = polygon_outlines(vertices, pv, area, normal, order, start)
    assert outline_start.tolist() == [0, 4, 4, 7]
    square = outline[0:4]
    assert sorted(map(tuple, square)) == [(0, 0, 0), (0, 0, 1), (1, 0, 0), (1, 0, 1)]
    # counter-clockwise about +y: Newell's normal of the outline points along +y
    n = sum(np.cross(square[i], square[(i + 1) % 4]) for i in range(4))
    assert n[1] > 0 and abs(n[0]) + abs(n[2]) < 1e-12
    assert sorted(map(tuple, outline[4:7])) == [(5, 0, 0), (5, 0, 1), (6, 0, 0)]


def _two_lights_scene():
    """A floor lit by light A from above, a square blocker between (A's umbra under it), and
    by light B from the side, low, whose shadow edge (the end of a low wall) crosses A's
    umbra: elements there are per-pixel (B varies over them) with A hidden from every corner.
    The camera looks in under the blocker."""
    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],             # floor
                  *LIGHT,                                                      # light A
                  *SQUARE,                                                     # blocker A
                  [-1.8, 0.4, -0.2], [-1.8, 0.8, -0.2], [-1.8, 0.8, 0.2],      # light B (+x)
                  [-1.8, 0.4, 0.2],
                  [-1.2, 0, 0], [-1.2, 0.5, 0], [-1.2, 0.5, 2], [-1.2, 0, 2]], float)
    faces = np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11], [12, 13, 14, 15],
                      [16, 17, 18, 19]])
    cam = Camera(eye=np.array([2.6, 0.7, -2.4]), look_at=np.array([0.0, 0.0, 0.0]),
                 up=np.array([0.0, 1.0, 0.0]), fov=50.0, width=48, height=48)
    return scene_from_arrays(v, faces, [0, 1, 2, 3, 2],
                             diffuse=[[0.5] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3],
                             emission=[[0] * 3, [20.0] * 3, [0] * 3, [20.0] * 3],
                             camera=cam)


def test_proved_lights_keep_the_bits_of_tracing_them(rng):
    ctx, h = render_context(_two_lights_scene(), patch_size=1.0, element_size=0.25, rdiff=0.01)
    modes = ctx.elem_light_mode
    assert modes is not None
    e, m = np.nonzero(modes == LIGHT_HIDDEN)
    assert len(e) > 0 and ctx.elem_perpixel[e].all()
    # the proof asked of every pair of a per-pixel element and a light, not only of those
    # hidden from every corner: it must hold for each pair it proves, and not prove the
    # partly lit ones
    everything = np.repeat(ctx.elem_perpixel[:, None], modes.shape[1], axis=1)
    proved = render.hidden_lights(ctx, h, everything)
    assert (proved[e, m]).all() and (everything & ~proved).any()
    trace = np.full_like(modes, LIGHT_TRACE)
    skip = np.where(proved, LIGHT_HIDDEN, LIGHT_TRACE).astype(np.int8)
    # at random points of the elements, tracing every light gives the same bits
    tri = np.flatnonzero(ctx.elem_perpixel[ctx.tri_element])
    pick = rng.choice(tri, 2000)
    w = rng.dirichlet(np.ones(3), len(pick))
    p = np.einsum("nk,nkx->nx", w, ctx.grid.triangles[pick])
    elem = ctx.tri_element[pick]
    lights = ctx.lights

    def at(mode):
        return direct_at_hits(ctx.grid, p, np.ascontiguousarray(ctx.elem_normal[elem]),
                              np.tile([0.0, 1.0, 0.0], (len(p), 1)),
                              np.arange(len(p), dtype=np.int64), np.zeros((len(p), 3)),
                              np.zeros(len(p)), float(lights.offset), *lights.light_args,
                              int(lights.samples), np.ascontiguousarray(mode[elem]))

    H_trace, _ = at(trace)
    assert np.array_equal(at(skip)[0], H_trace)
    assert (H_trace > 0).any() and proved[elem].any()
    # and the image: the same bits with the proved lights traced, and the modes are read
    # there (every light of every per-pixel element taken as hidden darkens it)
    image = render.pixels(ctx)
    traced = render.pixels(replace(ctx, elem_light_mode=np.where(
        modes == LIGHT_HIDDEN, LIGHT_TRACE, modes).astype(np.int8)))
    assert np.array_equal(image, traced)
    dark = render.pixels(replace(ctx, elem_light_mode=np.full_like(modes, LIGHT_HIDDEN)))
    assert (dark < image).any()
