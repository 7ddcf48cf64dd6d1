"""Hard shadows, contact lines and leaks (issue 14).

- Point and directional light is one shadow ray per pixel: a shadow that falls between an
  element's corners (all of them lit) is still drawn, exactly.
- Polygons are cut along the lines where others stand on them, so no element straddles the
  foot of a block.
- A vertex on a junction (a wall's top edge under the ceiling) takes no light through the
  surface it meets: a light outside a closed room leaves the room black, with a warning.
"""

from __future__ import annotations

import math

import numpy as np

from daskrad import render
from daskrad.io import read_exr
from daskrad.mesh import build_hierarchy
from daskrad.mesh.contacts import cut_at_contacts
from daskrad.run import run
from daskrad.scene import Camera, load_scene, scene_from_arrays
from daskrad.settings import Settings
from daskrad.testing import shadows as shadow_scenes
from tests.helpers import render_context

RHO = 0.5


def _floor_and_post(sun):
    """A 4 × 4 floor (ρ 0.5) and a thin black square 0.1 wide at height 1, facing down, under
    a sun travelling along ``sun``: the post's shadow, 0.1 wide, falls inside one element of
    the coarse mesh (element 2.0: corners 2 apart) and no vertex is in it."""
    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [0.45, 1, 0.45], [0.55, 1, 0.45], [0.55, 1, 0.55], [0.45, 1, 0.55]], float)
    cam = Camera(eye=np.array([1.0, 2.5, 0.5]), look_at=np.array([1.0, 0.0, 0.5]),
                 up=np.array([0.0, 0.0, 1.0]), fov=30.0, width=48, height=48)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                             diffuse=[[RHO] * 3, [0.0] * 3], emission=[[0.0] * 3] * 2,
                             camera=cam, directional_lights=([sun], [[2.0, 2.0, 2.0]]))


def test_sun_shadow_between_vertices_is_exact_at_every_pixel():
    sun = np.array([0.5, -1.0, 0.0]) / math.sqrt(1.25)
    scene = _floor_and_post(sun)
    ctx, h = render_context(scene, patch_size=4.0, element_size=2.0, subdivide=0.0)
    assert ctx.hard_lights is not None
    cam = scene.camera
    image = render.render(ctx)[..., 0].ravel()       # 1 sample per pixel: its centre ray
    o, d = render.primary_rays(cam, slice(0, cam.height), slice(0, cam.width), 1)
    # the centre ray meets the post (black, seen from behind) or the floor at p, which is in
    # the shadow when the ray from p towards the sun crosses the post's square at y = 1
    q = o + ((1.0 - o[:, 1]) / d[:, 1])[:, None] * d
    p = o + (-o[:, 1] / d[:, 1])[:, None] * d
    c = p - sun / -sun[1]                             # where p's sun ray reaches y = 1
    margin = lambda x: np.abs(np.abs(x - 0.5) - 0.05)  # noqa: E731  distance to the outline
    post = (np.abs(q[:, 0] - 0.5) < 0.05) & (np.abs(q[:, 2] - 0.5) < 0.05)
    shadow = (np.abs(c[:, 0] - 0.5) < 0.05) & (np.abs(c[:, 2] - 0.5) < 0.05)
    exact = np.where(post | shadow, 0.0, RHO * 2.0 * (-sun[1]) / math.pi)
    # pixels whose centre is not within round-off of an outline
    clear = np.minimum(np.minimum(margin(q[:, 0]), margin(q[:, 2])),
                       np.minimum(margin(c[:, 0]), margin(c[:, 2]))) > 1e-9
    assert (shadow & ~post & clear).sum() >= 4        # the shadow is in view, a few pixels
    # no vertex is in the shadow (vertices 2 apart, the shadow 0.1 wide at x = 1)
    floor_v = np.abs(h.vertices[:, 1]) < 1e-12
    assert not ((np.abs(h.vertices[floor_v, 0] - 1.0) < 0.05)
                & (np.abs(h.vertices[floor_v, 2] - 0.5) < 0.05)).any()
    np.testing.assert_allclose(image[clear], exact[clear], rtol=1e-12, atol=1e-15)
    # without the per-pixel pass the shadow is lost between the vertices (the test can fail)
    plain = render.render(render_context(scene, patch_size=4.0, element_size=2.0,
                                         subdivide=0.0, per_pixel=False)[0])[..., 0].ravel()
    assert np.all(plain[shadow & ~post & clear] > 0.1)


