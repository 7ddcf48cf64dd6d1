"""Speed (issue 12): time against error beside a path tracer, start-up, and worker counts.

Four tables, one JSON (``benchmarks/results/speed.json``):

1. **Time against error** on the Cornell box (and the lit room): daskrad end to end
   (:func:`daskrad.run.run`, in-process on every core, 128×128) at several settings, beside
   the path tracer of :mod:`daskrad.reference` at several sample counts, each against the
   cached path-traced reference of :mod:`benchmarks.bench_reference` (2,048 paths per pixel;
   the lit room's is made here once, as that one's, and cached beside it). Error: relative RMS
   over all pixels and off the light (:func:`benchmarks.bench_reference.errors`). daskrad's
   time is the whole run (load, mesh, direct, solve, render, store and files), its solve and
   render apart; the path tracer's is its render (its scene setup is milliseconds).
2. **Start-up**: ``import daskrad.cli`` and ``import daskrad.run`` (``-X importtime``, in a
   fresh interpreter), ``daskrad --version`` and ``daskrad info`` (wall, fresh process), the
   Cornell box's whole command through :func:`daskrad.cli.entry` against :func:`daskrad.cli.main`
   alone (the exit's collection, :func:`exit_pair`), and the cold start in an empty numba
   cache (``NUMBA_CACHE_DIR``): ``daskrad warmup`` (what
   ``make install`` runs), the first run after it and a warm run (the issue's bound: first ≤ 2×
   warm).
3. **Workers**: whole converging runs (re-shots included, ``WORKER_PASSES`` alternated passes,
   medians) of a scene of ≥ 50k elements with
   ``--workers 0`` (threads), 1 and 2 (LocalCluster start included): the Cornell box with
   7-unit elements by default, or the scenes given with ``--scene PATH`` (e.g. the office
   interiors converted to OBJ, passed by path; never commit those).

``python -m benchmarks.bench_speed [--quick] [--scene PATH ...] [--no-cold]``; ``--quick`` is
a smoke run (one setting, one sample count, no cold start, a small scene for the workers).
Times are wall seconds, medians of ``REPEATS`` (one run where said); on a machine shared with
other work read them as ratios measured in the same run.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.arms import process_env
from benchmarks.bench_reference import cached_path_trace, errors
from benchmarks.bench_reference import reference as cornell_reference
from daskrad.io import read_exr
from daskrad.reference import path_trace
from daskrad.run import run
from daskrad.scene import load_scene
from daskrad.settings import Settings

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).parent / "results"
CORNELL = ROOT / "scenes" / "cornell_box.obj"
LIT_ROOM = ROOT / "scenes" / "lit_room.obj"
SIZE = 128
REFERENCE_SPP = 2048
REPEATS = 3

#: daskrad settings timed against their error (Settings fields; the image is SIZE × SIZE;
#: ``element_scale`` and ``patch_scale`` multiply the scene's automatic element and patch
#: sizes, so a setting means the same mesh density in the Cornell box and the lit room). The
#: error is per pixel, and much of it is where the two renderers sample a pixel differently
#: (silhouettes, the light's outline): the edge and samples-per-pixel rows show what
#: antialiasing buys.
CONFIGS = {
    "default": {},
    "no edge resampling": {"edge_spp": 0},
    "R 100": {"resolution": 100},
    "coarse elements": {"element_scale": 2.0},
    "coarse patches": {"patch_scale": 2.0},
    "fast": {"element_scale": 2.0, "patch_scale": 2.0, "per_pixel": False},
    "fine elements": {"element_scale": 0.5},
    "no per-pixel pass": {"per_pixel": False},
    "tolerance 1e-2": {"tolerance": 1e-2},
    "16 samples/pixel": {"spp": 16},
    "64 samples/pixel": {"spp": 64},
}
#: Path-tracer samples per pixel (seed 7: independent of the reference's seeds).
PT_SPP = (16, 64, 256, 1024)
#: Element size of the Cornell box for the workers table and bench_scaling (~59,000 elements
#: before adaptive subdivision; 73,066 after it).
LARGE_ELEMENT_SIZE = 7.0
#: The workers table's rows: ``(--workers, --processes)``; 0 is in-process threads, no Dask.
WORKERS = ((0, False), (1, False), (2, False), (1, True), (2, True))
#: Passes over the workers table's rows (medians; ``--quick``: one).
WORKER_PASSES = 3
#: ``--quick``: the workers table's scene (Cornell box, ~600 elements) and its shot cap.
QUICK_ELEMENT_SIZE = 60.0
QUICK_ITERATIONS = 64


def _python() -> list[str]:
    return [sys.executable]


def lit_room_reference() -> tuple[np.ndarray, float]:
    """The lit room's path-traced reference at SIZE² and REFERENCE_SPP (two halves, cached as
    bench_reference caches the Cornell box's) and its relative RMS noise."""
    return cached_path_trace(LIT_ROOM, "lit_room_reference", REFERENCE_SPP, SIZE)


