"""The image: camera convention, radiance units, one-sidedness, the Cornell box end to end."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from daskrad import render
from daskrad.io import read_exr
from daskrad.kernels.grid import build_grid
from daskrad.mesh import build_hierarchy, hierarchy_triangles, vertex_average
from daskrad.scene import Camera, scene_from_arrays
from tests.helpers import SCENES


def _plane_context(radiance, normal_up=True, size=64, spp=1):
    """A unit square in z = 0 seen from z = +1 (or its back), uniform vertex radiance."""
    poly = np.array([[0, 1, 2, 3]]) if normal_up else np.array([[3, 2, 1, 0]])
    scene = scene_from_arrays(
        np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]), poly, [0],
        diffuse=[[0.5, 0.5, 0.5]], emission=[[1.0, 1.0, 1.0]])
    h = build_hierarchy(scene, 1.0, 0.5)
    tris, tri_verts, tri_elem = hierarchy_triangles(h)
    cam = Camera(eye=np.array([0.0, 0.0, 1.0]), look_at=np.zeros(3), up=np.array([0.0, 1, 0]),
                 fov=30.0, width=size, height=size)
    vr = np.tile(np.asarray(radiance, float), (len(h.vertices), 1))
    return render.RenderContext(grid=build_grid(tris), tri_verts=tri_verts, tri_element=tri_elem,
                                elem_normal=h.elem_normal, vertex_radiance=vr, camera=cam,
                                spp=spp)


def test_uniform_plane_shows_its_radiance_and_back_is_black():
    # The camera's view (fov 30° at distance 1) lies inside the 2×2 square: every pixel sees
    # the plane, so every pixel is exactly the vertex radiance (Gouraud of a constant).
    img = render.render(_plane_context([0.25, 0.5, 1.0]))
    np.testing.assert_allclose(img, np.broadcast_to([0.25, 0.5, 1.0], img.shape), rtol=1e-12)
    # The same plane wound the other way faces away from the camera: one-sided, so black.
    back = render.render(_plane_context([0.25, 0.5, 1.0], normal_up=False))
    assert np.all(back == 0.0)


def test_tiles_assemble_to_the_same_image_whatever_the_tile_size():
    ctx = _plane_context([1.0, 1.0, 1.0], size=50, spp=4)
    whole = render.render_tile(ctx, slice(0, 50), slice(0, 50))
    for tile in (7, 16, 64):
        img = np.zeros_like(whole)
        for rows, cols in render.tiles(50, 50, tile):
            img[rows, cols] = render.render_tile(ctx, rows, cols)
        np.testing.assert_array_equal(img, whole)


def _square_context(half, size, spp, edge_spp):
    """A square ``[-half, half]²`` in z = 0 facing a camera at z = 1 (fov 30°), radiance 1,
    nothing behind it; and the exact part ``(size,)`` of each pixel row (and column) it
    covers: a pixel's coverage is the product of its row's and its column's."""
    scene = scene_from_arrays(
        np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]]),
        np.array([[0, 1, 2, 3]]), [0], diffuse=[[0.5] * 3], emission=[[1.0] * 3])
    h = build_hierarchy(scene, 2 * half, 2 * half)
    tris, tri_verts, tri_elem = hierarchy_triangles(h)
    cam = Camera(eye=np.array([0.0, 0.0, 1.0]), look_at=np.zeros(3), up=np.array([0.0, 1, 0]),
                 fov=30.0, width=size, height=size)
    ctx = render.RenderContext(
        grid=build_grid(tris), tri_verts=tri_verts, tri_element=tri_elem,
        elem_normal=h.elem_normal, vertex_radiance=np.ones((len(h.vertices), 3)),
        camera=cam, spp=spp, edge_spp=edge_spp, edge_step=render.EDGE_STEP)
    # a fronto-parallel square projects to the square [lo, hi]² of pixel coordinates
    t = math.tan(math.radians(cam.fov) / 2.0)
    lo, hi = (1.0 - half / t) / 2.0 * size, (1.0 + half / t) / 2.0 * size
    edges = np.arange(size + 1, dtype=float)
    overlap = np.clip(np.minimum(edges[1:], hi) - np.maximum(edges[:-1], lo), 0.0, 1.0)
    return ctx, overlap