def test_floor_is_cut_along_the_feet_of_the_blocks(scenes_dir):
    scene = load_scene(scenes_dir / "cornell_box.obj")
    cut, parent, normals = cut_at_contacts(scene)
    floor = np.flatnonzero(parent == 0)
    assert len(floor) > 1 and np.all(np.bincount(parent)[1:] == 1)
    # the pieces tile the floor: areas add up, each piece lies in the floor's plane
    h = build_hierarchy(scene)
    area = np.bincount(h.elem_polygon, h.elem_area)
    full = build_hierarchy(scene, 1e4, 1e4)  # one patch per piece
    assert np.isclose(area[floor].sum(), 552.8 * 559.2 - 0.5 * 3.2 * 559.2, rtol=1e-12)
    assert np.allclose(full.elem_centroid[np.isin(full.elem_polygon, floor)][:, 1], 0.0)
    # no element straddles a block's foot: its corners lie all inside or all outside the
    # footprint (within round-off of the foot lines)
    for foot in shadow_scenes.block_feet():
        xz = foot[:, [0, 2]]
        edge = np.roll(xz, -1, axis=0) - xz
        on_floor = np.isin(h.elem_polygon, floor)
        corners = h.vertices[h.elem_verts[on_floor][:, :3]][..., [0, 2]]
        # signed distance of every corner to every foot line, positive inside
        inward = np.stack([edge[:, 1], -edge[:, 0]], axis=1)
        inward /= np.linalg.norm(inward, axis=1, keepdims=True)
        if np.sum(inward[0] * (xz.mean(0) - xz[0])) < 0:
            inward = -inward
        s = np.einsum("eck,lk->ecl", corners, inward) - np.sum(inward * xz, axis=1)
        tol = 1e-9 * scene.diagonal
        strictly_in = (s > tol).all(axis=2)          # (elements, corners)
        strictly_out = (s < -tol).any(axis=2)
        assert not (strictly_in.any(axis=1) & strictly_out.any(axis=1)).any()
        assert strictly_in.all(axis=1).sum() > 0       # elements under the block exist


def test_light_outside_a_closed_room_leaves_it_black_and_warns(tmp_path, capsys):
    path = shadow_scenes.closed_box_outside(tmp_path)
    out = tmp_path / "out.exr"
    report = run(path, out, Settings(width=32, height=32, workers=0), progress=False)
    assert np.all(read_exr(out) == 0.0)
    assert report["warnings"] and "no surface receives any light" in report["warnings"][0]
    assert "no surface receives any light" in capsys.readouterr().err
    # the same box lit from inside is not black and does not warn (the test can fail)
    inside = shadow_scenes.closed_box_point(tmp_path)
    report = run(inside, out, Settings(width=32, height=32, workers=0), progress=False)
    assert read_exr(out).mean() > 0.05 and not report["warnings"]


def _wall_on_floor():
    """A 4 × 4 floor (ρ 0.5) lit straight down by a sun of 2 W/m², and a wall 1 high (ρ 0.2)
    standing on its back edge, facing it, lit by nothing but the floor."""
    v = np.array([[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2],
                  [-2, 0, -2], [2, 0, -2], [2, 1, -2], [-2, 1, -2]], float)
    return scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                             diffuse=[[0.5] * 3, [0.2] * 3], emission=[[0.0] * 3] * 2,
                             directional_lights=([[0.0, -1.0, 0.0]], [[2.0, 2.0, 2.0]]))


def test_foot_of_a_wall_gathers_the_lit_floor_beside_it():
    # At the wall's foot the floor (radiance ρ_f E / π) fills the part F of the hemisphere
    # that Lambert's formula gives: the foot's radiance is ρ_w ρ_f E F / π. Element averages
    # take the light of points half an element up, where the floor fills less; the gather at
    # vertices beside a junction takes it at the vertex.
    from daskrad.kernels.lambert import lambert_polygon

    scene = _wall_on_floor()
    opts = dict(patch_size=1.0, element_size=0.5, subdivide=0.0)
    ctx, h = render_context(scene, **opts)
    plain, _ = render_context(scene, per_pixel=False, **opts)
    foot = _wall_vertices(h, y=0.0, xmax=1.0)
    assert len(foot) >= 3
    F = np.array([lambert_polygon(x, 1e-5 * scene.diagonal, -2.0, 0.0, 0.0, 1.0,
                                  scene.vertices[[0, 1, 2, 3]], 4) for x in h.vertices[foot, 0]])
    exact = 0.2 * 0.5 * 2.0 * F / math.pi
    # the floor also takes light back from the wall (≤ ρ_f ρ_w / 4 = 2.5 % of its own) and
    # 32 × 32 stratified rays estimate F to a few 1e-3: 4 %
    np.testing.assert_allclose(ctx.vertex_radiance[foot, 0], exact, rtol=0.04)
    # element averages (the plain context) are farther off (the test can fail)
    assert np.all(plain.vertex_radiance[foot, 0] < 0.93 * exact)


