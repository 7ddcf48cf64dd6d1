"""Scaling on Dask (issues 4 and 12): system efficiency ``T(1) / (T(C) · C)`` (the paper's
measure) of whole converging runs on C = 1 and C = 2 LocalCluster workers, per stage, and a
model for 8, 32 and 128 workers built from the stages' measured shares.

**Measured.** ``T(C)`` is the wall time of a whole run (:func:`daskrad.run.run` through
:func:`benchmarks.bench_speed.whole_run`, as bench_speed's workers table) of a scene of
≥ 50k elements: the Cornell box with 7-unit elements by default (~59,000 elements, ~73,000
after adaptive subdivision; ``--scene PATH`` and ``--element-size`` for others), converged to
the default tolerance (re-shots included), on a LocalCluster of C single-threaded processes
(``--processes``: each reads the store and keeps its own caches, as the machines of a real
cluster would; ``--threads`` measures ``--workers C``'s default, threads of the client's
process, instead).
The cluster is started and closed by this benchmark around each run (so its task stream can be
read before it closes), and both are in ``T(C)``. Every run is a fresh cluster (its workers
load the geometry and their numba kernels from the on-disk cache inside the run); one untimed
run before the timed ones loads the client's kernels. C = 1 and C = 2 alternate, ``--repeats``
times (default 3); each figure is the median of its repeats.

Stages, from the run report's step times: ``direct`` (direct light and adaptive subdivision),
``solve`` (the shooting), ``render`` (the per-pixel pass: junction gathers and tiles) and
``rest`` = ``T(C)`` − those three: load and preprocess, the cluster's start and close, the
store, the report and image files. (With the cluster started here, the report's ``direct`` no
longer includes its start.)

**Derived.** Per stage, an Amdahl fit through its two medians, ``T(C) = serial + parallel / C``:
``parallel = 2 (T(1) − T(2))`` clipped to ``[0, T(1)]`` and ``serial = T(1) − parallel``; the
shares are those over ``T(1)`` of the stage. A stage slower on two workers than on one
(cores shared with the client, a larger cluster to start) is thus all serial at its ``T(1)``,
and one more than twice as fast all parallel. The measured efficiency is the whole run's,
``T(1) / (2 T(2))`` with median wall times.

**Modelled** (labelled ``model`` in the table and in ``benchmarks/results/scaling.json``):

- ``Amdahl``: ``T(C) = Σ_stages serial + parallel / C`` at C = 2, 8, 32, 128, efficiency
  ``T(1) / (C · T(C))`` with ``T(1)`` the sum of the C = 1 stage medians. At C = 2 it gives
  back the sum of the C = 2 stage medians unless a stage was clipped (a stage slower on two
  workers is modelled at its ``T(1)``: the model is then optimistic by the difference).
- ``Amdahl, task-limited``: the same fit with ``1 / C`` replaced by the stage's
  ``φ(C) = Σ_g f_g / min(C, n_g)``: a stage's tasks come in groups that can run at once (the
  tasks of one direct-light pass, of one render pass, of two consecutive shooting batches, as
  the solve keeps two in flight), ``n_g`` tasks holding the fraction ``f_g`` of the stage's
  compute seconds (Dask's task stream of the median C = 1 run). No more than ``n_g`` workers
  can help a group, whatever C; ``rest`` has no tasks, so it is all serial. Both the fit and
  the prediction use φ, so at C = 2 this model, too, gives back the measurement (clipping
  aside).

No per-task scheduler cost is added (the old model's ``TASK_COST``, ~2 ms a task in flight, is
gone): a run's tasks (one per new form-factor row, or per group of rows cheaper than a task,
never fewer groups than workers; per direct-light range, per tile and per gather range;
re-shot rows the client dropped aside, one task per worker holding some) depend on C only
through that grouping, so their scheduling is already inside the measured serial shares.
What the model leaves out: tasks of unequal cost (a group of ``n_g`` tasks is treated as
``n_g`` equal parts, so the task-limited model is optimistic), the client and the scheduler
contending with the workers for cores (on a 2-core machine the C = 2 run shares its cores
with them, so its measured efficiency is a lower bound and the fitted serial shares too
large), a cluster's start growing with C (at 128 workers, a cluster started beforehand and
reached with ``--scheduler``), and the transfers of larger clusters.

``python -m benchmarks.bench_scaling [--quick] [--scene PATH] [--element-size S] [--threads]
[--repeats N] [--json PATH]``; writes ``benchmarks/results/scaling.json`` (``--quick``: a
smoke run, the Cornell box at 60-unit elements, 64 shots at most, a 64² image, one repeat;
no JSON unless ``--json``). Never run it beside other timed work: it times wall seconds.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import bench_speed
from benchmarks.bench_speed import CORNELL, LARGE_ELEMENT_SIZE, whole_run
from daskrad.distributed import connect
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results" / "scaling.json"
REPEATS = 3
MEASURED = (1, 2)
#: ``--quick``: the image's side, pixels.
QUICK_SIZE = 64
MODELLED = (2, 8, 32, 128)
STAGES = ("direct", "solve", "render", "rest")
#: The stage of each kind of task (its key's first word; dask_executor names them).
TASK_STAGE = {"direct": "direct", "formfactor": "solve", "tile": "render", "gather": "render"}


def task_groups(stream: list[dict]) -> tuple[dict, dict]:
    """``({stage: [(tasks, compute seconds), ...]}, {stage: tasks})``: the groups of a run's
    tasks that can run at once, and the count of its tasks, from Dask's task stream (records
    with ``key`` and ``startstops``).

    Keys are ``direct-<generation>-…`` (one pass: a generation), ``tile-<generation>-…``,
    ``gather-<generation>-<n>-<a>-<token>-…`` (one pass: a generation and a context token) and
    ``formfactor-<generation>-<batch>-…``; a shooting group is a batch and the next one (two
    batches are in flight). The rows computed ahead (``formfactor-<generation>-ahead<p>-…``,
    :meth:`daskrad.solve.solve`'s prefetch) are one group of their own: they fill the workers
    the batches leave idle."""
    groups: dict[tuple, list] = {}
    for rec in stream:
        key = rec["key"] if isinstance(rec["key"], str) else str(rec["key"])
        parts = key.split("-")
        kind = parts[0]
        if kind not in TASK_STAGE:
            continue
        if kind == "gather":
            group = (kind, parts[1], parts[4])
        elif kind == "formfactor":
            ahead = parts[2].startswith("ahead")
            group = (kind, int(parts[1]), -1 if ahead else int(parts[2]))
        else:
            group = (kind, parts[1])
        seconds = sum(s["stop"] - s["start"] for s in rec["startstops"]
                      if s["action"] == "compute")
        n, t = groups.get(group, (0, 0.0))
        groups[group] = (n + 1, t + seconds)
    out: dict[str, list[tuple[int, float]]] = {s: [] for s in STAGES}
    counts = dict.fromkeys(STAGES, 0)
    for (kind, *rest), (n, t) in sorted(groups.items()):
        counts[TASK_STAGE[kind]] += n
        if kind == "formfactor" and rest[1] >= 0:  # with the batch after it, if it had tasks
            n += groups.get((kind, rest[0], rest[1] + 1), (0, 0.0))[0]
        out[TASK_STAGE[kind]].append((n, t))
    return out, counts


def phi(groups: list[tuple[int, float]], workers: int) -> float:
    """The task-limited ``φ(C)``: the stage's time on ``workers`` over its time on one, for
    its parallel part (module docstring); 1 for a stage without tasks."""
    total = sum(t for _, t in groups)
    if total <= 0.0:
        return 1.0
    return sum(t / total / min(workers, n) for n, t in groups)


def amdahl(t1: float, t2: float, phi2: float = 0.5) -> tuple[float, float]:
    """``(serial, parallel)`` seconds of ``T(C) = serial + parallel · φ(C)`` through
    ``T(1) = t1`` and ``T(2) = t2`` (``φ(2) = phi2``, ½ for Amdahl's law), clipped so that both
    are ≥ 0 and they sum to ``t1``."""
    if phi2 >= 1.0:                  # nothing of the stage can run on a second worker
        return t1, 0.0
    parallel = min(max((t1 - t2) / (1.0 - phi2), 0.0), t1)
    return t1 - parallel, parallel


def timed(scene: Path, settings: Settings, out: Path) -> dict:
    """One whole run on a LocalCluster of ``settings.workers`` workers started here: wall
    seconds (cluster start and close included), the report's step seconds, the stage groups
    of its task stream."""
    from distributed import get_task_stream

    t = time.perf_counter()
    ex = connect(settings)
    start = time.perf_counter() - t
    close, ex.close = ex.close, lambda: None    # the run closes it: read its stream first
    try:
        with get_task_stream(client=ex.client) as stream:
            r = whole_run(scene, out, settings, executor=ex)
        tasks = ex.stats["tasks"]
    finally:
        t = time.perf_counter()
        close()
        stop = time.perf_counter() - t
    rep = r["report"]
    seconds = start + r["seconds"] + stop
    stages = {s: rep["seconds"][s] for s in STAGES[:3]}
    stages["rest"] = seconds - sum(stages.values())
    groups, counts = task_groups(stream.data)
    return {"workers": settings.workers, "seconds": seconds, "stages": stages,
            "cluster_start_s": start, "cluster_close_s": stop,
            "report_seconds": rep["seconds"], "tasks": tasks, "shots": rep["iterations"],
            "elements": rep["counts"]["elements"], "converged": rep["converged"],
            "load_average_1min": os.getloadavg()[0], "groups": groups, "stage_tasks": counts}


def measure(scene: Path, settings: Settings, repeats: int) -> list[dict]:
    """Every timed run: C = 1 and C = 2 alternate, so both see the same other load."""
    runs = []
    with tempfile.TemporaryDirectory(prefix="daskrad-scaling-") as tmp:
        out = Path(tmp) / "x.exr"
        # untimed: the client's numba kernels load from the cache (a small scene, one worker)
        timed(CORNELL, settings.replace(workers=1, element_size=bench_speed.QUICK_ELEMENT_SIZE,
                                        max_iterations=8), out)
        for repeat in range(repeats):
            for c in MEASURED:
                runs.append({**timed(scene, settings.replace(workers=c), out),
                             "repeat": repeat})
    return runs


def medians(runs: list[dict]) -> list[dict]:
    """The measured rows: per C, the median wall time and the median of each stage."""
    rows = []
    for c in MEASURED:
        mine = sorted((r for r in runs if r["workers"] == c), key=lambda r: r["seconds"])
        rows.append({"kind": "measured", "workers": c,
                     "seconds": statistics.median(r["seconds"] for r in mine),
                     "stages": {s: statistics.median(r["stages"][s] for r in mine)
                                for s in STAGES},
                     "cluster_start_s": statistics.median(r["cluster_start_s"] for r in mine),
                     "load_average_1min": max(r["load_average_1min"] for r in mine),
                     "median_run": mine[(len(mine) - 1) // 2]})
    t1 = rows[0]["seconds"]
    for row in rows:
        row["efficiency"] = t1 / (row["workers"] * row["seconds"])
    return rows


def fit(rows: list[dict]) -> dict:
    """Per stage: the measured medians, the Amdahl fit and the task-limited fit."""
    one, two = rows
    groups = one["median_run"]["groups"]
    out = {}
    for s in STAGES:
        t1, t2 = one["stages"][s], two["stages"][s]
        serial, parallel = amdahl(t1, t2)
        phi2 = phi(groups[s], 2)
        tl_serial, tl_parallel = amdahl(t1, t2, phi2)
        out[s] = {"T1_s": t1, "T2_s": t2, "serial_s": serial, "parallel_s": parallel,
                  "serial_share": serial / t1 if t1 > 0 else 1.0,
                  "parallel_share": parallel / t1 if t1 > 0 else 0.0,
                  "tasks": one["median_run"]["stage_tasks"][s],
                  "groups": len(groups[s]),
                  "widest_group": max((n for n, _ in groups[s]), default=0),
                  "task_limited": {"serial_s": tl_serial, "parallel_s": tl_parallel,
                                   "phi_2": phi2}}
    return out


def model(stages: dict, groups: dict, t1: float) -> list[dict]:
    """The model rows at ``MODELLED`` worker counts (module docstring)."""
    out = []
    for rule in ("Amdahl", "Amdahl, task-limited"):
        for c in MODELLED:
            if rule == "Amdahl":
                per = {s: v["serial_s"] + v["parallel_s"] / c for s, v in stages.items()}
            else:
                per = {s: v["task_limited"]["serial_s"]
                       + v["task_limited"]["parallel_s"] * phi(groups[s], c)
                       for s, v in stages.items()}
            total = sum(per.values())
            out.append({"kind": "model", "rule": rule, "workers": c, "seconds": total,
                        "stages": per, "efficiency": t1 / (c * total)})
    return out


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_scaling")
    parser.add_argument("--quick", action="store_true",
                        help="a smoke run: small scene, one repeat, capped shots")
    parser.add_argument("--scene", type=Path, default=None,
                        help="the scene (default: the Cornell box)")
    parser.add_argument("--element-size", type=float, default=None,
                        help=f"element size (default: {LARGE_ELEMENT_SIZE} for the Cornell box, "
                             "the scene's automatic size for --scene)")
    parser.add_argument("--threads", action="store_true",
                        help="workers as threads of the client's process (--workers C's "
                             "default) instead of processes (a real cluster's stand-in)")
    parser.add_argument("--repeats", type=int, default=None,
                        help=f"runs per worker count (default {REPEATS}; --quick: 1)")
    parser.add_argument("--json", type=Path, default=None,
                        help=f"where to write the results (default {RESULTS}; --quick: nowhere)")
    args = parser.parse_args([] if argv is None else argv)
    scene = args.scene or CORNELL
    size = args.element_size
    if size is None and args.scene is None:
        size = bench_speed.QUICK_ELEMENT_SIZE if args.quick else LARGE_ELEMENT_SIZE
    repeats = args.repeats or (1 if args.quick else REPEATS)
    opts = {"dashboard": "127.0.0.1:0", "processes": not args.threads}
    if size is not None:
        opts["element_size"] = size
    if args.quick:
        opts.update(max_iterations=bench_speed.QUICK_ITERATIONS, width=QUICK_SIZE,
                    height=QUICK_SIZE)
    settings = Settings(**opts)

    runs = measure(scene, settings, repeats)
    rows = medians(runs)
    stages = fit(rows)
    groups = rows[0]["median_run"]["groups"]
    predicted = model(stages, groups, sum(rows[0]["stages"].values()))
    first = runs[0]

    print(f"{scene.name}, element size {size or 'auto'}: {first['elements']} elements, "
          f"{first['shots']} shots ({'converged' if first['converged'] else 'not converged'}); "
          f"whole runs, median of {repeats}")
    print("Measured, per stage (s) and Amdahl fit T(C) = serial + parallel/C "
          "(shares of the stage's T(1))")
    print(f"{'stage':<8}{'T(1)':>8}{'T(2)':>8}{'serial':>8}{'parallel':>9}{'tasks':>7}"
          f"{'groups':>7}{'widest':>7}")
    for s, v in stages.items():
        print(f"{s:<8}{v['T1_s']:>8.2f}{v['T2_s']:>8.2f}{v['serial_share']:>8.1%}"
              f"{v['parallel_share']:>9.1%}{v['tasks']:>7}{v['groups']:>7}"
              f"{v['widest_group']:>7}")
    print("(rest: load, preprocess, cluster start and close, store, files; tasks and groups "
          "from the C = 1 median run's task stream)")
    header = f"{'':<10}{'rule':<22}{'workers':>7}{'T (s)':>9}{'efficiency':>11}"
    print(header)
    print("-" * len(header))
    for r in rows:
        print(f"{'measured':<10}{'whole run, median':<22}{r['workers']:>7}{r['seconds']:>9.2f}"
              f"{r['efficiency']:>11.3f}")
    for m in predicted:
        print(f"{'model':<10}{m['rule']:<22}{m['workers']:>7}{m['seconds']:>9.2f}"
              f"{m['efficiency']:>11.3f}")
    print(f"(measured: cluster start {rows[0]['cluster_start_s']:.2f} s at C = 1, "
          f"{rows[1]['cluster_start_s']:.2f} s at C = 2; highest 1-min load average "
          f"{max(r['load_average_1min'] for r in rows):.1f})")

    result = {
        "benchmark": "scaling", "method": "whole runs; Amdahl fit per stage (module docstring)",
        "scene": scene.name, "element_size": size, "elements": first["elements"],
        "shots": first["shots"], "converged": first["converged"],
        "max_iterations": settings.max_iterations, "repeats": repeats,
        "machine": platform.platform(),
        "cores": len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity")
        else os.cpu_count(),
        "measured": [{k: v for k, v in r.items() if k != "median_run"} for r in rows],
        "stages": stages, "model": predicted,
        "task_groups": {st: [list(g) for g in v] for st, v in groups.items()},
        "all_runs": [{k: v for k, v in r.items() if k != "groups"} for r in runs],
    }
    target = args.json or (None if args.quick else RESULTS)
    if target is not None:
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main(sys.argv[1:])
