"""RenderPark's five MGF scenes end to end, in-process against ``--workers 2`` (issue 12, item 5).

Each scene is read unconverted (two-sided as the format says) and seen through the camera of
its OBJ conversion (a TOML ``[camera]`` passed with ``--config``), at 192 × 144, with the
defaults but ``--max-iterations 2000`` (``--shots default``: the run's own cap, 4 shots a
patch, so every scene converges), as a user runs it: one ``daskrad run`` process per run
(``--workers 0``: threads over the nogil kernels; ``--workers 2``: a LocalCluster of threads).
In each pass every scene runs in-process, then on 2 workers, back to back; ``--passes``
passes (default 2). The table gives the median over the passes of the report's step times
(direct / solve / render / total) in-process, the total on 2 workers and their ratio, computed
per pass before the median (the machine is shared: read the ratios, not the seconds).

The scenes are not in the repository (docs/references.md): ``--root DIR`` is a folder holding
``mgf/cube.mgf``, ``mgf/office2/office2.mgf``, ``mgf/office3/office.mgf``,
``mgf/salon/classroom.mgf`` and ``mgf/office1/graz.mgf``, and the cameras
``<name>/<name>.toml`` (``cube``, ``office2``, ``office3``, ``classroom``, ``graz``). Without
``--root`` the benchmark says so and measures nothing.

``--relaxation W,W`` runs every scene at each overshooting factor (``--relaxation`` of
``daskrad run``; default: the run's own), all in each pass, one row per scene and factor, and
writes ``mgf_relaxation.json`` instead.

``python -m benchmarks.bench_mgf --root DIR [--scene NAME ...] [--passes N] [--shots N|default]
[--relaxation W,W]``; writes ``benchmarks/results/mgf.json`` (``mgf_converged.json`` with
``--shots default``).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).parent / "results"

#: name → the MGF file under ``--root`` (its camera is ``<name>/<name>.toml``).
SCENES = {"cube": "mgf/cube.mgf", "office2": "mgf/office2/office2.mgf",
          "office3": "mgf/office3/office.mgf", "classroom": "mgf/salon/classroom.mgf",
          "graz": "mgf/office1/graz.mgf"}
SIZE = (192, 144)
MAX_ITERATIONS = 2000
STEPS = ("direct", "solve", "render", "total")


def one_run(root: Path, name: str, workers: int, out: Path,
            shots: int | None = MAX_ITERATIONS, relaxation: float | None = None) -> dict:
    """One ``daskrad run`` of scene ``name`` in a process of its own; the report's figures.
    ``shots``: ``--max-iterations``, ``relaxation``: ``--relaxation`` (None: the run's
    default)."""
    exr = out / f"{name}-{workers}.exr"
    cap = [] if shots is None else ["--max-iterations", str(shots)]
    if relaxation is not None:
        cap += ["--relaxation", str(relaxation)]
    cmd = [sys.executable, "-m", "daskrad", "run", str(root / SCENES[name]),
           "--config", str(root / name / f"{name}.toml"), "--width", str(SIZE[0]),
           "--height", str(SIZE[1]), *cap, "--workers", str(workers), "-q", "-o", str(exr)]
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    wall = time.perf_counter() - t
    report = json.loads(exr.with_suffix(".json").read_text())
    return {"wall": wall, **{k: report["seconds"][k] for k in STEPS},
            "elements": report["counts"]["elements"], "shots": report["iterations"],
            "converged": report["converged"]}


def measure(root: Path, names: list[str], passes: int,
            shots: int | None = MAX_ITERATIONS,
            relaxations: tuple = (None,)) -> list[dict]:
    runs = {(n, w, x): [] for n in names for w in (0, 2) for x in relaxations}
    with tempfile.TemporaryDirectory() as tmp:
        for _ in range(passes):
            for name in names:
                for x in relaxations:
                    for workers in (0, 2):
                        runs[name, workers, x].append(one_run(root, name, workers, Path(tmp),
                                                              shots, x))
    rows = []
    for name, x in ((n, x) for n in names for x in relaxations):
        solo, two = runs[name, 0, x], runs[name, 2, x]
        rows.append({
            "scene": Path(SCENES[name]).name, "relaxation": x,
            "elements": solo[0]["elements"],
            "shots": solo[0]["shots"], "converged": solo[0]["converged"],
            **{f"in_process_{k}": float(np.median([r[k] for r in solo])) for k in STEPS},
            **{f"two_workers_{k}": float(np.median([r[k] for r in two])) for k in STEPS},
            "ratio_two_workers": float(np.median([b["total"] / a["total"]
                                                  for a, b in zip(solo, two, strict=True)])),
            "passes": {"in_process_total": [r["total"] for r in solo],
                       "two_workers_total": [r["total"] for r in two]}})
    return rows


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_mgf")
    parser.add_argument("--root", type=Path, default=None,
                        help="folder of the MGF scenes and their cameras (not in the repo)")
    parser.add_argument("--scene", action="append", choices=sorted(SCENES), default=[])
    parser.add_argument("--passes", type=int, default=2)
    parser.add_argument("--shots", default=str(MAX_ITERATIONS),
                        help="--max-iterations of every run, or 'default' (converging)")
    parser.add_argument("--relaxation", default=None,
                        help="overshooting factors to run each scene at, comma-separated "
                             "(default: the run's own)")
    args = parser.parse_args([] if argv is None else argv)
    if args.root is None:
        print("bench_mgf: no --root given (the MGF scenes are not in the repository); "
              "nothing measured")
        return {}
    names = [n for n in SCENES if n in args.scene] if args.scene else list(SCENES)
    shots = None if args.shots == "default" else int(args.shots)
    relaxations = (tuple(float(x) for x in args.relaxation.split(","))
                   if args.relaxation else (None,))
    rows = measure(args.root, names, max(1, args.passes), shots, relaxations)
    print(f"{'scene':<14}{'omega':>6}{'elements':>9}{'shots':>7}  in-process: direct  solve "
          f"render  total   2 workers: solve  total  ratio")
    for r in rows:
        omega = "" if r["relaxation"] is None else f"{r['relaxation']:g}"
        print(f"{r['scene']:<14}{omega:>6}{r['elements']:>9,}{r['shots']:>7}  "
              f"{r['in_process_direct']:>18.1f}{r['in_process_solve']:>7.1f}"
              f"{r['in_process_render']:>7.1f}{r['in_process_total']:>7.1f}"
              f"{r['two_workers_solve']:>18.1f}{r['two_workers_total']:>7.1f}"
              f"{r['ratio_two_workers']:>7.2f}")
    RESULTS.mkdir(exist_ok=True)
    name = ("mgf_relaxation.json" if args.relaxation
            else "mgf_converged.json" if shots is None else "mgf.json")
    (RESULTS / name).write_text(json.dumps(rows, indent=2) + "\n")
    return {"mgf": rows}


if __name__ == "__main__":
    main(sys.argv[1:])
