"""Reference images by path tracing, to measure daskrad against something independent.

``path_trace(scene, camera, spp)`` renders the same scene, with the same camera convention and
units, by Monte Carlo (:mod:`daskrad.kernels.pathtrace`). Benchmarks compare the radiosity image
with it; a converged path-traced image is what daskrad is ultimately judged against.
"""

from __future__ import annotations

import math

import numpy as np

from daskrad import render, tolerances
from daskrad.kernels.grid import build_grid
from daskrad.kernels.pathtrace import trace_image
from daskrad.scene.corners import split_quads
from daskrad.scene.types import Camera, Scene


def scene_triangles(scene: Scene):
    """The scene's polygons as triangles: ``(T, 3, 3)`` corners and ``(T,)`` polygon ids."""
    tris, owner = split_quads(scene.polygons)
    return scene.vertices[tris], owner


def path_trace(scene: Scene, camera: Camera | None = None, spp: int = 64,
               max_bounces: int = 64, seed: int = 1) -> np.ndarray:
    """``(H, W, 3) float64`` radiance of ``scene`` seen by ``camera`` (default: the scene's)."""
    camera = camera or scene.camera or render.default_camera(scene.bounds)
    tris, owner = scene_triangles(scene)
    grid = build_grid(tris)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    cross = np.cross(e1, e2)
    area = 0.5 * np.linalg.norm(cross, axis=1)
    # the polygon's normal (not the triangle's) so a split quad is one-sided the same way
    poly_normal = np.zeros((len(scene.polygons), 3))
    np.add.at(poly_normal, owner, cross)
    poly_normal /= np.linalg.norm(poly_normal, axis=1, keepdims=True)
    mat = scene.polygon_material[owner]
    ke = scene.materials.emission[mat].astype(np.float64)
    rho = scene.materials.diffuse[mat].astype(np.float64)
    lights = np.flatnonzero((ke > 0).any(axis=1) & (area > 0))
    cdf = np.cumsum(area[lights])
    forward, right, up = render.camera_frame(camera)
    return trace_image(
        grid, np.ascontiguousarray(poly_normal[owner]), rho, ke, lights.astype(np.int64),
        cdf, float(cdf[-1]) if len(cdf) else 0.0,
        np.asarray(scene.point_lights.position, float).reshape(-1, 3),
        np.asarray(scene.point_lights.intensity, float).reshape(-1, 3),
        np.asarray(scene.directional_lights.direction, float).reshape(-1, 3),
        np.asarray(scene.directional_lights.irradiance, float).reshape(-1, 3),
        np.asarray(camera.eye, float), forward, right, up,
        math.tan(math.radians(camera.fov) / 2.0), int(camera.width), int(camera.height),
        int(spp), tolerances.RAY_OFFSET * scene.diagonal, int(max_bounces), int(seed))
