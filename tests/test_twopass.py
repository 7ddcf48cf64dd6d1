"""The two-pass pipeline end to end: scenes lit only by point/directional lights (issue 5)."""

from __future__ import annotations

import math

import numpy as np

from daskrad import render
from daskrad.io import read_exr
from daskrad.run import run, solve_scene
from daskrad.scene import Camera, scene_from_arrays
from daskrad.settings import Settings


def test_plane_under_a_directional_light_renders_rho_E_cos_over_pi():
    # One plane, no other surface: no indirect light, and a parallel light is uniform on it, so
    # every pixel that sees the plane shows exactly ρ E cosθ / π (round-off only).
    v = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]])
    d = np.array([0.3, 0.2, -1.0])
    d /= np.linalg.norm(d)
    cam = Camera(eye=np.array([0.0, 0.0, 1.0]), look_at=np.zeros(3), up=np.array([0.0, 1, 0]),
                 fov=30.0, width=24, height=24)
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3]]), [0], diffuse=[[0.6, 0.5, 0.4]],
                              emission=[[0, 0, 0]], camera=cam,
                              directional_lights=(d[None], [[2.0, 1.0, 3.0]]))
    settings = Settings(patch_size=1.0, element_size=0.25, spp=1)
    _, _, sol, light = solve_scene(scene, settings)
    image = render.render(render.context(scene, light, sol, settings, cam))
    expected = np.array([0.6, 0.5, 0.4]) * np.array([2.0, 1.0, 3.0]) * (-d[2]) / math.pi
    np.testing.assert_allclose(image, np.broadcast_to(expected, image.shape), rtol=1e-9)


def test_lit_room_renders_every_light(tmp_path, scenes_dir):
    # Point, directional and area light together: the image is lit (it was black before the
    # direct pass for point/directional lights), finite and the block casts a shadow.
    out = tmp_path / "room.exr"
    report = run(scenes_dir / "lit_room.obj", out,
                 Settings(width=64, height=64, spp=1, tolerance=1e-2), progress=False)
    image = read_exr(out)
    assert np.isfinite(image).all()
    assert report["counts"]["point_lights"] == 1 and report["counts"]["directional_lights"] == 1
    lum = image.mean(axis=2)
    assert np.percentile(lum, 50) > 0.1          # most of the view is lit
    assert (lum < 0.5 * np.median(lum)).sum() > 20  # shadows exist
