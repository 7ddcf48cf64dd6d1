"""The junction gather by the hemisphere base against rays (issue 12, item 3).

:data:`daskrad.render.GATHER_METHODS`: ``"rays"`` casts ``GATHER_SIDE²`` stratified, jittered,
cosine-distributed rays from each junction vertex, each walking the polygons' grid;
``"disc"`` projects every polygon onto the base of the vertex's hemisphere (Doi's item
buffer, ``R × R``, :func:`daskrad.render.gather_side`), each disc pixel a cosine-distributed
direction. Both give the same operator (:class:`daskrad.render.GatherOperator`), so both are
measured on the same junction vertices, in one run:

- **rows**: the operator of every junction vertex of the view (:func:`daskrad.render.
  for_view`'s own choice of vertices, caught through the executor's ``gather`` call), one
  thread, both methods alternated ``--repeat`` times (medians), and the per-vertex error of the
  gathered radiance ``G · L − x`` (``L`` the solution's vertex radiance) against a reference
  that favours neither: the mean of a disc of side :data:`REFERENCE_SIDE` (two turns and
  shifts averaged) and :data:`REFERENCE_RAYS`² rays, all seeded apart from the arms: relative RMS
  over the vertices and the mean's relative bias, and the two references' own gap;
- **image** (the bundled scenes): the whole render (:func:`daskrad.render.image`, a thread per
  core) with each method, seconds (medians) and, for the Cornell box, the relative RMS against
  the cached path-traced reference of :mod:`benchmarks.bench_reference` (2,048 paths per
  pixel, 128 × 128, off the light as well);
- **ahead** (the bundled scenes): whole warm runs (:func:`daskrad.run.run`, default settings,
  in-process on every core) with the view's gather computed ahead on the cores the solve
  leaves idle (:data:`daskrad.render.GATHER_AHEAD`) and in the render, alternated ``--runs``
  times: medians of the solve's and the render's seconds and of their sum, and whether the
  two arms' images are the same bits; ``--workers N ...`` adds the Cornell box at
  :data:`CLUSTER_ELEMENT_SIZE` (~73,000 elements) on a LocalCluster of ``N`` thread workers,
  where the client's thread computes the gather ahead (``--cluster-runs`` alternated runs).

Scenes: the bundled Cornell box and lit room, and ``--scene PATH`` (e.g. RenderPark's MGF
scenes converted to OBJ, which are not in the repository: docs/references.md; ``--shots``
caps their solves). A scene of more than :data:`daskrad.render.DISC_POLYGONS` polygon
triangles gathers by rays in a run, but both are measured here.

``python -m benchmarks.bench_gather [--scene PATH ...] [--shots N] [--repeat N] [--runs N]
[--sides R ...] [--workers N ...] [--cluster-runs N] [--ahead-only]`` (``--sides``: the disc's
error and time at these sides too; ``--ahead-only``: the ahead table alone); writes
``benchmarks/results/gather.json`` (``gather_ahead.json`` with ``--ahead-only``).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_reference import SIZE as REFERENCE_SIZE
from benchmarks.bench_reference import errors, reference
from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.io import read_exr
from daskrad.preprocess import preprocess
from daskrad.run import run
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"
#: The element size of the ahead table's cluster runs: the Cornell box at ~73,000 elements.
CLUSTER_ELEMENT_SIZE = 7.0
#: The disc side of the error's reference: ~7,850 directions a vertex.
REFERENCE_SIDE = 100
#: The rays per side of the error's other reference: 4,096 a vertex.
REFERENCE_RAYS = 64
#: Added to the vertex seeds of the references (other turns, shifts and jitter than the
#: arms').
SEED_SHIFT = 1_000_003


class _Catch(InProcess):
    """The default executor, keeping the last gather context it was asked to run."""

    gctx = None

    def gather(self, ctx, ranges):
        self.gctx = ctx
        return super().gather(ctx, ranges)


def _arm(gctx: render.GatherContext, method: str, side: int | None = None,
         shift: int = 0) -> render.GatherContext:
    # the run's own side for its method; the other method at its default
    own = render.gather_method(gctx.polygons) == method
    side = side or (gctx.side if own else render.DISC_SIDE if method == "disc"
                    else render.GATHER_SIDE)
    return dataclasses.replace(gctx, method=method, side=side, seeds=gctx.seeds + shift)


def _gathered(gctx: render.GatherContext, L: np.ndarray) -> tuple[np.ndarray, float]:
    """``(G · L − x, seconds)`` over every vertex of ``gctx``, in this thread."""
    t = time.perf_counter()
    op = render.gather_vertices(gctx, 0, len(gctx.points))
    return op.mean_radiance(L) - op.excluded, time.perf_counter() - t


def _solved(path: Path, settings: Settings):
    scene = load_scene(path)
    ex = InProcess()
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    return scene, light, solve.radiosity(light, settings, ex)


def rows(path: Path, shots: int | None, repeat: int, sides: tuple = ()) -> dict:
    settings = Settings(workers=0)
    if shots is not None:
        settings = settings.replace(max_iterations=shots)
    scene, light, sol = _solved(path, settings)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    ex = _Catch()
    render.for_view(ctx, ex)
    gctx = ex.gctx
    ex.close()
    if gctx is None:
        return {"scene": path.name, "junction_vertices": 0}
    L = ctx.vertex_radiance
    disc = 0.5 * (_gathered(_arm(gctx, "disc", REFERENCE_SIDE, SEED_SHIFT), L)[0]
                  + _gathered(_arm(gctx, "disc", REFERENCE_SIDE, 2 * SEED_SHIFT), L)[0])
    rays = _gathered(_arm(gctx, "rays", REFERENCE_RAYS, SEED_SHIFT), L)[0]
    ref = 0.5 * (disc + rays)
    scale = float(np.abs(ref).mean())
    out = {"scene": path.name, "junction_vertices": int(len(gctx.points)),
           "polygon_triangles": int(len(gctx.polygons.triangles)),
           "run_method": render.gather_method(gctx.polygons),
           "reference_gap": {"relative_rms": float(np.sqrt(np.mean((disc - rays) ** 2))
                                                   / scale),
                             "bias": float(np.mean(disc - rays) / scale)}}
    for method in render.GATHER_METHODS:
        _gathered(_arm(gctx, method, shift=0), L)         # compiled (or loaded) first
    seconds: dict[str, list[float]] = {m: [] for m in render.GATHER_METHODS}
    values = {}
    for k in range(repeat):
        for method in (list(seconds) if k % 2 == 0 else list(seconds)[::-1]):
            values[method], s = _gathered(_arm(gctx, method), L)
            seconds[method].append(s)
    for method, got in values.items():
        out[method] = {"seconds": statistics.median(seconds[method]),
                       "us_per_vertex": 1e6 * statistics.median(seconds[method])
                       / len(gctx.points),
                       "relative_rms": float(np.sqrt(np.mean((got - ref) ** 2)) / scale),
                       "worst": float(np.abs(got - ref).max() / scale),
                       "bias": float(np.mean(got - ref) / scale)}
    out["speedup"] = out["rays"]["seconds"] / out["disc"]["seconds"]
    out["sides"] = {}
    for side in sides:                      # the disc at other sides, on the same vertices
        times = []
        for _ in range(repeat):
            got, t = _gathered(_arm(gctx, "disc", side), L)
            times.append(t)
        out["sides"][int(side)] = {
            "seconds": statistics.median(times),
            "relative_rms": float(np.sqrt(np.mean((got - ref) ** 2)) / scale),
            "worst": float(np.abs(got - ref).max() / scale)}
    return out


def image(path: Path, repeat: int) -> dict:
    """The render with each method: seconds (a thread per core) and, for the Cornell box, the
    error against the path-traced reference."""
    settings = Settings(workers=0, width=REFERENCE_SIZE, height=REFERENCE_SIZE)
    scene, light, sol = _solved(path, settings)
    ref = reference()[0] if path.name == "cornell_box.obj" else None
    keep = render.DISC_POLYGONS
    ex = InProcess()
    seconds: dict[str, list[float]] = {"rays": [], "disc": []}
    pictures = {}
    try:
        for k in range(repeat + 1):
            for method in (("rays", "disc") if k % 2 == 0 else ("disc", "rays")):
                render.DISC_POLYGONS = keep if method == "disc" else -1
                t = time.perf_counter()
                pictures[method] = render.image(scene, light, sol, settings, ex).pixels
                if k:                                  # the first pass compiles
                    seconds[method].append(time.perf_counter() - t)
    finally:
        render.DISC_POLYGONS = keep
        ex.close()
    out = {"scene": path.name, "size": REFERENCE_SIZE, "threads": ex.threads}
    for method, px in pictures.items():
        out[method] = {"render_s": statistics.median(seconds[method])}
        if ref is not None:
            out[method].update(errors(px, ref))
    return out


def ahead(path: Path, runs: int, workers: int = 0, element_size: float | None = None
          ) -> dict:
    """Whole warm runs of ``path`` (defaults; ``workers``: on a LocalCluster of that many
    thread workers, started by each run; ``element_size``), the gather computed ahead and in
    the render, alternated ``runs`` times after one warm-up run of each: medians and the
    bits."""
    opts: dict = {"workers": workers, "dashboard": "127.0.0.1:0"}
    if element_size is not None:
        opts["element_size"] = element_size
    seconds: dict = {True: [], False: []}
    pictures: dict = {}
    before = render.GATHER_AHEAD
    with tempfile.TemporaryDirectory(prefix="daskrad-ahead-") as tmp:
        try:
            for n in range(runs + 1):
                for arm in (False, True):
                    render.GATHER_AHEAD = arm
                    out = Path(tmp) / f"{n}-{int(arm)}.exr"
                    report = run(path, out, Settings(**opts), progress=False)
                    pictures[arm] = read_exr(out)
                    if n:
                        seconds[arm].append(report["seconds"])
        finally:
            render.GATHER_AHEAD = before

    def medians(rows):
        return {k: statistics.median(r[k] for r in rows) for k in ("solve", "render")} | {
            "solve_render": statistics.median(r["solve"] + r["render"] for r in rows)}

    on, off = medians(seconds[True]), medians(seconds[False])
    return {"scene": path.name, "runs": runs, "workers": workers,
            "element_size": element_size, "elements": report["counts"]["elements"],
            "ahead": on, "in_render": off,
            "speedup": off["solve_render"] / on["solve_render"],
            "same_bits": bool(np.array_equal(pictures[True], pictures[False]))}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_gather")
    parser.add_argument("--scene", type=Path, action="append", default=[])
    parser.add_argument("--shots", type=int, default=None,
                        help="cap the solves of --scene scenes (default: the run's own)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--sides", type=int, nargs="*", default=[],
                        help="also the disc at these sides (error, worst vertex, seconds)")
    parser.add_argument("--runs", type=int, default=8,
                        help="alternated whole runs of each arm of the ahead table")
    parser.add_argument("--workers", type=int, nargs="*", default=[],
                        help="also the ahead table's whole runs of the Cornell box at "
                             f"element size {CLUSTER_ELEMENT_SIZE} on a LocalCluster of "
                             "these many thread workers")
    parser.add_argument("--cluster-runs", type=int, default=3,
                        help="alternated whole runs of each arm on a cluster")
    parser.add_argument("--ahead-only", action="store_true",
                        help="only the ahead table")
    args = parser.parse_args([] if argv is None else argv)
    bundled = [SCENES / "cornell_box.obj", SCENES / "lit_room.obj"]
    table, images = [], []
    if not args.ahead_only:
        table = [rows(p, None, args.repeat, tuple(args.sides)) for p in bundled]
        table += [rows(p, args.shots, args.repeat, tuple(args.sides)) for p in args.scene]
        images = [image(p, args.repeat) for p in bundled]
    aheads = [ahead(p, args.runs) for p in bundled]
    aheads += [ahead(bundled[0], args.cluster_runs, n, CLUSTER_ELEMENT_SIZE)
               for n in args.workers]

    if not args.ahead_only:
        _print_rows(table, images, args)
    print(f"\nwhole warm runs, defaults, every core: the view's gather ahead (during the "
          f"solve) and in the render, medians of {args.runs} alternated ({args.cluster_runs} "
          "on a LocalCluster of thread workers, w: how many)")
    print(f"{'scene':<22}{'elements':>9}{'solve':>8}{'render':>8}{'sum':>8}   {'solve':>8}"
          f"{'render':>8}{'sum':>8}{'x':>7}  same bits")
    for r in aheads:
        a, b = r["in_render"], r["ahead"]
        name = r["scene"] + (f" w{r['workers']}" if r["workers"] else "")
        print(f"{name:<22}{r['elements']:>9,}{a['solve']:>8.3f}{a['render']:>8.3f}"
              f"{a['solve_render']:>8.3f}   {b['solve']:>8.3f}{b['render']:>8.3f}"
              f"{b['solve_render']:>8.3f}{r['speedup']:>7.2f}  {r['same_bits']}")
    result = {"repeat": args.repeat, "reference_side": REFERENCE_SIDE,
              "reference_rays": REFERENCE_RAYS,
              "disc_side": render.DISC_SIDE, "disc_side_simple": render.DISC_SIDE_SIMPLE,
              "disc_simple": render.DISC_SIMPLE, "gather_side": render.GATHER_SIDE,
              "rows": table, "images": images, "ahead": aheads}
    RESULTS.mkdir(exist_ok=True)
    name = "gather_ahead.json" if args.ahead_only else "gather.json"
    (RESULTS / name).write_text(json.dumps(result, indent=2))
    return result


def _print_rows(table: list[dict], images: list[dict], args) -> None:
    print("junction gather, one thread: seconds (medians of "
          f"{args.repeat}) and per-vertex error against the mean of a disc of side "
          f"{REFERENCE_SIDE} and {REFERENCE_RAYS}² rays (gap: disc − rays references)")
    print(f"{'scene':<16}{'vertices':>9}{'polygons':>9}  {'rays s':>8}{'µs/v':>7}{'rms':>8}"
          f"{'bias':>9}  {'disc s':>8}{'µs/v':>7}{'rms':>8}{'bias':>9}{'x':>7}"
          f"{'gap rms':>9}{'bias':>8}  run")
    for r in table:
        if not r["junction_vertices"]:
            print(f"{r['scene']:<16}{0:>9}")
            continue
        a, b = r["rays"], r["disc"]
        print(f"{r['scene']:<16}{r['junction_vertices']:>9,}{r['polygon_triangles']:>9,}  "
              f"{a['seconds']:>8.3f}{a['us_per_vertex']:>7.0f}{a['relative_rms']:>8.2%}"
              f"{a['bias']:>+9.2%}  {b['seconds']:>8.3f}{b['us_per_vertex']:>7.0f}"
              f"{b['relative_rms']:>8.2%}{b['bias']:>+9.2%}{r['speedup']:>7.2f}"
              f"{r['reference_gap']['relative_rms']:>9.2%}{r['reference_gap']['bias']:>+8.2%}"
              f"  {r['run_method']}")
    if args.sides:
        print(f"\nthe disc at other sides: relative RMS / worst vertex / seconds (the rays: "
              f"{render.GATHER_SIDE}², as above)")
        for r in table:
            if r.get("sides"):
                a = r["rays"]
                print(f"{r['scene']:<16} rays {a['relative_rms']:.2%} / {a['worst']:.1%} / "
                      f"{a['seconds']:.3f} s;  " + ";  ".join(
                          f"{side}: {v['relative_rms']:.2%} / {v['worst']:.1%} / "
                          f"{v['seconds']:.3f} s" for side, v in r["sides"].items()))
    print(f"\nrender {REFERENCE_SIZE}x{REFERENCE_SIZE}, {images[0]['threads']} threads: seconds "
          f"(medians of {args.repeat}); Cornell box error against the path tracer")
    for r in images:
        line = f"{r['scene']:<16}"
        for method in ("rays", "disc"):
            m = r[method]
            line += f"  {method} {m['render_s']:.3f} s"
            if "relative_rms" in m:
                line += (f" (rel RMS {m['relative_rms']:.5f}, off the light "
                         f"{m['relative_rms_off_light']:.5f})")
        print(line)


if __name__ == "__main__":
    main(sys.argv[1:])
