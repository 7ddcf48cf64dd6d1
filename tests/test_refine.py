"""Adaptive subdivision around shadow boundaries (issue 5, item 2)."""

from __future__ import annotations

import numpy as np

from daskrad import direct, tolerances
from daskrad.kernels.grid import build_grid
from daskrad.mesh import build_hierarchy, hierarchy_triangles
from daskrad.mesh.refine import refine, resolve_tvertices
from tests.helpers import blocker_scene, in_shadow

ELEMENT = 0.5
MIN_SIZE = ELEMENT / 8


def _expected_floor_elements(x0, z0, size):
    """Independent count: a square floor element splits when its corners' shadow states
    differ (relative spread 1 > threshold) and its edge exceeds the minimum size."""
    corners = np.array([[x0, 0, z0], [x0 + size, 0, z0], [x0 + size, 0, z0 + size],
                        [x0, 0, z0 + size]])
    dark = in_shadow(corners)
    if dark.all() or not dark.any() or size <= MIN_SIZE * (1 + tolerances.SPLIT_SIZE_RTOL):
        return 1
    half = size / 2
    return sum(_expected_floor_elements(x0 + i * half, z0 + j * half, half)
               for i in (0, 1) for j in (0, 1))


def _refine_direct(scene, rho):
    """Refine ``scene``'s hierarchy under its direct light alone, reflected with ``rho`` (a
    number; ``1.0`` leaves ``H`` bit-identical). Returns the refinement, ``H`` at the refined
    vertices, the evaluate calls ``(start, stop, vertices, generation)`` and the context."""
    h = build_hierarchy(scene, 4.0, ELEMENT)
    tris, _, _ = hierarchy_triangles(h)
    ctx = direct.make_context(scene, h, build_grid(tris))
    H = direct.compute(ctx, 0, len(h.vertices))
    calls = []

    def evaluate(h2, start, stop):
        calls.append((start, stop, len(h2.vertices), h2.generation))
        return rho * direct.compute(direct.with_hierarchy(ctx, h2), start, stop)  # ρ H

    h2, H2, tv, levels = refine(h, rho * H, evaluate, threshold=0.5, min_size=MIN_SIZE)
    return h, h2, H2 / rho, tv, levels, calls, ctx


def _refined():
    return _refine_direct(blocker_scene(), 0.5)


def test_subdivision_refines_around_the_shadow_and_nowhere_else():
    h, h2, H2, tv, levels, calls, _ = _refined()
    floor = h2.elem_normal[:, 1] > 0.5
    expected = sum(_expected_floor_elements(-2 + i * ELEMENT, -2 + j * ELEMENT, ELEMENT)
                   for i in range(8) for j in range(8))
    assert int(floor.sum()) == expected
    assert expected > 64                      # the shadow's outline did cause splits
    # the blocker (lit from behind: no light at all) is untouched
    assert int((~floor).sum()) == int((h.elem_normal[:, 1] < -0.5).sum())
    assert levels == 3 and h2.generation == h.generation + 3
    # direct light was computed only at the new vertices of each level, once
    starts = [c[0] for c in calls]
    stops = [c[1] for c in calls]
    assert starts[0] == len(h.vertices) and starts[1:] == stops[:-1]
    assert stops[-1] == len(h2.vertices) == len(H2)


def test_refined_mesh_keeps_areas_and_the_shadow_area_converges():
    h, h2, H2, tv, _, _, _ = _refined()
    np.testing.assert_allclose(np.bincount(h2.elem_patch, weights=h2.elem_area),
                               h.patch_area, rtol=1e-12)
    # elements stay contiguous per patch
    assert np.all(np.diff(h2.elem_patch) >= 0)
    # shadow area from the element means: only elements cut by the outline (perimeter 4,
    # edge MIN_SIZE) are uncertain, so the error is below 4 · MIN_SIZE · ½ = 0.125
    lit = 2.0 / np.sqrt(1.09)
    He = direct.element_mean(h2, H2)
    on_floor = h2.elem_normal[:, 1] > 0.5
    dark = 16.0 - (h2.elem_area * He[:, 0])[on_floor].sum() / lit
    assert abs(dark - 1.0) < 4 * MIN_SIZE * 0.5


