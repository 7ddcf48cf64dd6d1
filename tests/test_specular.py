"""Specular light in the per-pixel pass (issue 5, item 5): Phong highlights and mirrors."""

from __future__ import annotations

import math

import numpy as np

from daskrad import render
from daskrad.scene import Camera, scene_from_arrays
from tests.helpers import render_context

FLOOR = np.array([[-2.0, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]])
LIGHT = np.array([0.4, 1.5, 0.9])
I = 2.0
KS, NS = 0.6, 30.0


def _context(scene, **opts):
    return render_context(scene, **opts)[0]


def _render(ctx):
    cam = ctx.camera
    image = np.zeros((cam.height, cam.width, 3))
    total = {"perpixel": 0, "specular": 0, "mirror": 0}
    for rows, cols in render.tiles(cam.width, cam.height):
        image[rows, cols], stats = render.render_tile_stats(ctx, rows, cols)
        for k in total:
            total[k] += stats[k]
    return image, total


def _floor_hits(cam):
    o, d = render.primary_rays(cam, slice(0, cam.height), slice(0, cam.width), 1)
    p = o + (-o[:, 1] / d[:, 1])[:, None] * d
    inside = (np.abs(p[:, 0]) < 2) & (np.abs(p[:, 2]) < 2)
    return o, d, p, inside


def _camera(size=48):
    return Camera(eye=np.array([-0.6, 1.2, -1.4]), look_at=np.array([0.3, 0.0, 0.5]),
                  up=np.array([0.0, 1.0, 0.0]), fov=60.0, width=size, height=size)


def test_phong_highlight_of_a_point_light_on_a_plane_is_exact():
    # Kd = 0: the floor shows only the Phong lobe, Ks (Ns+2)/(2π) (r·v)^Ns · I cosθ / r², at
    # the exact hit point of every pixel (no interpolation): round-off only.
    cam = _camera()
    scene = scene_from_arrays(FLOOR, np.array([[0, 1, 2, 3]]), [0], diffuse=[[0.0] * 3],
                              emission=[[0.0] * 3], specular=[[KS] * 3], shininess=[NS],
                              camera=cam, point_lights=(LIGHT[None], [[I] * 3]))
    image, stats = _render(_context(scene))
    o, d, p, inside = _floor_hits(cam)
    lv = LIGHT - p
    r2 = (lv**2).sum(axis=1)
    ln = lv / np.sqrt(r2)[:, None]
    n = np.array([0.0, 1.0, 0.0])
    refl = 2.0 * ln[:, 1:2] * n - ln
    c = np.maximum(0.0, (refl * -d).sum(axis=1))
    exact = np.where(inside, KS * (NS + 2) / (2 * math.pi) * c**NS * I * ln[:, 1] / r2, 0.0)
    assert stats["specular"] == inside.sum() and stats["perpixel"] == 0
    np.testing.assert_allclose(image[..., 0].reshape(-1), exact, rtol=1e-9, atol=1e-14)
    # the peak: the brightest pixel is the analytic one, and it lies next to the mirror point
    # of the light seen from the eye (the exact peak moves off it by the cosθ/r² slope)
    peak = int(np.argmax(image[..., 0]))
    assert peak == int(np.argmax(exact))
    eye = cam.eye
    q = LIGHT * np.array([1, -1, 1])             # the light mirrored in the plane y = 0
    m = eye + (eye[1] / (eye[1] - q[1])) * (q - eye)
    pixel_size = 2 * np.linalg.norm(p[peak] - eye) * math.tan(math.radians(cam.fov) / 2) / 48
    assert np.linalg.norm(p[peak] - m) < 4 * pixel_size
    assert image[..., 0].max() > 10 * np.median(image[..., 0][image[..., 0] > 0])


