"""Hard lights against the path tracer: sun, point light, a light outside a closed room (issue 14).

Scenes (written into a temporary directory from ``scenes/cornell_box.obj`` by
``daskrad/testing/shadows.py``):

(a) ``open box, sun``: the Cornell box without its ceiling and light, a directional light of
    irradiance 3 W/m² travelling along normalize(0.3, −1, 0.25);
(b) ``closed box, point``: the Cornell box with its light quad made ceiling, a point light inside;
(c) ``lit room``: ``scenes/lit_room.obj`` (point, sun and an emitting panel), if present;
(d) ``light outside``: the closed box with the point light above its ceiling: the room must be
    black and the run must warn that no surface receives light.

Each of (a)–(c) is rendered by daskrad (default settings, ``DASKRAD_SPP`` stratified samples per
pixel so that silhouettes are resolved as finely as the path tracer's jittered ones) and by the
path tracer of :mod:`daskrad.reference` (``SPP`` paths per pixel, cached in
``benchmarks/results/shadows_<scene>_<size>.exr`` with one half-image to estimate its own noise).
Errors are RMSEs (radiance) over pixel classes found from 4 × 4 primary rays per pixel:

- ``image``: every pixel;
- ``off outline``: pixels whose sub-samples do not mix an emitter with anything else (the
  outline of a visible area light differs between two renderers by their pixel sampling alone);
- ``contact``: floor pixels (all sub-samples on the floor) within ``CONTACT_WIDTH`` of the foot of
  a block (a face standing on the floor, away from the walls);
- ``shadow edge``: pixels whose sub-samples disagree on the visibility of a point or
  directional light, and their 8 neighbours.

``rel`` columns divide by the reference image's mean radiance (all channels). ``row`` is the
worst relative error of the mean radiance over one contact row: the contact pixels of one image
row along one foot edge (5 pixels or more), the measure of issue 14 ("0.42 against 0.61 along a
row of 13 pixels").
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_reference import cached_path_trace
from daskrad import render, tolerances
from daskrad.io import read_exr
from daskrad.kernels.grid import any_hit, build_grid, closest_hit
from daskrad.reference import scene_triangles
from daskrad.run import run
from daskrad.scene import load_scene
from daskrad.settings import Settings

sys.path.insert(0, str(Path(__file__).parent.parent))
from daskrad.testing import shadows as shadow_scenes  # noqa: E402

RESULTS = Path(__file__).parent / "results"
SIZE = 128
SPP = 2048
DASKRAD_SPP = 64
#: Half-width of the contact band along a block's foot, as a fraction of the scene diagonal
#: (Cornell box: 29 mm; the floor is seen at a grazing angle, so this is about two pixels).
CONTACT_WIDTH = 0.03
#: ... and at most this many pixels from a pixel of the block in the image.
CONTACT_PIXELS = 2
#: Fewest pixels of one image row along one foot edge that make a contact row.
ROW_PIXELS = 5


def _scenes(tmp: Path) -> list[tuple[str, Path]]:
    out = [("open box, sun", shadow_scenes.open_box_sun(tmp)),
           ("closed box, point", shadow_scenes.closed_box_point(tmp))]
    room = shadow_scenes.SCENES / "lit_room.obj"
    if room.exists():
        out.append(("lit room", room))
    return out


def reference(name: str, path: Path) -> tuple[np.ndarray, float]:
    """The cached path-traced image of ``path`` and its RMS noise (radiance, from two halves)."""
    ref, relative = cached_path_trace(path, "shadows_" + name.replace(",", "").replace(" ", "_"),
                                      SPP, SIZE)
    return ref, relative * float(np.sqrt(np.mean(ref**2)))


def _dilate(mask: np.ndarray, r: int) -> np.ndarray:
    """``mask`` grown by ``r`` pixels (a square neighbourhood)."""
    h, w = mask.shape
    pad = np.pad(mask, r)
    out = np.zeros_like(mask)
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            out |= pad[dy:dy + h, dx:dx + w]
    return out


def _feet(scene) -> tuple[np.ndarray, np.ndarray]:
    """``(S, 2, 3)`` and their polygons ``(S,)``: the bottom edges of faces standing on the
    floor away from the walls (vertical faces with an edge at the scene's lowest ``y``, every
    corner more than 5 % of the diagonal inside the bounding box in ``x`` and ``z``)."""
    lo, hi = scene.bounds
    margin = 0.05 * scene.diagonal
    segs, owner = [], []
    for i, poly in enumerate(scene.polygons):
        ids = poly[poly >= 0]
        p = scene.vertices[ids]
        n = np.cross(p[1] - p[0], p[2] - p[0])
        if abs(n[1]) > 0.1 * np.linalg.norm(n):
            continue
        inside = ((p[:, [0, 2]] > lo[[0, 2]] + margin) & (p[:, [0, 2]] < hi[[0, 2]] - margin))
        if not inside.all():
            continue
        for a, b in zip(range(len(ids)), np.roll(range(len(ids)), -1), strict=True):
            if p[a, 1] == lo[1] and p[b, 1] == lo[1]:
                segs.append([p[a], p[b]])
                owner.append(i)
    return np.array(segs).reshape(-1, 2, 3), np.array(owner, int)


def classes(scene, camera) -> dict:
    """Pixel classes ``(H, W) bool`` (and ``contact_edge (H, W) int``, −1 off the contact band)
    from 4 × 4 primary rays per pixel."""
    tris, owner = scene_triangles(scene)
    grid = build_grid(tris)
    k = 16
    o, d = render.primary_rays(camera, slice(0, camera.height), slice(0, camera.width), k)
    n = len(o)
    t, tri, _, _ = closest_hit(grid, o, d, np.zeros(n), np.full(n, np.inf))
    shape = (camera.height, camera.width, k)
    poly = np.where(tri >= 0, owner[np.maximum(tri, 0)], -1)
    one_poly = (poly.reshape(camera.height, camera.width, k)
                == poly.reshape(camera.height, camera.width, k)[..., :1]).all(axis=2)
    emit = np.where(poly >= 0, scene.emitting[np.maximum(poly, 0)], False).reshape(shape)
    # an emitter's outline: pixels within one pixel of its boundary (a jittered path tracer
    # catches an edge between the fixed sub-samples, whose pixels then look unmixed here)
    e_any, e_all = emit.any(axis=2), emit.all(axis=2)
    outline = _dilate(e_any & ~e_all, 1) | (_dilate(e_any, 1) & ~e_all) | (
        e_all & _dilate(~e_all, 1))
    p = o + np.where(tri >= 0, t, 0.0)[:, None] * d
    e1 = tris[:, 1] - tris[:, 0]
    e2 = tris[:, 2] - tris[:, 0]
    tn = np.cross(e1, e2)
    tn /= np.linalg.norm(tn, axis=1, keepdims=True)
    nrm = tn[np.maximum(tri, 0)]
    front = (tri >= 0) & (np.einsum("ij,ij->i", nrm, d) < 0)
    # hard-light visibility at every sub-sample hit: 1 lit, 0 shadowed, -1 not facing / no hit
    off = tolerances.RAY_OFFSET * scene.diagonal * 10
    edge = np.zeros(shape[:2], bool)
    lights = [(pos, None) for pos in np.asarray(scene.point_lights.position).reshape(-1, 3)]
    lights += [(None, dd) for dd in np.asarray(scene.directional_lights.direction).reshape(-1, 3)]
    for pos, dd in lights:
        if pos is not None:
            w = pos - p
            dist = np.linalg.norm(w, axis=1)
            w = w / np.where(dist > 0, dist, 1.0)[:, None]
            tmax = dist - off
        else:
            w = np.broadcast_to(-dd / np.linalg.norm(dd), p.shape).copy()
            tmax = np.full(n, np.inf)
        cos = np.einsum("ij,ij->i", nrm, w)
        ok = front & (cos > 0)
        vis = np.full(n, -1)
        idx = np.flatnonzero(ok)
        blocked = any_hit(grid, np.ascontiguousarray(p[idx] + off * nrm[idx]),
                          np.ascontiguousarray(w[idx]), np.full(len(idx), off), tmax[idx])
        vis[idx] = np.where(blocked, 0, 1)
        vis = vis.reshape(shape)
        # a shadow boundary across one surface (not a silhouette: one polygon under the pixel)
        edge |= (vis == 1).any(axis=2) & (vis == 0).any(axis=2) & one_poly
    # and the 8 neighbours of such a pixel: their light is still set by where the edge lies
    edge = _dilate(edge, 1)
    # contact band: floor pixels (every sub-sample on the floor) next to a block's pixels in
    # the image, their centre within CONTACT_WIDTH of a foot edge
    lo = scene.bounds[0]
    on_floor = (front & (nrm[:, 1] > 0.99) & (np.abs(p[:, 1] - lo[1]) < 1e-6 * scene.diagonal))
    floor_px = on_floor.reshape(shape).all(axis=2)
    segs, seg_poly = _feet(scene)
    contact_edge = np.full(shape[:2], -1)
    if len(segs):
        block = _dilate(np.isin(poly, seg_poly).reshape(shape).any(axis=2), CONTACT_PIXELS)
        c = p.reshape(shape + (3,)).mean(axis=2)[..., [0, 2]]
        a, b = segs[:, 0][:, [0, 2]], segs[:, 1][:, [0, 2]]
        ab = b - a
        s = np.clip(np.einsum("hwsk,sk->hws", c[:, :, None] - a, ab)
                    / np.einsum("sk,sk->s", ab, ab), 0.0, 1.0)
        q = a + s[..., None] * ab
        dist = np.linalg.norm(c[:, :, None] - q, axis=-1)
        near = dist.argmin(axis=2)
        band = floor_px & block & (dist.min(axis=2) < CONTACT_WIDTH * scene.diagonal)
        contact_edge = np.where(band, near, -1)
    return {"outline": outline, "shadow_edge": edge, "contact_edge": contact_edge}


def errors(img: np.ndarray, ref: np.ndarray, cls: dict) -> dict:
    """RMSE (radiance, all channels) over the pixel classes, relative to the reference's mean,
    and the worst contact row."""
    mean = float(ref.mean())
    sq = ((img - ref) ** 2).mean(axis=2)

    def rmse(mask):
        return float(np.sqrt(sq[mask].mean())) if mask.any() else float("nan")

    contact = cls["contact_edge"] >= 0
    masks = {"image": np.ones(sq.shape, bool), "off_outline": ~cls["outline"],
             "contact": contact, "shadow_edge": cls["shadow_edge"] & ~cls["outline"]}
    out = {"mean": mean}
    for k, m in masks.items():
        out[k] = rmse(m)
        out[k + "_rel"] = out[k] / mean
        out[k + "_pixels"] = int(m.sum())
    worst, worst_at = 0.0, None
    for row in range(sq.shape[0]):
        for e in np.unique(cls["contact_edge"][row]):
            if e < 0:
                continue
            cols = np.flatnonzero(cls["contact_edge"][row] == e)
            if len(cols) < ROW_PIXELS:
                continue
            a, b = img[row, cols].mean(), ref[row, cols].mean()
            if abs(a / b - 1.0) > abs(worst):
                worst, worst_at = a / b - 1.0, [row, int(cols[0]), int(cols[-1]), a, b]
    out["worst_row"] = worst
    out["worst_row_at"] = worst_at
    return out


def _render(path: Path, out: Path) -> tuple[np.ndarray, dict, float]:
    t = time.perf_counter()
    report = run(path, out, Settings(width=SIZE, height=SIZE, spp=DASKRAD_SPP, workers=0),
                 progress=False)
    seconds = time.perf_counter() - t
    return read_exr(out).astype(np.float64), report, seconds


def main() -> dict:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for name, path in _scenes(tmp):
            ref, noise = reference(name, path)
            scene = load_scene(path)
            cam = dataclasses.replace(scene.camera, width=SIZE, height=SIZE)
            img, report, seconds = _render(path, tmp / "out.exr")
            r = {"scene": name, "seconds": seconds, "reference_noise": noise,
                 "perpixel_elements": report["counts"]["perpixel_elements"],
                 "elements": report["counts"]["elements"],
                 **errors(img, ref, classes(scene, cam))}
            rows.append(r)
        outside = shadow_scenes.closed_box_outside(tmp)
        img, report, _ = _render(outside, tmp / "outside.exr")
        dark = {"scene": "light outside", "max_radiance": float(img.max()),
                "warnings": report["warnings"]}
        shutil.rmtree(tmp / "out.zarr", ignore_errors=True)
    print(f"path tracer: {SPP} paths/pixel; daskrad: {DASKRAD_SPP} samples/pixel; {SIZE}x{SIZE}; "
          "RMSE in radiance, rel = RMSE / reference mean")
    print(f"{'scene':<19}{'mean':>8}{'noise':>8}{'image':>8}{'rel':>7}{'off outl':>9}{'rel':>7}"
          f"{'contact':>9}{'rel':>7}{'sh. edge':>9}{'rel':>7}{'worst row':>10}{'s':>7}")
    for r in rows:
        print(f"{r['scene']:<19}{r['mean']:>8.4f}{r['reference_noise']:>8.4f}"
              f"{r['image']:>8.4f}{r['image_rel']:>7.1%}{r['off_outline']:>9.4f}"
              f"{r['off_outline_rel']:>7.1%}{r['contact']:>9.4f}{r['contact_rel']:>7.1%}"
              f"{r['shadow_edge']:>9.4f}{r['shadow_edge_rel']:>7.1%}{r['worst_row']:>+10.1%}"
              f"{r['seconds']:>7.1f}")
    print(f"{'light outside':<19} max radiance {dark['max_radiance']:.3g}; warning: "
          f"{'yes' if dark['warnings'] else 'NO'}")
    result = {"size": SIZE, "spp": SPP, "daskrad_spp": DASKRAD_SPP,
              "contact_width": CONTACT_WIDTH, "scenes": rows, "light_outside": dark}
    (RESULTS / "shadows.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
