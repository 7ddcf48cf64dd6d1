"""The view's hits by screen bins (:mod:`daskrad.kernels.view`) against the walk of the
polygons' grid (:func:`daskrad.kernels.grid.closest_hit_located_batch`): the same ``(t, tri,
u, v)``, bit for bit, for rays leaving one point, wherever the geometry lies (behind the eye,
across its plane, through it, along shared edges), at any number of bins."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from daskrad import render
from daskrad.kernels import view
from daskrad.kernels.grid import build_grid, closest_hit_located_batch, locator
from tests.helpers import steps_on


def _walked(polygons, elements, loc, eye, d):
    n = len(d)
    return closest_hit_located_batch(polygons, loc, elements, np.tile(eye, (n, 1)), d,
                                     np.zeros(n), np.full(n, np.inf))


def _binned(polygons, elements, loc, eye, d, bins=None):
    if bins is None:
        return view.view_hits_batch(polygons, loc, elements, eye, d)
    mean = d.sum(axis=0)
    f = mean / np.linalg.norm(mean)
    r = np.cross(f, [0.3, 0.5, 0.8])
    r /= np.linalg.norm(r)
    u = np.cross(f, r)
    return view.view_hits(polygons, elements, loc, eye, np.ascontiguousarray(d), r, u, f,
                          bins, bins)


def _same(a, b):
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)


def _cone(rng, n, axis, half_angle_deg):
    """``n`` unit directions within ``half_angle_deg`` of ``axis``, and a few exactly on it."""
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    d = rng.normal(size=(n, 3))
    d -= (d @ axis)[:, None] * axis
    d /= np.linalg.norm(d, axis=1)[:, None]
    ang = np.radians(half_angle_deg) * np.sqrt(rng.random(n))
    d = np.cos(ang)[:, None] * axis + np.sin(ang)[:, None] * d
    d[:3] = axis
    return d


@pytest.mark.parametrize("bins", [None, 1, 3, 40])
@pytest.mark.parametrize("eye", [(0.5, 0.5, 0.5), (0.5, 0.5, -2.0), (0.1, 0.9, 0.5)],
                         ids=["inside", "outside", "off centre"])
def test_binned_hits_are_the_walks_in_a_soup(rng, bins, eye):
    # a soup around and behind the eye: triangles across its plane, behind it, in front
    centre = rng.random((600, 3)) * 1.6 - 0.3
    tris = centre[:, None, :] + rng.normal(scale=0.08, size=(600, 3, 3))
    polygons = build_grid(tris)
    loc = locator(tris)
    eye = np.array(eye, float)
    d = _cone(rng, 4000, [0.2, -0.1, 1.0], 60.0)
    _same(_binned(polygons, polygons, loc, eye, d, bins), _walked(polygons, polygons, loc,
                                                                  eye, d))


@pytest.mark.parametrize("bins", [None, 1, 7])
def test_rays_along_shared_edges_and_geometry_at_the_eye(bins):
    # a fan of triangles sharing the vertex above the eye, rays aimed exactly at the shared
    # edges and corners (where only the walk's edge tolerance decides), a triangle through
    # the eye itself and one across its plane beside it
    eye = np.array([0.0, 0.0, 0.0])
    apex = np.array([0.0, 0.0, 1.0])
    rim = [np.array([np.cos(a), np.sin(a), 1.0]) for a in np.linspace(0, 2 * np.pi, 9)[:-1]]
    fan = [np.array([apex, rim[k], rim[(k + 1) % 8]]) for k in range(8)]
    through = np.array([[-0.3, -0.3, -0.2], [0.3, -0.2, 0.2], [0.0, 0.4, 0.1]])  # holds the eye
    across = np.array([[2.0, 0.0, -1.0], [2.0, 0.5, 1.0], [2.0, -0.5, 2.0]])
    tris = np.array(fan + [through, across])
    polygons = build_grid(tris)
    loc = locator(tris)
    aims = [apex] + rim + [0.5 * (apex + p) for p in rim] + [0.5 * (p + q) for p, q in
                                                             zip(rim, rim[1:] + rim[:1],
                                                                 strict=True)]
    d = np.array(aims, float)
    d = np.vstack([d, d * np.array([1.0, 1.0, -1.0]), [[1.0, 0.0, 0.0], [1.0, 0.1, 0.3]]])
    d /= np.linalg.norm(d, axis=1)[:, None]
    _same(_binned(polygons, polygons, loc, eye, d, bins), _walked(polygons, polygons, loc,
                                                                  eye, d))


def test_polygons_and_elements_apart(rng):
    # the polygons' grid finds the surface, the elements' the triangle that holds the point
    # (two elements per polygon here): the binned hits take the same located answer
    quads = rng.random((150, 3)) * 2.0
    polys, elems = [], []
    for c in quads:
        a, b = rng.normal(scale=0.1, size=(2, 3))
        p = [c, c + a, c + a + b, c + b]
        polys += [[p[0], p[1], p[2]], [p[0], p[2], p[3]]]
        m = 0.5 * (p[0] + p[2])
        elems += [[p[0], p[1], m], [p[1], p[2], m], [p[2], p[3], m], [p[3], p[0], m]]
    polygons, elements = build_grid(np.array(polys)), build_grid(np.array(elems))
    loc = locator(np.array(elems))
    eye = np.array([1.0, 1.0, -1.5])
    d = _cone(rng, 3000, [0.0, 0.0, 1.0], 45.0)
    got = _binned(polygons, elements, loc, eye, d)
    _same(got, _walked(polygons, elements, loc, eye, d))
    assert (got[1] >= 0).sum() > 300            # a test of hits, not of misses


def test_rays_behind_the_view_walk(rng):
    # directions on every side: those behind the mean direction's plane walk the grid
    tris = rng.random((300, 3, 3)) * 2.0 - 1.0
    polygons = build_grid(tris)
    loc = locator(tris)
    d = rng.normal(size=(2000, 3))
    d[:1000, 2] = np.abs(d[:1000, 2]) + 2.0        # most forward, the rest anywhere
    d /= np.linalg.norm(d, axis=1)[:, None]
    eye = np.zeros(3)
    got = _binned(polygons, polygons, loc, eye, d)
    _same(got, _walked(polygons, polygons, loc, eye, d))
    assert (got[1] >= 0).sum() > 500


def test_the_render_takes_the_same_bits_by_bins(monkeypatch):
    # the camera's rays of the Cornell box through bins and through the walk: the same image
    scene, light, sol, image = steps_on("cornell_box.obj", 2)
    assert render.VIEW_BINS
    monkeypatch.setattr(render, "VIEW_BINS", False)
    walked = render.pixels(replace(image.context))
    np.testing.assert_array_equal(walked, image.pixels)
    assert image.stats["edges"] > 0     # edge pixels' samples went through the bins too


@pytest.mark.parametrize("bins", [None, 1, 5])
def test_a_ray_within_the_edge_tolerance_outside_a_lone_triangle(bins):
    # the walk counts a point up to eps outside a triangle's edge lines as a hit: rays aimed
    # just outside one edge (and beyond a corner) must find the triangle in their bin. With
    # a coarser tolerance (a millionth of the scene) the offset is far beyond the widening
    # for round-off: only the triangle grown by the tolerance holds them
    tri = np.array([[[-1.0, -1.0, 5.0], [1.0, -1.0, 5.0], [0.0, 1.0, 5.0]]])
    other = np.array([[[50.0, 50.0, 9.0], [51.0, 50.0, 9.0], [50.0, 51.0, 9.0]],
                      [[-50.0, -50.0, 1.0], [-51.0, -50.0, 1.0], [-50.0, -51.0, 1.0]]])
    tris = np.concatenate([tri, other])         # the others: the triangle inside the grid
    polygons = build_grid(tris, rel_eps=1e-6)
    loc = locator(tris)
    eps = polygons.eps
    xs = np.linspace(-0.9, 0.9, 40)
    aims = [[x, -1.0 - 0.5 * eps, 5.0] for x in xs]            # below the bottom edge
    aims += [[1.0 + 0.3 * eps, -1.0 - 0.3 * eps, 5.0]]          # beyond a corner
    d = np.array(aims)
    d /= np.linalg.norm(d, axis=1)[:, None]
    eye = np.zeros(3)
    walked = _walked(polygons, polygons, loc, eye, d)
    assert (walked[1] == 0).sum() >= 20             # the walk hits most of them
    _same(_binned(polygons, polygons, loc, eye, d, bins), walked)


@pytest.mark.parametrize("bins", [None, 1, 6])
def test_geometry_within_the_near_depth_of_the_eye(rng, bins):
    # a small triangle across the view's axis at a tenth of the near depth zc (it projects
    # over much of the screen), a long one from just off the eye out to the far wall passing
    # beside the axis, and a far wall that sets the scene's extent
    zc = view.NEAR * np.sqrt(3.0)
    small = [[-1e-6, -1e-6, 0.1 * zc], [1e-6, -1e-6, 0.1 * zc], [0.0, 1e-6, 0.1 * zc]]
    long = [[2e-6, -1.0, 1e-7], [2e-6, 1.0, 1e-7], [0.05, 0.0, 1.0]]
    wall = [[-1.0, -1.0, 1.0], [1.0, -1.0, 1.0], [0.0, 1.0, 1.0]]
    far = [[1.0, 1.0, 0.9], [0.9, 1.0, 1.0], [1.0, 0.9, 1.0]]
    tris = np.array([small, long, wall, far])
    polygons = build_grid(tris)
    loc = locator(tris)
    eye = np.zeros(3)
    d = _cone(rng, 3000, [0.0, 0.0, 1.0], 15.0)
    walked = _walked(polygons, polygons, loc, eye, d)
    assert (walked[1] == 0).sum() > 100 and (walked[1] == 1).sum() > 20
    _same(_binned(polygons, polygons, loc, eye, d, bins), walked)


def test_a_soup_far_from_the_origin_with_slivers(rng):
    # coordinates of a million (a building in map units), and slivers among the triangles
    centre = rng.random((400, 3)) * 2.0
    tris = centre[:, None, :] + rng.normal(scale=0.1, size=(400, 3, 3))
    tris[::10, 2] = tris[::10, 0] + 1e-13 * (tris[::10, 1] - tris[::10, 0])   # slivers
    shift = np.array([1e6, -2e6, 5e5])
    tris = tris + shift
    polygons = build_grid(tris)
    loc = locator(tris)
    eye = shift + np.array([1.0, 1.0, -1.0])
    d = _cone(rng, 3000, [0.1, 0.0, 1.0], 40.0)
    got = _binned(polygons, polygons, loc, eye, d)
    _same(got, _walked(polygons, polygons, loc, eye, d))
    assert (got[1] >= 0).sum() > 300


@pytest.mark.parametrize("case", ["one ray", "one direction", "not finite", "sideways"])
def test_odd_batches(rng, case):
    tris = rng.random((200, 3, 3)) * 2.0 - 1.0
    polygons = build_grid(tris)
    loc = locator(tris)
    eye = np.array([0.0, 0.0, -2.0])
    d = _cone(rng, 50, [0.0, 0.0, 1.0], 20.0)
    if case == "one ray":
        d = d[:1]
    elif case == "one direction":
        d[:] = d[0]
    elif case == "not finite":
        d[::7] = np.nan
        d[1::7] = [np.inf, 0.0, 1.0]
    else:       # perpendicular to the mean direction, or away from it
        d[::3] = [1.0, 0.0, 0.0]
        d[1::9] = [0.0, 0.0, -1.0]
    _same(_binned(polygons, polygons, loc, eye, d), _walked(polygons, polygons, loc, eye, d))
