"""An independent reference: a diffuse path tracer over the same triangles and voxel grid.

It shares nothing with the radiosity solver but the geometry and the ray queries, so it checks
the whole chain — units (``Ke`` is radiance, exitance ``π·Ke``; images are radiance), one-sided
surfaces, the camera convention — the way a user's own path tracer would. Estimator: next-event
estimation at every diffuse vertex (area lights sampled uniformly by area, point and
directional lights by one shadow ray each), emission counted only where a camera ray hits an
emitter directly (so nothing is counted twice), cosine-weighted bounces, Russian roulette after
three bounces. Unbiased for one-sided Lambertian surfaces and emitters.
"""

# numba compiles the legacy np.random calls to a fast per-thread generator; it does not
# support passing a np.random.Generator through prange loops, hence:
# ruff: noqa: NPY002

from __future__ import annotations

import math

import numpy as np
from numba import prange

from daskrad.kernels._jit import jit, jit_parallel
from daskrad.kernels.grid import any_hit_one, closest_hit_one
from daskrad.kernels.tolerances import SHADOW_SHORTEN


@jit
def tangent_frame(n):
    """Two unit tangents completing ``n`` (Duff et al. 2017)."""
    sign = 1.0 if n[2] >= 0.0 else -1.0
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = np.array([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]])
    s = np.array([b, sign + n[1] * n[1] * a, -n[1]])
    return t, s


@jit
def _radiance(grid, tri_normal, tri_rho, tri_ke, light_tris, light_cdf, light_area,
              pl_pos, pl_int, dl_dir, dl_irr, o, d, offset, max_bounces):
    L = np.zeros(3)
    thr = np.ones(3)
    for bounce in range(max_bounces):
        t, tri, _, _ = closest_hit_one(grid, o, d, 0.0, np.inf)
        if tri < 0:
            break
        n = tri_normal[tri]
        if d[0] * n[0] + d[1] * n[1] + d[2] * n[2] >= 0.0:
            break  # the back of a one-sided surface: black
        x = o + t * d
        if bounce == 0:
            L += thr * tri_ke[tri]
        rho = tri_rho[tri]
        if rho.max() <= 0.0:
            break
        xo = x + offset * n
        f = thr * rho / math.pi
        # area lights: one point, uniform over the emitters' total area
        if light_area > 0.0:
            k = np.searchsorted(light_cdf, np.random.random() * light_area)
            k = min(k, len(light_tris) - 1)
            lt = light_tris[k]
            r1, r2 = np.random.random(), np.random.random()
            if r1 + r2 > 1.0:
                r1, r2 = 1.0 - r1, 1.0 - r2
            tv = grid.triangles[lt]
            y = tv[0] + r1 * (tv[1] - tv[0]) + r2 * (tv[2] - tv[0])
            w = y - xo
            dist2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
            dist = math.sqrt(dist2)
            w = w / dist
            nl = tri_normal[lt]
            cx = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
            cy = -(nl[0] * w[0] + nl[1] * w[1] + nl[2] * w[2])
            if cx > 0.0 and cy > 0.0:
                if not any_hit_one(grid, xo, w, 0.0, dist * (1.0 - SHADOW_SHORTEN) - offset):
                    L += f * tri_ke[lt] * (cx * cy / dist2 * light_area)
        for m in range(len(pl_pos)):
            w = pl_pos[m] - xo
            dist2 = w[0] * w[0] + w[1] * w[1] + w[2] * w[2]
            dist = math.sqrt(dist2)
            w = w / dist
            cx = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
            if cx > 0.0 and not any_hit_one(grid, xo, w, 0.0, dist):
                L += f * pl_int[m] * (cx / dist2)
        for m in range(len(dl_dir)):
            w = -dl_dir[m]
            cx = n[0] * w[0] + n[1] * w[1] + n[2] * w[2]
            if cx > 0.0 and not any_hit_one(grid, xo, w, 0.0, np.inf):
                L += f * dl_irr[m] * cx
        # cosine-weighted bounce: the estimator's cos/pdf = π cancels the BRDF's 1/π
        thr = thr * rho
        if bounce >= 3:
            q = min(0.95, thr.max())
            if np.random.random() >= q:
                break
            thr = thr / q
        r1, r2 = np.random.random(), np.random.random()
        phi = 2.0 * math.pi * r1
        sr = math.sqrt(r2)
        ta, tb = tangent_frame(n)
        d = (math.cos(phi) * sr) * ta + (math.sin(phi) * sr) * tb + math.sqrt(1.0 - r2) * n
        o = xo
    return L


@jit_parallel
def trace_image(grid, tri_normal, tri_rho, tri_ke, light_tris, light_cdf, light_area,
                pl_pos, pl_int, dl_dir, dl_irr, eye, forward, right, up, tan_half,
                width, height, spp, offset, max_bounces, seed):
    """``(height, width, 3) float64`` radiance, ``spp`` paths per pixel, box filter.

    Parameters
    ----------
    tri_normal : (T, 3) float64, unit, the lit side of each grid triangle
    tri_rho, tri_ke : (T, 3) float64, diffuse reflectance and emitted radiance
    light_tris : (L,) int64 emitting triangles; light_cdf : (L,) cumulative areas
    pl_pos, pl_int : (M, 3) point lights (W/sr); dl_dir, dl_irr : (K, 3) directional lights
    eye, forward, right, up : (3,) the camera frame of docs/design.md §6; tan_half = tan(fov/2)
    """
    img = np.zeros((height, width, 3))
    for row in prange(height):
        np.random.seed(seed + row)
        for col in range(width):
            acc = np.zeros(3)
            for _ in range(spp):
                x_ndc = 2.0 * (col + np.random.random()) / width - 1.0
                y_ndc = 1.0 - 2.0 * (row + np.random.random()) / height
                d = (forward + (x_ndc * tan_half) * right
                     + (y_ndc * tan_half * height / width) * up)
                d = d / math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
                acc += _radiance(grid, tri_normal, tri_rho, tri_ke, light_tris, light_cdf,
                                 light_area, pl_pos, pl_int, dl_dir, dl_irr, eye.copy(), d,
                                 offset, max_bounces)
            img[row, col] = acc / spp
    return img
