"""The view's closest hits through the polygons against the walk of the elements (issue 12).

The primary rays, mirror rays and junction gather of a render find the first surface along a
ray. :data:`daskrad.render.POLYGON_HITS` finds it in the grid over the scene's polygons and
locates the point among the elements' triangles
(:func:`daskrad.kernels.grid.closest_hit_located`); the reference arm walks the grid over the
elements' triangles (:func:`daskrad.kernels.grid.closest_hit_one`'s fan twin for the gather).

For each scene (the bundled Cornell box and lit room; ``--scene PATH`` adds one, e.g. the
converted office, which is not in the repository: docs/references.md), solved once with the
defaults (``--shots`` caps the solves of the ``--scene`` scenes; ``--size`` pixels), the
render's two view-dependent steps are timed in this process with the default executor (a thread
per core), both arms alternated ``--repeat`` times (medians): **gather**
(:func:`daskrad.render.for_view`: the view region's primary rays and the junction gather) and
**tiles** (the image's tiles). The arms are compared where they can differ: the vertex radiance
after the gather and the image (pixels changed, the relative RMS of the change, the largest
change relative to the pixel). They differ to round-off but where two one-sided faces coincide
back to back (the walk then sees whichever round-off favours, the located hit the face towards
the ray).

A second table times the camera's rays found by screen bins (:data:`daskrad.render.VIEW_BINS`,
:mod:`daskrad.kernels.view`) against the walk of the polygons' grid: every tile's primary rays on
one thread, and the image's tiles, both arms alternated, with whether they give the same bits.

``python -m benchmarks.bench_hits [--scene PATH [--config TOML]] [--size W H] [--shots N]
[--repeat N]``; writes ``benchmarks/results/hits.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.kernels.grid import closest_hit_located_batch
from daskrad.kernels.view import view_hits_batch
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"


def _arm(ctx: render.RenderContext, located: bool, ex) -> tuple[float, float, np.ndarray,
                                                                  np.ndarray]:
    """``(gather seconds, tiles seconds, vertex radiance, image)`` of ``ctx`` with
    :data:`daskrad.render.POLYGON_HITS` set to ``located`` (restored after), the junction
    gather by rays in both arms (:data:`daskrad.render.DISC_POLYGONS` −1: the disc's
    directions have no walk of the elements to compare with)."""
    keep, few, bins = render.POLYGON_HITS, render.DISC_POLYGONS, render.VIEW_BINS
    render.POLYGON_HITS = located
    render.DISC_POLYGONS = -1        # both arms gather by rays (the walk has no disc)
    render.VIEW_BINS = False         # both walk a grid (the view table has the bins)
    try:
        t = time.perf_counter()
        view = render.for_view(ctx, ex)
        gather = time.perf_counter() - t
        t = time.perf_counter()
        image = render.pixels(view, ex)
        return gather, time.perf_counter() - t, view.vertex_radiance, image
    finally:
        render.POLYGON_HITS, render.DISC_POLYGONS, render.VIEW_BINS = keep, few, bins


def view_table(ctx: render.RenderContext, repeat: int, ex) -> dict:
    """The camera's rays through screen bins against the walk of the polygons' grid
    (:data:`daskrad.render.VIEW_BINS`), alternated ``repeat`` times, medians: **rays**, every
    tile's primary rays (``spp`` a pixel) on one thread, and whether the hits are the same
    bits; **tiles**, the image's tiles on the executor's threads, and whether the images are
    the same bits."""
    view = render.for_view(ctx, ex)
    cam = view.camera
    batches = [render.primary_rays(cam, rows, cols, view.spp)
               for rows, cols in render.tiles(cam.width, cam.height)]
    polys, loc, grid = view.occluders, view.locator, view.grid

    def walk():
        return [closest_hit_located_batch(polys, loc, grid, o, d, np.zeros(len(o)),
                                          np.full(len(o), np.inf)) for o, d in batches]

    def bins():
        return [view_hits_batch(polys, loc, grid, o[0], d) for o, d in batches]

    keep = render.VIEW_BINS
    seconds: dict = {"walk": [], "bins": [], "tiles walk": [], "tiles bins": []}
    got: dict = {}
    try:
        for k in range(repeat + 1):              # the first pass loads the kernels
            for arm in (("walk", "bins") if k % 2 == 0 else ("bins", "walk")):
                t = time.perf_counter()
                got[arm] = (walk if arm == "walk" else bins)()
                if k:
                    seconds[arm].append(time.perf_counter() - t)
                render.VIEW_BINS = arm == "bins"
                t = time.perf_counter()
                got["tiles " + arm] = render.pixels(view, ex)
                if k:
                    seconds["tiles " + arm].append(time.perf_counter() - t)
    finally:
        render.VIEW_BINS = keep
    same = all(np.array_equal(x, y) for a, b in zip(got["walk"], got["bins"], strict=True)
               for x, y in zip(a, b, strict=True))
    med = {k: float(np.median(v)) for k, v in seconds.items()}
    return {"rays": int(sum(len(o) for o, _ in batches)), "rays_walk_s": med["walk"],
            "rays_bins_s": med["bins"], "rays_speedup": med["walk"] / med["bins"],
            "rays_same_bits": bool(same), "tiles_walk_s": med["tiles walk"],
            "tiles_bins_s": med["tiles bins"],
            "tiles_speedup": med["tiles walk"] / med["tiles bins"],
            "tiles_same_bits": bool(np.array_equal(got["tiles walk"], got["tiles bins"]))}


def _change(a: np.ndarray, b: np.ndarray, axis: int) -> dict:
    """How ``b`` differs from ``a``: entries changed (beyond 1e-12 of ``a``'s largest), the
    relative RMS of the change and the largest change relative to the entry."""
    diff = np.abs(b - a).max(axis=axis)
    size = np.abs(a).max(axis=axis)
    return {"changed": int((diff > 1e-12 * np.abs(a).max()).sum()),
            "relative_rms": float(np.sqrt(((b - a) ** 2).mean() / max((a**2).mean(), 1e-300))),
            "largest_relative": float((diff / np.maximum(size, 1e-300)).max())}


def measure(path: Path, config: Path | None, size: tuple[int, int], shots: int | None,
            repeat: int) -> dict:
    settings = Settings(workers=0, width=size[0], height=size[1])
    if shots is not None:
        settings = settings.replace(max_iterations=shots)
    scene = load_scene(path, config)
    ex = InProcess()
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    sol = solve.radiosity(light, settings, ex)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    _arm(ctx, True, ex)                     # compile (or load) before timing
    seconds = {False: [], True: []}
    out = {}
    for k in range(repeat):
        for located in ((False, True) if k % 2 == 0 else (True, False)):
            g, t, vertex, image = _arm(ctx, located, ex)
            seconds[located].append((g, t))
            out[located] = (vertex, image)
    med = {a: np.median(np.array(s), axis=0) for a, s in seconds.items()}
    return {"scene": path.name, "elements": int(len(ctx.elem_normal)),
            "element_triangles": int(len(ctx.grid.triangles)),
            "polygon_triangles": int(len(ctx.occluders.triangles)),
            "pixels": int(size[0] * size[1]), "threads": ex.threads,
            "gather_walk_s": float(med[False][0]), "gather_located_s": float(med[True][0]),
            "gather_speedup": float(med[False][0] / med[True][0]),
            "tiles_walk_s": float(med[False][1]), "tiles_located_s": float(med[True][1]),
            "tiles_speedup": float(med[False][1] / med[True][1]),
            "render_speedup": float(med[False].sum() / med[True].sum()),
            "vertex_radiance": _change(out[False][0], out[True][0], 1),
            "image": _change(out[False][1], out[True][1], 2),
            "view": view_table(ctx, repeat, ex)}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_hits")
    parser.add_argument("--scene", type=Path, action="append", default=[])
    parser.add_argument("--config", type=Path, action="append", default=[],
                        help="a TOML config (camera) per --scene, in order")
    parser.add_argument("--size", type=int, nargs=2, default=(256, 256))
    parser.add_argument("--shots", type=int, default=None,
                        help="cap the solves of --scene scenes (default: the run's own)")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args([] if argv is None else argv)
    configs = args.config + [None] * (len(args.scene) - len(args.config))
    scenes = [(SCENES / "cornell_box.obj", None, None), (SCENES / "lit_room.obj", None, None),
              *((p, c, args.shots) for p, c in zip(args.scene, configs, strict=True))]
    rows = [measure(p, c, tuple(args.size), shots, args.repeat) for p, c, shots in scenes]
    print(f"{'scene':<16}{'elements':>9}{'polygons':>9}  {'gather: walk':>12}{'located':>8}"
          f"{'x':>6}  {'tiles: walk':>11}{'located':>8}{'x':>6}{'render x':>9}  "
          f"{'vertices changed':>16}{'pixels changed':>15}{'image rel RMS':>14}"
          f"{'largest':>9}")
    for r in rows:
        print(f"{r['scene']:<16}{r['elements']:>9,}{r['polygon_triangles']:>9,}  "
              f"{r['gather_walk_s']:>12.2f}{r['gather_located_s']:>8.2f}"
              f"{r['gather_speedup']:>6.2f}  {r['tiles_walk_s']:>11.2f}"
              f"{r['tiles_located_s']:>8.2f}{r['tiles_speedup']:>6.2f}"
              f"{r['render_speedup']:>9.2f}  {r['vertex_radiance']['changed']:>16,}"
              f"{r['image']['changed']:>15,}{r['image']['relative_rms']:>14.1e}"
              f"{r['image']['largest_relative']:>9.1e}")
    print(f"(seconds: medians of {args.repeat} alternated repeats, {rows[0]['threads']} "
          f"threads, {args.size[0]} x {args.size[1]}; 'x' = walk / located)")
    print(f"\nthe camera's rays by screen bins against the walk of the polygons' grid: every "
          f"tile's primary rays on one thread, the tiles on {rows[0]['threads']} threads")
    print(f"{'scene':<16}{'rays':>9}  {'rays: walk':>10}{'bins':>8}{'x':>6}  same  "
          f"{'tiles: walk':>11}{'bins':>8}{'x':>6}  same")
    for r in rows:
        v = r["view"]
        print(f"{r['scene']:<16}{v['rays']:>9,}  {v['rays_walk_s']:>10.3f}{v['rays_bins_s']:>8.3f}"
              f"{v['rays_speedup']:>6.2f}  {str(v['rays_same_bits']):<5} "
              f"{v['tiles_walk_s']:>11.3f}{v['tiles_bins_s']:>8.3f}{v['tiles_speedup']:>6.2f}"
              f"  {v['tiles_same_bits']}")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "hits.json").write_text(json.dumps(rows, indent=2) + "\n")
    return {"hits": rows}


if __name__ == "__main__":
    main(sys.argv[1:])