def test_pixels_on_an_edge_are_sampled_again_and_take_their_coverage():
    # An edge pixel's 64 samples (an 8 × 8 grid of cell centres) estimate its coverage to
    # 1/16 along each axis the edge crosses; the 4 samples of the base grid only to 1/4. Only
    # the pixels beside the outline (0.3 of a pixel into them) are sampled again; each takes
    # the bits of a whole image rendered at 64 samples, the others those of the base image.
    size = 24
    ctx, overlap = _square_context(0.11834, size, 4, 64)
    coverage = overlap[:, None] * overlap[None, :]
    cut = (overlap > 0) & (overlap < 1)
    img = render.render(ctx)[..., 0]
    base = render.render(replace(ctx, edge_spp=0))[..., 0]
    full = render.render(replace(ctx, spp=64, edge_spp=0))[..., 0]
    again = img != base
    partial = (coverage > 0) & (coverage < 1)
    assert again[partial].mean() > 0.5 and again.sum() < 0.5 * size * size
    np.testing.assert_array_equal(img[again], full[again])
    # the run report's count: every pixel that changed was sampled again (a pixel inside
    # the square beside one on the outline may be too, and keep its value)
    same, stats = render.pixels_stats(ctx)
    np.testing.assert_array_equal(same[..., 0], img)
    assert again.sum() <= stats["edges"] <= again.sum() + 8 * size
    corner = cut[:, None] & cut[None, :]           # both axes cut: errors add up
    edge = partial & ~corner
    assert np.abs(img - coverage)[edge].max() <= 1 / 16 + 1e-12
    assert np.abs(img - coverage).max() <= 2 / 16 + 1 / 256 + 1e-12
    assert np.abs(base - coverage)[edge].max() > 1 / 8       # the test can fail


def test_edge_resampling_does_not_depend_on_the_tiles():
    ctx, _ = _square_context(0.11834, 50, 4, 64)
    whole, stats = render.render_tile_stats(ctx, slice(0, 50), slice(0, 50))
    assert 0 < stats["edges"] < 50 * 50
    for tile in (7, 16):
        img = np.zeros_like(whole)
        edges = 0
        for rows, cols in render.tiles(50, 50, tile):
            img[rows, cols], part = render.render_tile_stats(ctx, rows, cols)
            edges += part["edges"]
        np.testing.assert_array_equal(img, whole)
        assert edges == stats["edges"]        # the same pixels, whatever the tiles


def test_camera_right_is_forward_cross_up():
    cam = Camera(eye=np.array([278.0, 273, -800]), look_at=np.array([278.0, 273, 0]),
                 up=np.array([0.0, 1, 0]), fov=39.3077, width=8, height=8)
    forward, right, up = render.camera_frame(cam)
    np.testing.assert_allclose(forward, [0, 0, 1])
    np.testing.assert_allclose(right, [-1, 0, 0])  # seen from -z, +x (the red wall) is left
    np.testing.assert_allclose(up, [0, 1, 0])
    o, d = render.primary_rays(cam, slice(0, 8), slice(0, 8), 1)
    d = d.reshape(8, 8, 3)
    assert d[4, 0, 0] > 0 and d[4, 7, 0] < 0       # column 0 looks towards +x
    assert d[0, 4, 1] > 0 and d[7, 4, 1] < 0       # row 0 looks up
    # horizontal field of view: the outer pixel edges are ±fov/2 from the axis
    half = math.degrees(math.atan(math.tan(math.radians(39.3077) / 2) * 7 / 8))
    assert math.degrees(math.atan2(abs(d[4, 0, 0]), d[4, 0, 2])) == pytest.approx(half, rel=1e-9)


