"""Hierarchical z in the hemisphere base (option ``hiz``): the elements drawn front to back, the
raster of those wholly hidden behind what is drawn left out.

Its contract: every element wins exactly the pixels it wins without it (so the paper's counts
and the default's visible fractions do not change), an element left out is one that wins none,
and the solve turns it on only where the item buffer is drawn over many times.
"""

from __future__ import annotations

import numpy as np
import pytest

from daskrad import formfactor as ff
from daskrad.formfactor import shooting
from daskrad.kernels.hemisphere import hemisphere_visibility
from daskrad.mesh import build_hierarchy
from daskrad.settings import Settings
from daskrad.testing import stress
from tests.helpers import UP, closed_box, grid, merge, triangle_soup

HORIZON = 1e-9
EDGE = np.radians(2.0)


def slabs(k: int):
    """``k`` horizontal 0.8 × 0.8 squares facing down at heights 0.2 … 0.8 inside the closed unit
    box, and a stack of ``k`` shooters on the floor looking up: every slab but the lowest is
    hidden from them behind the one below."""
    parts = [closed_box(4)]
    for z in np.linspace(0.2, 0.8, k):
        parts.append(grid([0.1, 0.1, z], [0.0, 0.8, 0.0], [0.8, 0.0, 0.0], 3))
    verts, elems = merge(*parts)
    points = np.array([[0.5, 0.5, 0.0], [0.3, 0.4, 0.0], [0.45, 0.6, 0.0]])
    return verts, elems, points, np.tile(UP, (3, 1))


def box_in_box():
    outer = closed_box(4)
    inner_v, inner_e = closed_box(2, size=0.3)
    verts, elems = merge(outer, (inner_v + 0.35, inner_e[:, ::-1].copy()))
    points = np.array([[0.5, 0.5, 0.0], [0.1, 0.2, 0.0], [0.2, 0.0, 0.6]])
    return verts, elems, points, np.array([UP, UP, [0.0, 1.0, 0.0]])


def cases(rng):
    soup = triangle_soup(rng, 300)
    return {"slabs": slabs(5), "box in box": box_in_box(), "soup": soup}


@pytest.mark.parametrize("case", ["slabs", "box in box", "soup"])
@pytest.mark.parametrize("resolution", [64, 101])
def test_hiz_wins_the_same_pixels(rng, case, resolution):
    verts, elems, points, normals = cases(rng)[case]
    normals = normals / np.linalg.norm(normals, axis=1)[:, None]
    args = (np.ascontiguousarray(points), np.ascontiguousarray(normals), verts, elems,
            resolution, EDGE, False, HORIZON)
    won, covered, n_disc, visible = hemisphere_visibility(*args, False)
    won_h, covered_h, n_disc_h, visible_h = hemisphere_visibility(*args, True)
    assert n_disc_h == n_disc
    np.testing.assert_array_equal(won_h, won)
    drawn = covered_h > 0
    # an element drawn covers what it covers without hiz, and sees what it sees
    np.testing.assert_array_equal(covered_h[drawn], covered[drawn])
    np.testing.assert_array_equal(visible_h[drawn], visible[drawn])
    # an element left out wins nothing either way
    left_out = (covered > 0) & ~drawn
    assert (won[left_out] == 0).all()
    if case == "slabs":  # stacked surfaces: most of the hidden ones are left out
        assert left_out.sum() >= 0.5 * ((covered > 0) & (won == 0)).sum() > 0


@pytest.mark.parametrize("case", ["slabs", "box in box"])
def test_hiz_rows_are_the_rows(rng, case):
    # large hidden elements get F = 0 from won = 0 either way: the rows are the same bits
    verts, elems, points, normals = cases(rng)[case]
    off = ff.shooter_rows(points, normals, verts, elems, "hemisphere", 96, hiz=False)
    on = ff.shooter_rows(points, normals, verts, elems, "hemisphere", 96, hiz=True)
    np.testing.assert_array_equal(on, off)
    if case == "box in box":  # closed: the rows still sum to 1
        np.testing.assert_allclose(on.sum(axis=1), 1.0, atol=1e-9)


def shelves_scene():
    verts, polys = [], []
    for z in np.linspace(0.15, 0.85, 8):
        base = len(verts)
        verts += [[0.05, z, 0.05], [0.95, z, 0.05], [0.95, z, 0.95], [0.05, z, 0.95]]
        polys += [[base, base + 1, base + 2, base + 3], [base + 3, base + 2, base + 1, base]]
    return stress.box_with(verts, polys)


def test_solve_chooses_hiz_by_depth_complexity():
    settings = Settings()
    convex = build_hierarchy(stress.box_with(), settings.patch_size, settings.element_size)
    shelves = build_hierarchy(shelves_scene(), settings.patch_size, settings.element_size)
    # a convex room is drawn over once from anywhere in it (watertight edges), but for a
    # pixel centre or so where two walls meet the horizon (R = 64: 1/3,200 of a disc)
    assert shooting.depth_complexity(convex) == pytest.approx(1.0, abs=1e-3)
    assert shooting.depth_complexity(shelves) > shooting.HIZ_DEPTH
    assert not shooting.make_context(convex, "hemisphere", 64).options["hiz"]
    assert shooting.make_context(shelves, "hemisphere", 64).options["hiz"]
    # the other methods are not given the option
    assert "hiz" not in shooting.make_context(shelves, "hemicube", 64).options


def test_solve_with_hiz_is_the_solve_without(monkeypatch):
    # Eight shelves in the furnace box (depth complexity above HIZ_DEPTH): the solve drawn
    # front to back gives the radiosity of the plain pass but for the elements the bilinear
    # test counted partly visible behind nearer surfaces (sub-pixel ones), left out with hiz.
    # The furnace error itself (2.6 % at these coarse settings, 1.2 % with four shelves) is
    # the shelves' at R = 64, the same both ways.
    box = stress.BOX
    h = build_hierarchy(shelves_scene(), box.patch_size, box.element_size)
    assert shooting.make_context(h, box.method, box.resolution).options["hiz"]
    with_hiz = stress.furnace_error("shelves", shelves_scene())
    monkeypatch.setattr(shooting, "HIZ_DEPTH", np.inf)
    without = stress.furnace_error("shelves", shelves_scene())
    assert with_hiz.extra == without.extra   # the same shots
    assert abs(with_hiz.error - without.error) < 1e-6
