"""Two-pass lighting on the Cornell box: image error against run time (issue 5, item 7).

The box is lit by its own area light (the emitting ceiling quad), gathered at vertices by the
direct pass. Four configurations cross adaptive subdivision (``subdivide`` 0.5 vs off) with the
per-pixel pass (eq. 9, ``rdiff`` 0.05 vs off), plus an ``rdiff`` sweep; each is measured against
two references at 128 × 128:

- a converged radiosity solution of our own: elements of 10 mm (the default is 30 mm),
  no subdivision (the per-pixel pass makes its direct light exact), tolerance 1e-4, the
  per-pixel pass on every element whose direct light varies at all (``rdiff`` 0.002),
  16 samples per pixel, 8 × 8 shadow rays per area light; cached in
  ``benchmarks/results/twopass_converged_128.exr``;
- the path-traced reference of :mod:`benchmarks.bench_reference` (its noise is printed).

The per-pixel pass does not change the solve, so each subdivision setting is solved once and
rendered with and without it; a configuration's seconds are its solve (steps 1–3) plus its
render. Errors are relative RMS over the image (RMS of the difference / RMS of the reference).
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_reference import SCENE, SIZE, errors, reference
from daskrad import render
from daskrad.io import read_exr, write_exr, write_png
from daskrad.run import solve_scene
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SPP = 16

#: (name, subdivide, per_pixel rdiff or None)
CONFIGS = [
    ("plain Gouraud", 0.0, None),
    ("subdivision", 0.5, None),
    ("per-pixel", 0.0, 0.05),
    ("subdivision + per-pixel", 0.5, 0.05),
    ("per-pixel rdiff 0.2", 0.0, 0.2),
    ("subdiv + per-pixel rdiff 0.2", 0.5, 0.2),
    ("subdiv + per-pixel rdiff 0.1", 0.5, 0.1),
    ("subdiv + per-pixel rdiff 0.01", 0.5, 0.01),
]


def _solve(scene, settings):
    t = time.perf_counter()
    solved = solve_scene(scene, settings)
    return solved, time.perf_counter() - t


def _render(scene, settings, solved):
    t = time.perf_counter()
    ctx = render.context(scene, solved.light, solved.solution, settings,
                         render.camera(scene, settings))
    image = np.zeros((SIZE, SIZE, 3))
    count = 0
    for rows, cols in render.tiles(SIZE, SIZE):
        image[rows, cols], stats = render.render_tile_stats(ctx, rows, cols)
        count += stats["perpixel"]
    pp = int(ctx.elem_perpixel.sum()) if ctx.elem_perpixel is not None else 0
    return image, time.perf_counter() - t, pp, count


def converged(scene) -> tuple[np.ndarray, float]:
    """Our own converged radiosity image (cached) and the seconds it took (0 when cached)."""
    path = RESULTS / f"twopass_converged_{SIZE}.exr"
    if path.exists():
        return read_exr(path).astype(np.float64), 0.0
    settings = Settings(width=SIZE, height=SIZE, spp=SPP, edge_spp=0, element_size=10.0,
                        patch_size=60.0,
                        tolerance=1e-4, max_iterations=20000, subdivide=0.0, rdiff=0.002,
                        area_samples=8)
    solved, ts = _solve(scene, settings)
    image, tr, _, _ = _render(scene, settings, solved)
    RESULTS.mkdir(exist_ok=True)
    write_exr(path, image)
    write_png(path.with_suffix(".png"), image)
    return image, ts + tr


def _surface_mask(*images: np.ndarray) -> np.ndarray:
    """``(H, W) bool``: pixels off the light and off its outline. The light's radiance (17)
    is 30 times a lit wall's, so a pixel cut by its outline carries an error of up to
    17/spp from where the fixed stratified samples fall against the path tracer's random
    ones: anti-aliasing, not lighting, and it would swamp the surfaces' error."""
    bright = np.zeros(images[0].shape[:2], bool)
    for im in images:
        bright |= im.max(axis=2) > 2.0
    grown = bright.copy()
    grown[1:] |= bright[:-1]
    grown[:-1] |= bright[1:]
    grown[:, 1:] |= grown[:, :-1].copy()
    grown[:, :-1] |= grown[:, 1:].copy()
    return ~grown