def test_tvertices_lie_on_their_edge_and_are_resolved_from_it():
    _, h2, H2, tv, _, _, _ = _refined()
    assert len(tv.vertex) > 0
    v = h2.vertices
    np.testing.assert_allclose(v[tv.vertex], 0.5 * (v[tv.a] + v[tv.b]), atol=1e-15)
    # each T-vertex's edge is an edge of some element (the coarse side)
    ev = h2.elem_verts
    edges = {tuple(sorted((int(e[i]), int(e[(i + 1) % 4])))) for e in ev for i in range(4)}
    assert all((min(a, b), max(a, b)) in edges for a, b in zip(tv.a, tv.b, strict=True))
    shown = resolve_tvertices(H2, tv)
    np.testing.assert_array_equal(shown[tv.vertex], 0.5 * (shown[tv.a] + shown[tv.b]))
    others = np.setdiff1d(np.arange(len(v)), tv.vertex)
    np.testing.assert_array_equal(shown[others], H2[others])


def test_no_refinement_under_uniform_light():
    # A directional light straight down with nothing in the way: H is the same everywhere.
    _, h2, _, tv, levels, calls, _ = _refined_uniform()
    assert levels == 0 and not calls and len(tv.vertex) == 0


def _refined_uniform():
    from daskrad.scene import scene_from_arrays

    v = np.array([[-2.0, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]])
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3]]), [0], diffuse=[[0.5] * 3],
                              emission=[[0, 0, 0]],
                              directional_lights=(np.array([[0.0, -1, 0]]), [[1.0] * 3]))
    return _refine_direct(scene, 1.0)


def test_triangles_split_in_four_sharing_midpoints():
    # Two triangles sharing an edge, one shadowed corner: every split triangle's children
    # share the midpoints with their neighbours, and areas add up.
    from daskrad.mesh.refine import split_elements
    from daskrad.scene import scene_from_arrays

    v = np.array([[0.0, 0, 0], [0, 0, 1], [1, 0, 0], [1, 0, 1]])
    scene = scene_from_arrays(v, np.array([[0, 1, 2, -1], [2, 1, 3, -1]]), [0, 0],
                              diffuse=[[0.5] * 3], emission=[[0, 0, 0]],
                              directional_lights=(np.array([[0.0, -1, 0]]), [[1.0] * 3]))
    h = build_hierarchy(scene, 2.0, 2.0)
    h2, keys, verts = split_elements(h, np.ones(h.n_elements, bool), np.zeros(0, np.int64),
                                     np.zeros(0, np.int64))
    assert h2.n_elements == 4 * h.n_elements
    assert np.all(h2.elem_verts[:, 3] == -1)
    np.testing.assert_allclose(np.bincount(h2.elem_patch, weights=h2.elem_area),
                               h.patch_area, rtol=1e-12)
    assert np.all(h2.elem_area > 0)  # winding kept: positive projected areas


def _spreads_numpy(ev, values, vertices):
    """The element spreads as numpy array expressions (the code the kernel replaced)."""
    c3 = np.where(ev[:, 3] >= 0, ev[:, 3], ev[:, 0])
    corners = np.stack([values[ev[:, 0]], values[ev[:, 1]], values[ev[:, 2]], values[c3]],
                       axis=1)
    p = vertices[np.stack([ev[:, 0], ev[:, 1], ev[:, 2], c3], axis=1)]
    return (corners.max(axis=1).max(axis=1),
            (corners.max(axis=1) - corners.min(axis=1)).max(axis=1),
            np.linalg.norm(np.roll(p, -1, axis=1) - p, axis=2).max(axis=1))


def test_the_spreads_kernel_gives_numpys_bits(rng):
    # quads and triangles over random vertices, values over many magnitudes: every element's
    # largest value, per-channel spread and longest edge are exactly numpy's
    from daskrad.kernels.refine import element_spreads

    V, E = 500, 3000
    vertices = rng.normal(size=(V, 3)) * 10.0 ** rng.uniform(-3, 3, size=(V, 1))
    values = rng.random((V, 3)) * 10.0 ** rng.uniform(-6, 6, size=(V, 1))
    ev = rng.integers(0, V, size=(E, 4))
    ev[rng.random(E) < 0.4, 3] = -1
    for got, want in zip(element_spreads(ev, values, vertices),
                         _spreads_numpy(ev, values, vertices), strict=True):
        np.testing.assert_array_equal(got, want)