def test_mirror_floor_reflects_the_emitter_exactly():
    # A mirror floor (illum 3, Ks 0.7, Kd 0) under a down-facing emitter (Ke 5): a pixel of the
    # floor shows Ks · Ke where its mirrored ray meets the emitter, 0 elsewhere (the emitter's
    # back is black, nothing else is in the scene). Away from the emitter's outline (a pixel)
    # that is exact to round-off; with mirror_depth 0 the reflection is gone.
    cam = _camera()
    v = np.concatenate([FLOOR, [[-0.5, 1, -0.3], [0.5, 1, -0.3], [0.5, 1, 0.7],
                                [-0.5, 1, 0.7]]])
    scene = scene_from_arrays(v, np.array([[0, 1, 2, 3], [4, 5, 6, 7]]), [0, 1],
                              diffuse=[[0.0] * 3, [0.0] * 3],
                              emission=[[0.0] * 3, [5.0] * 3], specular=[[0.7] * 3, [0.0] * 3],
                              shininess=[0.0, 0.0], mirror=[True, False], camera=cam)
    image, stats = _render(_context(scene, mirror_depth=2))
    o, d, p, inside = _floor_hits(cam)
    tb = (1.0 - o[:, 1]) / d[:, 1]
    b = o + tb[:, None] * d
    in_sq = (np.abs(b[:, 0]) < 0.5) & (b[:, 2] > -0.3) & (b[:, 2] < 0.7)
    blocked = in_sq & (tb > 0) & (tb < -o[:, 1] / d[:, 1])   # the emitter's back in front
    dm = d * np.array([1, -1, 1])
    s = (1.0 - p[:, 1]) / dm[:, 1]
    c = p + s[:, None] * dm
    sees = (np.abs(c[:, 0]) < 0.5) & (c[:, 2] > -0.3) & (c[:, 2] < 0.7)
    mirror_px = inside & ~blocked
    exact = np.where(mirror_px & sees, 0.7 * 5.0, 0.0).reshape(48, 48)
    cls = np.where(mirror_px, sees.astype(int), 2 + blocked).reshape(48, 48)
    edge = np.zeros(cls.shape, bool)
    for ax in (0, 1):
        diff = np.diff(cls, axis=ax) != 0
        sl = [slice(None)] * 2
        sl[ax] = slice(1, None)
        edge[tuple(sl)] |= diff
        sl[ax] = slice(None, -1)
        edge[tuple(sl)] |= diff
    ok = np.isclose(image[..., 0], exact, rtol=1e-12, atol=1e-12) | edge
    assert ok.all()
    assert (exact > 0).sum() > 30 and stats["mirror"] == mirror_px.sum()
    flat, stats0 = _render(_context(scene, mirror_depth=0))
    assert stats0["mirror"] == 0 and not (flat[exact > 0] > 0).any()


def test_scene_without_specular_materials_skips_the_work_bit_for_bit():
    # Two floors side by side, Ks only on the right one: every pixel of the left floor is bit
    # for bit what the same scene without any Ks gives, and with no Ks at all the plain
    # Gouraud path runs (no specular sample, no mirror ray).
    cam = Camera(eye=np.array([0.0, 3.0, 0.01]), look_at=np.zeros(3),
                 up=np.array([0.0, 0.0, 1.0]), fov=60.0, width=32, height=32)
    v = np.array([[-2.0, 0, -2], [-2, 0, 2], [0, 0, 2], [0, 0, -2], [2, 0, 2], [2, 0, -2]])
    polys = np.array([[0, 1, 2, 3], [3, 2, 4, 5]])

    def scene(ks):
        return scene_from_arrays(v, polys, [0, 1], diffuse=[[0.5] * 3, [0.4] * 3],
                                 emission=[[0.0] * 3] * 2, specular=[[0.0] * 3, [ks] * 3],
                                 shininess=[1.0, 10.0], camera=cam,
                                 point_lights=(LIGHT[None], [[I] * 3]))

    opts = {"per_pixel": False}
    plain_ctx = _context(scene(0.0), **opts)
    assert not plain_ctx.extras and plain_ctx.lights is None
    plain, stats = _render(plain_ctx)
    assert stats == {"perpixel": 0, "specular": 0, "mirror": 0}
    assert np.array_equal(plain, render.render(plain_ctx))
    shiny, stats1 = _render(_context(scene(0.5), **opts))
    assert stats1["specular"] > 0
    # image x grows along right = forward × up = (0,-1,0) × (0,0,1) = -x: the left half of
    # the image is the x > 0 floor (the shiny one)
    assert np.array_equal(shiny[:, 17:], plain[:, 17:])
    assert (shiny[:, :15] > plain[:, :15]).any()