@pytest.fixture(scope="module")
def cornell(tmp_path_factory, ):
    out = tmp_path_factory.mktemp("cb") / "cb.exr"
    cmd = [sys.executable, "-m", "daskrad", "run", str(SCENES / "cornell_box.obj"), "-o",
           str(out), "--workers", "0", "--width", "96", "--height", "96", "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    return out


def test_cornell_box_image_is_finite_positive_with_walls_on_the_right_sides(cornell):
    img = read_exr(cornell)
    assert img.shape == (96, 96, 3)
    assert np.isfinite(img).all() and (img >= 0).all()
    mid = img[40:56]
    left, right = mid[:, 2:10].mean(axis=(0, 1)), mid[:, -10:-2].mean(axis=(0, 1))
    # red wall (0.63, 0.065, 0.05) on the left, green (0.14, 0.45, 0.091) on the right
    assert left[0] > 3 * left[1] and left[0] > 3 * left[2]
    assert right[1] > 2 * right[0] and right[1] > 2 * right[2]
    # the light is visible at the top centre with its own radiance (Ke = 17, 12, 4)
    top = img[:24, 30:66].reshape(-1, 3)
    brightest = top[np.argmax(top.sum(axis=1))]
    np.testing.assert_allclose(brightest, [17, 12, 4], rtol=0.02)


def test_cornell_box_writes_preview_and_report(cornell):
    from PIL import Image

    png = Image.open(cornell.with_suffix(".png"))
    assert png.size == (96, 96) and png.mode == "RGB"
    report = json.loads(cornell.with_suffix(".json").read_text())
    assert report["converged"] is True
    assert report["counts"]["emitters"] == 1
    rms = [h["relative_unshot_rms"] for h in report["unshot_rms_history"]]
    assert rms[-1] <= report["settings"]["tolerance"]
    assert report["iterations"] == report["unshot_rms_history"][-1]["iteration"]
    # the shot cap the run resolved from its patch count is the one it reports
    from daskrad.settings import MIN_SHOTS, SHOTS_PER_PATCH
    assert report["settings"]["max_iterations"] == max(
        MIN_SHOTS, SHOTS_PER_PATCH * report["counts"]["patches"])


def test_bad_output_path_is_one_line_and_exit_2(tmp_path, scenes_dir):
    cmd = [sys.executable, "-m", "daskrad", "run", str(scenes_dir / "cornell_box.obj"),
           "-o", str(tmp_path / "missing" / "x.exr"), "--workers", "0", "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert len(done.stderr.strip().splitlines()) == 1 and "Traceback" not in done.stderr
    assert not (tmp_path / "missing").exists()


def test_vertex_average_is_what_the_image_interpolates():
    # vertex radiance of a uniform polygon equals the element value: no darkening at edges
    scene = scene_from_arrays(np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]]),
                              np.array([[0, 1, 2, 3]]), [0], diffuse=[[0.5] * 3],
                              emission=[[1.0] * 3])
    h = build_hierarchy(scene, 0.5, 0.25)
    values = np.full((h.n_elements, 3), 2.0)
    np.testing.assert_allclose(vertex_average(h, values), 2.0, rtol=1e-12)


def test_default_camera_of_a_closed_room_stands_inside():
    # issue 16: a room's walls face inward; from the old default place outside the box every
    # pixel sees the back of a one-sided wall (black). An enclosure gets a camera inside, where
    # every pixel sees a wall from its lit side.
    from daskrad.scene import box_scene

    room = box_scene(size=(4.0, 3.0, 5.0), emission_per_face=1.0, subdivisions=2)
    solid = box_scene(size=(4.0, 3.0, 5.0), emission_per_face=1.0, inward=False)
    assert render.faces_inward(room) and not render.faces_inward(solid)
    h = build_hierarchy(room, 1.0, 1.0)
    tris, tri_verts, tri_elem = hierarchy_triangles(h)

    def image(camera):
        ctx = render.RenderContext(
            grid=build_grid(tris), tri_verts=tri_verts, tri_element=tri_elem,
            elem_normal=h.elem_normal, vertex_radiance=np.ones((len(h.vertices), 3)),
            camera=camera, spp=1)
        return render.render(ctx)

    outside = render.default_camera(room.bounds, 32, 32)
    inside = render.default_camera(room.bounds, 32, 32, inside=render.faces_inward(room))
    assert np.all(image(outside) == 0.0)
    np.testing.assert_allclose(image(inside), 1.0, rtol=1e-12)


