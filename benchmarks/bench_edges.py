"""Edge pixels that take the area lights their neighbourhood agrees on (issue 12, items 3 and 5).

A pixel whose base samples differ by more than ``edge_step`` is sampled again at ``edge_spp``
(64) samples. In RenderPark's office a fifth of the pixels are edges, and their samples' shadow
rays were half of the tiles' time. With :data:`daskrad.render.EDGE_VERDICTS` an edge sample
takes an area light as wholly visible or wholly hidden, without shadow rays, where every base
sample of its pixel lies on the same element and found the light so, and so did every base
sample of the 8 neighbouring pixels on that element
(:func:`daskrad.kernels.shade.pixel_modes`).

For each scene (the bundled Cornell box and lit room, solved in-process with the defaults;
``--store PATH`` adds the view of a finished run's store, e.g. RenderPark's office), the view's
tiles are rendered on every core with the verdicts off and on, alternated ``--repeat`` times
(medians, wall seconds). Verdicts are not exact, so both images are compared with a reference
of the same tiles at 4× the shadow rays without verdicts (rendered once): relative RMS error,
pixels more than 5 % off; and with each other (pixels changed, the largest change relative
to the pixel).

``python -m benchmarks.bench_edges [--store PATH] [--size W H] [--repeat N]``; writes
``benchmarks/results/edges.json``.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.distributed.store import Result
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"


def solved_view(path: Path, size: tuple[int, int], ex: InProcess) -> render.RenderContext:
    """The view of ``path`` solved with the defaults at ``size`` pixels, its gather applied."""
    settings = Settings(workers=0, width=size[0], height=size[1])
    scene = load_scene(path)
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    sol = solve.radiosity(light, settings, ex)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    return render.for_view(ctx, ex)


def _tiles(ctx: render.RenderContext, ex: InProcess, verdicts: bool):
    """``(image, stats, seconds)`` of the view's tiles with the verdicts on or off."""
    keep = render.EDGE_VERDICTS
    render.EDGE_VERDICTS = verdicts
    try:
        t = time.perf_counter()
        image, stats = render.pixels_stats(ctx, ex)
        return image, stats, time.perf_counter() - t
    finally:
        render.EDGE_VERDICTS = keep


def measure(label: str, ctx: render.RenderContext, ex: InProcess, repeat: int) -> dict:
    seconds: dict[bool, list[float]] = {False: [], True: []}
    images, stats = {}, {}
    for k in range(repeat):
        for arm in ((False, True) if k % 2 == 0 else (True, False)):
            images[arm], stats[arm], t = _tiles(ctx, ex, arm)
            seconds[arm].append(t)
    row = {"scene": label, "pixels": int(images[True].shape[0] * images[True].shape[1]),
           "edge_pixels": int(stats[True]["edges"]), "verdicts": int(stats[True]["verdicts"]),
           "off_s": statistics.median(seconds[False]), "on_s": statistics.median(seconds[True])}
    row["speedup"] = row["off_s"] / row["on_s"]
    if ctx.lights is not None:
        ref, _, _ = _tiles(replace(ctx, lights=replace(ctx.lights,
                                                       samples=2 * ctx.lights.samples)),
                           ex, False)
        scale = math.sqrt((ref**2).mean())
        for arm, name in ((False, "off"), (True, "on")):
            d = images[arm] - ref
            off = np.abs(d).max(axis=2) / np.maximum(ref.max(axis=2), 1e-300)
            row[f"{name}_error_rms"] = float(math.sqrt((d**2).mean()) / scale)
            row[f"{name}_pixels_off_5pct"] = int((off > 0.05).sum())
    change = np.abs(images[True] - images[False]).max(axis=2)
    row["pixels_changed"] = int((change > 0).sum())
    row["change_largest_relative"] = float(
        (change / np.maximum(images[False].max(axis=2), 1e-300)).max())
    return row


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_edges")
    parser.add_argument("--store", type=Path, action="append", default=[],
                        help="a finished run's store: its own view is rendered")
    parser.add_argument("--size", type=int, nargs=2, default=(256, 256),
                        help="pixels of the bundled scenes' views")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args([] if argv is None else argv)
    ex = InProcess()
    try:
        rows = [measure(name, solved_view(SCENES / f"{name}.obj", tuple(args.size), ex), ex,
                        args.repeat) for name in ("cornell_box", "lit_room")]
        for store in args.store:
            ctx = render.for_view(Result(store).render_context(), ex)
            rows.append(measure(store.stem, ctx, ex, args.repeat))
    finally:
        ex.close()
    print(f"{'scene':<14}{'edges':>8}{'verdicts':>11}{'off s':>8}{'on s':>8}{'x':>6}  "
          f"{'rel RMS error (off / on)':>25}  {'pixels > 5 % (off / on)':>24}"
          f"{'changed':>9}{'largest':>9}")
    for r in rows:
        err = (f"{r['off_error_rms']:>11.3e} / {r['on_error_rms']:<10.3e}  "
               f"{r['off_pixels_off_5pct']:>10,} / {r['on_pixels_off_5pct']:<10,}"
               if "on_error_rms" in r else f"{'':>50}")
        print(f"{r['scene']:<14}{r['edge_pixels']:>8,}{r['verdicts']:>11,}{r['off_s']:>8.2f}"
              f"{r['on_s']:>8.2f}{r['speedup']:>6.2f}  {err}"
              f"{r['pixels_changed']:>9,}{r['change_largest_relative']:>9.1e}")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "edges.json").write_text(json.dumps(rows, indent=2) + "\n")
    return {"edges": rows}


if __name__ == "__main__":
    main(sys.argv[1:])