def whole_run(scene: Path, out: Path, settings: Settings, executor=None) -> dict:
    """One whole run of ``scene`` into ``out`` (:func:`daskrad.run.run`, no progress bar):
    ``{"seconds": wall seconds, "report": the run report}``; ``executor``: run on this one
    (the run closes it)."""
    t = time.perf_counter()
    report = run(scene, out, settings, progress=False, executor=executor)
    return {"seconds": time.perf_counter() - t, "report": report}


def timed_run(scene: Path, settings: Settings, repeats: int = REPEATS) -> dict:
    """The median of ``repeats`` whole runs of ``scene`` (warm kernels), with the report and
    image of the median run (every run gives the same bits; the report's step times are
    that run's)."""
    runs = []
    with tempfile.TemporaryDirectory(prefix="daskrad-speed-") as tmp:
        out = Path(tmp) / "x.exr"
        for _ in range(repeats):
            r = whole_run(scene, out, settings)
            runs.append({**r, "image": read_exr(out).astype(np.float64)})
    runs.sort(key=lambda r: r["seconds"])
    return runs[(len(runs) - 1) // 2]


def time_vs_error(scene: Path, ref: np.ndarray, configs: dict, spps: tuple) -> list[dict]:
    from daskrad.mesh import default_sizes

    rows = []
    patch, element = default_sizes(load_scene(scene))[:2]
    for name, opts in configs.items():
        opts = dict(opts)
        if "element_scale" in opts:
            opts["element_size"] = element * opts.pop("element_scale")
        if "patch_scale" in opts:
            opts["patch_size"] = patch * opts.pop("patch_scale")
        r = timed_run(scene, Settings(width=SIZE, height=SIZE, workers=0, **opts))
        rep = r["report"]
        rows.append({"renderer": "daskrad", "config": name, "seconds": r["seconds"],
                     "solve": rep["seconds"]["solve"], "render": rep["seconds"]["render"],
                     "elements": rep["counts"]["elements"], "shots": rep["iterations"],
                     **errors(r["image"], ref)})
    loaded = load_scene(scene)
    cam = dataclasses.replace(loaded.camera, width=SIZE, height=SIZE)
    path_trace(loaded, dataclasses.replace(cam, width=8, height=8), spp=1, seed=7)  # compile
    for spp in spps:
        times, img = [], None
        for _ in range(REPEATS if spp < 256 else 1):      # long ones once: noise is small there
            t = time.perf_counter()
            img = path_trace(loaded, cam, spp=spp, seed=7)
            times.append(time.perf_counter() - t)
        rows.append({"renderer": "path tracer", "config": f"{spp} spp",
                     "seconds": float(np.median(times)), **errors(img, ref)})
    return rows


def _import_ms(module: str) -> float:
    """Cumulative import time of ``module`` in a fresh interpreter, milliseconds (median of 3)."""
    times = []
    for _ in range(3):
        done = subprocess.run(_python() + ["-X", "importtime", "-c", f"import {module}"],
                              capture_output=True, text=True, env=process_env(), cwd=ROOT)
        line = [ln for ln in done.stderr.splitlines() if ln.rstrip().endswith(f"| {module}")]
        times.append(int(re.split(r"\s*\|\s*", line[-1])[1]) / 1000.0)
    return float(np.median(times))


def _wall(cmd: list[str], env: dict | None = None, repeats: int = 3) -> float:
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        done = subprocess.run(cmd, capture_output=True, text=True, env=env or process_env(),
                              cwd=ROOT)
        times.append(time.perf_counter() - t)
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)} failed: {done.stderr}")
    return float(np.median(times))


