"""The path-traced reference must itself be right before anything is measured against it."""

from __future__ import annotations

import math

import numpy as np

from daskrad.reference import path_trace
from daskrad.scene import Camera, scene_from_arrays


def _plane(**lights):
    return scene_from_arrays(
        np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]), np.array([[0, 1, 2, 3]]),
        [0], diffuse=[[0.5, 0.25, 0.125]], emission=[[0.0, 0, 0]], **lights)


CAM = Camera(eye=np.array([0.0, 0, 3]), look_at=np.zeros(3), up=np.array([0.0, 1, 0]),
             fov=0.5, width=4, height=4)


def test_point_light_over_a_plane_gives_rho_I_over_pi_r2():
    # A single plane sees nothing else, so L = ρ/π · I cosθ / r² exactly. The 0.5° view from
    # 3 away spans points up to ρ = 3·tan(0.25°)·√2 = 0.0185 from the centre, where
    # cosθ/r² = (1 + ρ²)^(-3/2) ≥ 1 − 1.5·ρ² = 1 − 5.2e-4.
    scene = _plane(point_lights=([[0.0, 0, 1]], [[2.0, 2.0, 2.0]]))
    img = path_trace(scene, CAM, spp=4)
    np.testing.assert_allclose(img, np.broadcast_to(np.array([0.5, 0.25, 0.125]) * 2 / math.pi,
                                                    img.shape), rtol=5.2e-4)


def test_area_light_converges_to_the_disc_formula_and_back_faces_are_black():
    # A small square emitter (Ke = 1, facing down) 1 above the plane, beside the camera's line
    # of sight: the irradiance at the centre is π Ke F with F Lambert's point-to-square value.
    h, c = 0.1, 0.5
    verts = np.array([[-1.0, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0],
                      [c - h, -h, 1], [c - h, h, 1], [c + h, h, 1], [c + h, -h, 1]])
    scene = scene_from_arrays(verts, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                              diffuse=[[0.5] * 3, [0.0] * 3], emission=[[0.0] * 3, [1.0] * 3])
    from daskrad.formfactor import analytic_point_to_elements

    F = analytic_point_to_elements(np.zeros(3), np.array([0.0, 0, 1]), verts,
                                   np.array([[4, 5, 6, 7]], np.int32))[0]
    img = path_trace(scene, CAM, spp=4096)
    # 4096 light samples per pixel × 16 pixels; the estimator's relative spread for a square
    # seen from 1 away is a few per cent per sample, so the mean is good to ~1e-3
    np.testing.assert_allclose(img.mean(axis=(0, 1)), 0.5 / math.pi * math.pi * F, rtol=5e-3)
    below = Camera(eye=np.array([0.0, 0, -3]), look_at=np.zeros(3), up=np.array([0.0, 1, 0]),
                   fov=0.5, width=4, height=4)
    assert np.all(path_trace(scene, below, spp=4) == 0.0)


def test_directional_light_gives_rho_E_cos_over_pi_and_nothing_from_behind():
    # A sun of irradiance E (on a surface facing it) travelling along d lights the plane with
    # E cosθ, cosθ = −d·n, the same at every point: L = ρ/π · E cosθ exactly, one shadow ray.
    d = np.array([0.6, 0.0, -0.8])
    scene = _plane(directional_lights=([d], [[3.0, 3.0, 3.0]]))
    img = path_trace(scene, CAM, spp=4)
    np.testing.assert_allclose(img, np.broadcast_to(np.array([0.5, 0.25, 0.125]) * 3 * 0.8
                                                    / math.pi, img.shape), rtol=1e-12)
    # a sun below the horizon (or behind the one-sided plane) gives nothing
    assert np.all(path_trace(_plane(directional_lights=([-d], [[3.0] * 3])), CAM, spp=2) == 0)


def test_oblique_point_light_gives_I_cos_over_r2():
    # The light 1 up and 2 to the side: at the centre cosθ = 1/√5, r² = 5. The 0.5° view
    # spans ρ ≤ 0.0185 around the centre, where I cosθ/r² varies by at most
    # |∇ log(cosθ/r²)| ρ = (3·2/5 + 0) · 0.0185 ≈ 2.3 % to first order: compare the mean.
    scene = _plane(point_lights=([[2.0, 0, 1]], [[2.0, 2.0, 2.0]]))
    img = path_trace(scene, CAM, spp=4)
    expect = np.array([0.5, 0.25, 0.125]) / math.pi * 2.0 * (1 / math.sqrt(5)) / 5
    # the pixel grid is symmetric about the centre: the first-order term cancels in the mean,
    # the second-order one is below (0.0185)² · 5 ≈ 2e-3
    np.testing.assert_allclose(img.mean(axis=(0, 1)), expect, rtol=2e-3)
    assert np.all(img[..., 0] > 0)