def _err(img: np.ndarray, ref: np.ndarray, mask: np.ndarray) -> dict:
    """Relative RMS over the surfaces, and the 99th percentile of the per-pixel error in units
    of the white level (the 90th percentile of the reference): where shadows blur, it shows."""
    d = np.abs(img - ref)[mask].max(axis=1)
    white = float(np.percentile(ref[mask].max(axis=1), 90))
    return {"relative_rms": float(np.sqrt(np.mean((img - ref)[mask] ** 2))
                                  / np.sqrt(np.mean(ref[mask] ** 2))),
            "p99_over_white": float(np.percentile(d, 99) / white)}


def main() -> dict:
    scene = load_scene(SCENE)
    pt, noise = reference()
    own, own_seconds = converged(scene)
    mask = _surface_mask(own, pt)
    # warm-up: compile (or load) every kernel once, so no configuration's time includes it
    warm = Settings(width=SIZE, height=SIZE, spp=1, element_size=150.0, rdiff=0.01)
    _render(scene, warm, _solve(scene, warm)[0])
    rows = []
    solved = {}
    for name, subdivide, rdiff in CONFIGS:
        settings = Settings(width=SIZE, height=SIZE, spp=SPP, edge_spp=0, subdivide=subdivide,
                            per_pixel=rdiff is not None, rdiff=rdiff or 0.05)
        if subdivide not in solved:
            solved[subdivide] = _solve(scene, settings)
        s, solve_seconds = solved[subdivide]
        image, render_seconds, pp, samples = _render(scene, settings, s)
        rows.append({
            "config": name, "subdivide": subdivide, "rdiff": rdiff,
            "elements": s[0].n_elements, "perpixel_elements": pp,
            "perpixel_samples": samples, "solve_seconds": solve_seconds,
            "render_seconds": render_seconds, "seconds": solve_seconds + render_seconds,
            "vs_converged": _err(image, own, mask), "vs_pathtraced": _err(image, pt, mask),
            "vs_pathtraced_whole_image": errors(image, pt)["relative_rms"],
            "mean_error_vs_pathtraced": errors(image, pt)["mean_relative_error_rgb"],
        })
    own_vs_pt = _err(own, pt, mask)
    print(f"Cornell box {SIZE}x{SIZE}, {SPP} samples/pixel, errors over the {mask.sum()} pixels "
          f"off the light; path-traced reference noise (whole image) {noise:.4f}; converged "
          f"radiosity vs path-traced: rel RMS {own_vs_pt['relative_rms']:.4f}, "
          f"p99 {own_vs_pt['p99_over_white']:.4f}")
    print(f"{'config':<31}{'elements':>9}{'pp elem':>8}{'solve s':>8}{'render s':>9}"
          f"{'total s':>8}{'conv RMS':>9}{'conv p99':>9}{'PT RMS':>8}{'PT p99':>8}")
    for r in rows:
        c, p = r["vs_converged"], r["vs_pathtraced"]
        print(f"{r['config']:<31}{r['elements']:>9}{r['perpixel_elements']:>8}"
              f"{r['solve_seconds']:>8.2f}{r['render_seconds']:>9.2f}{r['seconds']:>8.2f}"
              f"{c['relative_rms']:>9.4f}{c['p99_over_white']:>9.4f}"
              f"{p['relative_rms']:>8.4f}{p['p99_over_white']:>8.4f}")
    result = {"size": SIZE, "spp": SPP, "pathtraced_noise": noise,
              "converged_vs_pathtraced": own_vs_pt, "converged_seconds": own_seconds,
              "configs": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "twopass.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