#: The two sides of the exit's measure (:func:`exit_pair`), launched alike: the command as it
#: is (:func:`daskrad.cli.entry`, the frozen exit) and :func:`daskrad.cli.main` alone, as the
#: command ran before.
_SIDES = {"entry": "import sys; from daskrad.cli import entry; sys.exit(entry(sys.argv[1:]))",
          "main": "import sys; from daskrad.cli import main; sys.exit(main(sys.argv[1:]))"}


def exit_pair(repeats: int = 5) -> dict:
    """Whole command-line runs of the Cornell box (``-q``, 256 × 256, in-process and with
    ``--workers 2``) through :func:`daskrad.cli.entry` (the command: the interpreter's last
    collection skipped) and through :func:`daskrad.cli.main` alone, alternated, medians of
    ``repeats``: the process's wall seconds and their ratio."""
    out = {}
    with tempfile.TemporaryDirectory(prefix="daskrad-exit-") as tmp:
        for label, extra in (("in-process", []), ("2 workers", ["--workers", "2",
                                                               "--dashboard", "127.0.0.1:0"])):
            args = ["run", str(CORNELL), "-q", *extra]
            sides = {"entry": [], "main": []}
            for n in range(repeats):
                # ABBA order, each run its own output (none replaces an earlier one)
                for side in (("entry", "main") if n % 2 == 0 else ("main", "entry")):
                    dest = ["-o", str(Path(tmp) / f"{side}{n}{len(extra)}.exr")]
                    sides[side].append(_wall(_python() + ["-c", _SIDES[side], *args, *dest],
                                             repeats=1))
            e, m = float(np.median(sides["entry"])), float(np.median(sides["main"]))
            out[f"run {label}, main s"] = m
            out[f"run {label}, entry s"] = e
            out[f"run {label}, main / entry"] = m / e
    return out


def startup(cold: bool) -> dict:
    """Import times, CLI start-up, and (``cold``: not with ``--quick``) the command's exit
    (:func:`exit_pair`) and the cold start in an empty numba cache."""
    daskrad = _python() + ["-m", "daskrad"]
    out = {"import daskrad.cli ms": _import_ms("daskrad.cli"),
           "import daskrad.run ms": _import_ms("daskrad.run"),
           "daskrad --version s": _wall(daskrad + ["--version"]),
           "daskrad info s": _wall(daskrad + ["info", str(CORNELL)])}
    if cold:
        out.update(exit_pair())
        with tempfile.TemporaryDirectory(prefix="daskrad-cold-") as tmp:
            env = process_env(NUMBA_CACHE_DIR=str(Path(tmp) / "numba"))
            cmd = daskrad + ["run", str(CORNELL), "-o", str(Path(tmp) / "c.exr"), "-q"]
            out["daskrad warmup s"] = _wall(daskrad + ["warmup"], env, repeats=1)
            out["first run after warmup s"] = _wall(cmd, env, repeats=1)
            out["warm run s"] = _wall(cmd, env, repeats=2)
            shutil.rmtree(Path(tmp) / "numba")
            out["cold run, no warmup s"] = _wall(cmd, env, repeats=1)
        out["first / warm"] = out["first run after warmup s"] / out["warm run s"]
    return out