@pytest.mark.parametrize("samples", [1, 2, 4, 8])
def test_shadow_rays_per_pixel_stay_near_their_budget_as_samples_grow(samples):
    # beyond LIGHT_SPP samples per pixel each sample casts fewer shadow rays per area light,
    # so a pixel casts about what it does at LIGHT_SPP: within the rounding of the side
    # (a factor ((n + ½) / n)² ≤ 2.25), or one ray per sample when even that is more
    budget = render.LIGHT_SPP * samples**2
    for spp in range(1, 257):
        n = render.shadow_side(samples, spp)
        assert n >= 1
        if spp <= render.LIGHT_SPP:
            assert n == samples
        elif n > 1:
            assert budget / 2.25 <= spp * n * n <= 2.25 * budget
        else:                       # one ray per sample: never fewer than the band allows
            assert spp >= budget / 2.25


def test_sample_positions_are_stratified_and_centred_for_any_count():
    # a square count is the grid of cell centres; any other count puts one sample in every
    # row and every column of an n × n grid, so the positions average to the pixel's centre
    # exactly (a grid trimmed to n left the last row short: the mean moved off the centre)
    for n in range(1, 257):
        off = render.sample_offsets(n)
        assert off.shape == (n, 2) and np.all((off > 0) & (off < 1))
        s = math.isqrt(n)
        if s * s == n:
            cells = np.round(off * s - 0.5).astype(int)
            assert len({tuple(c) for c in cells}) == n
        else:
            for axis in (0, 1):
                assert sorted(np.round(off[:, axis] * n - 0.5).astype(int)) == list(range(n))
        np.testing.assert_allclose(off.mean(axis=0), 0.5, atol=1e-12)


def test_the_shading_kernels_interpolate_as_gouraud_bit_for_bit(rng):
    # shade_hits and gouraud share one interpolation (one pass over the rays): both are held to
    # Gouraud's formula, summed in its order, and shade_hits to one-sidedness
    from daskrad.kernels.shade import gouraud, shade_hits

    n_tri, n_vert, n = 40, 30, 500
    values = rng.random((n_vert, 3))
    tri_verts = rng.integers(0, n_vert, (n_tri, 3)).astype(np.int32)
    tri_element = rng.integers(0, 7, n_tri).astype(np.int32)
    normals = rng.normal(size=(7, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    tri = rng.integers(-1, n_tri, n).astype(np.int32)           # -1: a miss
    u, v = rng.random(n), rng.random(n)
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hit = tri >= 0
    c = tri_verts[tri[hit]]
    uh, vh = u[hit, None], v[hit, None]
    expected = ((1.0 - uh - vh) * values[c[:, 0]] + uh * values[c[:, 1]]
                + vh * values[c[:, 2]])
    np.testing.assert_array_equal(gouraud(values, tri_verts, tri[hit], u[hit], v[hit]),
                                  expected)
    L, front = shade_hits(values, tri_verts, tri_element, normals, d, tri, u, v)
    facing = np.zeros(n, bool)
    facing[hit] = (d[hit] * normals[tri_element[tri[hit]]]).sum(axis=1) < 0.0
    assert 0 < facing.sum() < hit.sum()                 # some fronts, some backs, some misses
    np.testing.assert_array_equal(front, facing)
    np.testing.assert_array_equal(L[facing], expected[facing[hit]])
    assert not L[~facing].any()                         # misses and backs are black