def _wall_vertices(h, y, xmax):
    """The wall's vertices (polygon facing +z) at height ``y`` with ``|x| ≤ xmax``."""
    from daskrad.mesh import vertex_polygon

    vp = vertex_polygon(h)
    wall = np.zeros(len(h.vertices), bool)
    normal_z = np.zeros(len(h.polygon_material))
    normal_z[h.patch_polygon] = h.patch_normal[:, 2]
    wall[vp >= 0] = normal_z[vp[vp >= 0]] > 0.5
    return np.flatnonzero(wall & (np.abs(h.vertices[:, 1] - y) < 1e-12)
                          & (np.abs(h.vertices[:, 0]) <= xmax))


def test_the_junction_gather_of_a_view_changes_only_the_corners_near_what_it_shows(
        monkeypatch):
    # A camera close above the floor's left half, looking down: the image shows part of the
    # floor and of the wall's foot. The gather is view-dependent: it changes only corners of
    # the elements the primary rays hit and of their neighbours (elements sharing a corner);
    # without a camera it gathers everywhere, so it also changes corners farther away (the
    # test can fail both ways). A scene this small gathers everywhere whatever the view
    # (GATHER_ALL): the view's gather is what scenes with more junction vertices get.
    from dataclasses import replace

    from daskrad.run import solve_scene

    scene = _wall_on_floor()
    settings = Settings(patch_size=1.0, element_size=0.5, subdivide=0.0, spp=1)
    h, _, sol, light = solve_scene(scene, settings)
    cam = Camera(eye=np.array([-1.5, 1.0, -1.2]), look_at=np.array([-1.5, 0.0, -1.6]),
                 up=np.array([0.0, 0.0, -1.0]), fov=40.0, width=24, height=24)
    ctx = render.context(scene, light, sol, settings, cam)
    assert ctx.junctions is not None
    seen = render.seen_elements(ctx)
    assert 0 < seen.sum() < len(seen)
    ev, valid = h.elem_verts, h.elem_verts >= 0

    def corners(elements):
        out = np.zeros(len(h.vertices), bool)
        out[ev[elements][valid[elements]]] = True
        return out

    near = corners((corners(seen)[np.where(valid, ev, 0)] & valid).any(axis=1))
    assert not near.all()
    whole = render.for_view(ctx)
    monkeypatch.setattr(render, "GATHER_ALL", 0)
    view = render.for_view(ctx)
    everywhere = render.for_view(replace(ctx, camera=None))
    changed = np.any(view.vertex_radiance != ctx.vertex_radiance, axis=1)
    assert changed[corners(seen)].any() and not changed[~near].any()
    assert np.any(everywhere.vertex_radiance[~near] != ctx.vertex_radiance[~near])
    np.testing.assert_array_equal(whole.vertex_radiance, everywhere.vertex_radiance)
    # Whatever GATHER_ALL, the view's gather is the whole gather restricted to the region or,
    # below the threshold, the whole gather: the region is searched first for surfaces nearby
    # and the whole scene only when the region alone does not exceed it, which must give the
    # same bits as searching the whole scene first. As GATHER_ALL grows the answer turns from
    # the region's to the whole one once, and never to anything else.
    answers = []
    for limit in range(0, len(h.vertices) + 1, max(1, len(h.vertices) // 40)):
        monkeypatch.setattr(render, "GATHER_ALL", limit)
        got = render.for_view(ctx).vertex_radiance
        same = [np.array_equal(got, v.vertex_radiance) for v in (view, whole)]
        assert any(same), limit
        answers.append(same[1])
    assert not answers[0] and answers[-1] and answers == sorted(answers)
    monkeypatch.setattr(render, "GATHER_ALL", 0)
    # the image is the view's gather rendered (the stored context keeps the solution's values)
    assert view.junctions is None and ctx.junctions is not None
    image = render.pixels(ctx)
    np.testing.assert_array_equal(image, render.pixels(view))
    assert np.any(image != render.pixels(replace(ctx, junctions=None)))