def workers(scenes: list[Path], element_size: float | None, max_iterations: int | None,
            passes: int = WORKER_PASSES) -> list[dict]:
    """Whole-run wall time of each scene with --workers 0 (threads, no Dask), 1 and 2 (a
    LocalCluster of threads) and 1 and 2 with --processes: ``passes`` passes over the kinds,
    alternated (the machine's load moves between runs of a few seconds), each row the median
    of its passes (its step times from its median run), its speed-up the median of the
    passes' ratios to one worker of its kind in the same pass."""
    rows = []
    for scene in scenes:
        runs: dict = {kind: [] for kind in WORKERS}
        for _ in range(passes):
            for n, processes in WORKERS:
                opts = {"workers": n, "processes": processes, "dashboard": "127.0.0.1:0"}
                if element_size is not None:
                    opts["element_size"] = element_size
                if max_iterations is not None:
                    opts["max_iterations"] = max_iterations
                runs[(n, processes)].append(timed_run(scene, Settings(**opts), repeats=1))
        for (n, processes), done in runs.items():
            base = runs[(1, processes)]
            ratios = sorted(b["seconds"] / r["seconds"] for b, r in zip(base, done, strict=True))
            r = sorted(done, key=lambda x: x["seconds"])[(len(done) - 1) // 2]
            rep = r["report"]
            mem = rep.get("memory", {})
            # a worker process's peak (the process is the run's own); the in-process run's
            # and the threads' peak would be this benchmark process's, earlier runs
            # included: not shown
            peak = max([w["peak_mib"] for w in mem.get("workers", [])], default=None) \
                if processes else None
            rows.append({"scene": scene.name, "workers": n, "processes": processes,
                         "seconds": r["seconds"], "passes": [x["seconds"] for x in done],
                         "elements": rep["counts"]["elements"], "shots": rep["iterations"],
                         "converged": rep["converged"], "peak MiB": peak,
                         "worker peaks MiB": [w["peak_mib"] for w in mem.get("workers", [])],
                         **{f"{k} s": v for k, v in rep["seconds"].items()},
                         "speed-up vs 1 worker": ratios[(len(ratios) - 1) // 2]})
    return rows


def _print_errors(title: str, rows: list[dict], noise: float) -> None:
    print(f"\n{title} ({SIZE}x{SIZE}; reference {REFERENCE_SPP} paths/pixel, noise {noise:.4f})")
    print(f"{'renderer':<13}{'config':<20}{'seconds':>9}{'solve':>8}{'render':>8}"
          f"{'rel RMS':>9}{'off light':>10}")
    for r in rows:
        solve = f"{r['solve']:8.2f}" if "solve" in r else f"{'':8}"
        rend = f"{r['render']:8.2f}" if "render" in r else f"{'':8}"
        print(f"{r['renderer']:<13}{r['config']:<20}{r['seconds']:>9.2f}{solve}{rend}"
              f"{r['relative_rms']:>9.4f}{r['relative_rms_off_light']:>10.4f}")


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_speed")
    parser.add_argument("--quick", action="store_true", help="a smoke run")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold start")
    parser.add_argument("--scene", action="append", type=Path, default=[],
                        help="scene(s) for the workers table (default: the Cornell box with "
                             f"{LARGE_ELEMENT_SIZE}-unit elements)")
    args = parser.parse_args([] if argv is None else argv)
    quick = args.quick
    configs = {"default": {}} if quick else CONFIGS
    spps = (4,) if quick else PT_SPP
    result: dict = {"cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
                    else os.cpu_count()}

    ref, noise = cornell_reference()
    rows = time_vs_error(CORNELL, ref, configs, spps)
    result["cornell_box"] = {"noise": noise, "rows": rows}
    _print_errors("Cornell box: time against error", rows, noise)
    if not quick:
        ref, noise = lit_room_reference()
        rows = time_vs_error(LIT_ROOM, ref, configs, spps)
        result["lit_room"] = {"noise": noise, "rows": rows}
        _print_errors("Lit room: time against error", rows, noise)

    start = startup(cold=not (quick or args.no_cold))
    result["startup"] = start
    print("\nStart-up")
    for k, v in start.items():
        print(f"  {k:<34}{v:>9.2f}")

    if quick:
        scenes, size, cap = [CORNELL], QUICK_ELEMENT_SIZE, QUICK_ITERATIONS
    else:
        scenes = args.scene or [CORNELL]
        size, cap = (None if args.scene else LARGE_ELEMENT_SIZE), None
    wrows = workers(scenes, size, cap, 1 if quick else WORKER_PASSES)
    result["workers"] = wrows
    print("\nWhole runs by --workers (0: in-process threads, no Dask; a LocalCluster of "
          "threads, or of processes, its start included; vs 1: against 1 worker of its kind "
          "in the same pass; medians of the passes)")
    print(f"{'scene':<20}{'workers':>8}{'kind':>10}{'elements':>10}{'shots':>7}{'seconds':>9}"
          f"{'direct':>8}{'solve':>8}{'render':>8}{'vs 1':>7}{'worker MiB':>11}")
    for r in wrows:
        kind = "-" if not r["workers"] else "processes" if r["processes"] else "threads"
        print(f"{r['scene']:<20}{r['workers']:>8}{kind:>10}{r['elements']:>10}{r['shots']:>7}"
              f"{r['seconds']:>9.2f}{r['direct s']:>8.2f}{r['solve s']:>8.2f}"
              f"{r['render s']:>8.2f}{r['speed-up vs 1 worker']:>7.2f}"
              f"{'' if r['peak MiB'] is None else round(r['peak MiB']):>11}")
    if not quick:
        RESULTS.mkdir(exist_ok=True)
        (RESULTS / "speed.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
