"""The kernels as shipped against a reference build of them (the code a change replaced,
``daskrad/kernels/_jit.py``'s :func:`~daskrad.kernels._jit.reference_arm`): whole runs, the
two arms alternated in one benchmark. ``--reference``:

- ``counted`` (the default): leaves without reference counts (arm ``leaves``) against
  ``DASKRAD_LEAF_REFCOUNTS=1``, every leaf compiled with numba's reference counts, as before
  the leaves (arm ``counted``); writes ``results/leaves.json``;
- ``registers``: the grid's walk marking every triangle a fan's ray tested
  (:attr:`daskrad.kernels.grid.Fan.tested`, arm ``marks``) against
  ``DASKRAD_WALK_REGISTERS=1``, the last four remembered in registers, as before (arm
  ``registers``); writes ``results/walk.json``.

Each run is a ``daskrad run`` in a process of its own. The reference arm sets its variable and
a numba cache of its own. Both arms' caches are compiled by ``daskrad warmup`` before the
timings; the reference arm's stays in the temporary directory between benchmark runs, and its
warmup recompiles only when the kernels changed. Cases:

- the Cornell box at its defaults (256 × 256, in-process on every core);
- the Cornell box meshed to 73k elements (``--element-size 7``) in-process and on 2 thread
  workers (``--workers 0`` / ``2``);
- each ``--scene PATH`` on 2 workers, 352 shots as the paper's Fig. 4 (``--workers 2
  --max-iterations 352``; e.g. the office interiors converted to OBJ, by path: never commit
  them).

Columns are the run report's seconds (direct, solve, render, total) and the process's wall
time, medians of ``--passes`` passes (in the order ABBA…, so each arm goes first as often);
the ratio row is shipped / reference. Each pass's images of the two arms are compared bit for
bit (``same``: every pass's were).

``python -m benchmarks.bench_leaves [--reference counted|registers] [--passes 4]
[--scene PATH ...] [--quick]``.
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

from benchmarks.arms import ROOT, medians, print_table, process_env
from daskrad.io import read_exr

RESULTS = Path(__file__).parent / "results"
CORNELL = ROOT / "scenes" / "cornell_box.obj"
COLUMNS = ("direct", "solve", "render", "total", "wall")
#: ``--reference`` → (the shipped arm's name, the reference arm's name, its variable, the
#: results file).
REFERENCES = {"counted": ("leaves", "counted", "DASKRAD_LEAF_REFCOUNTS", "leaves.json"),
              "registers": ("marks", "registers", "DASKRAD_WALK_REGISTERS", "walk.json")}


def _cache(reference: str) -> Path:
    """The reference arm's numba cache (its warmup reuses it while the kernels are
    unchanged)."""
    return Path(tempfile.gettempdir()) / f"daskrad-bench-leaves-{reference}"


def _env(reference: str, arm: str) -> dict:
    env = process_env()
    for _, _, variable, _ in REFERENCES.values():
        env.pop(variable, None)
    _, ref, variable, _ = REFERENCES[reference]
    if arm == ref:
        env.update({variable: "1", "NUMBA_CACHE_DIR": str(_cache(reference))})
    return env


def _daskrad(reference: str, arm: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "daskrad", *args], env=_env(reference, arm),
                          check=True, capture_output=True, text=True)


def one_run(reference: str, arm: str, scene: Path, extra: list[str], exr: Path) -> dict:
    """One ``daskrad run`` of ``scene`` in arm ``arm``: the report's seconds and the wall."""
    t = time.perf_counter()
    _daskrad(reference, arm, "run", str(scene), *extra, "-q", "-o", str(exr))
    wall = time.perf_counter() - t
    seconds = json.loads(exr.with_suffix(".json").read_text())["seconds"]
    return {**{k: seconds.get(k, 0.0) for k in COLUMNS if k != "wall"}, "wall": wall}


def cases(scenes: list[Path], quick: bool) -> list[tuple[str, Path, list[str]]]:
    out = [("cornell 256²", CORNELL, [])]
    if quick:
        return out
    out += [("box 73k, workers 0", CORNELL, ["--element-size", "7", "--workers", "0"]),
            ("box 73k, workers 2", CORNELL, ["--element-size", "7", "--workers", "2"])]
    out += [(f"{p.stem}, workers 2", p, ["--workers", "2", "--max-iterations", "352"])
            for p in scenes]
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reference", choices=sorted(REFERENCES), default="counted")
    ap.add_argument("--passes", type=int, default=4)
    ap.add_argument("--scene", type=Path, action="append", default=[],
                    help="an OBJ scene to run on 2 workers, 352 shots (repeatable)")
    ap.add_argument("--quick", action="store_true", help="the Cornell box only, one pass")
    args = ap.parse_args(argv)
    passes = 1 if args.quick else args.passes
    for p in args.scene:
        if not p.is_file():
            ap.error(f"{p}: no such scene")
    shipped, ref, _, result = REFERENCES[args.reference]
    arms = (shipped, ref)
    for arm in arms:           # outside the timings; quick when already compiled
        t = time.perf_counter()
        _daskrad(args.reference, arm, "warmup")
        print(f"{arm}: kernels ready in {time.perf_counter() - t:.1f} s")
    results = []
    with tempfile.TemporaryDirectory(prefix="daskrad-bench-leaves-") as tmp:
        for name, scene, extra in cases(args.scene, args.quick):
            runs = {arm: [] for arm in arms}
            same = True
            for k in range(passes):
                # alternate which arm goes first, so a drift of the machine is shared
                images = {}
                for arm in (arms if k % 2 == 0 else arms[::-1]):
                    exr = Path(tmp) / f"{arm}.exr"
                    runs[arm].append(one_run(args.reference, arm, scene, extra, exr))
                    images[arm] = read_exr(exr)
                same = same and bool(np.array_equal(images[shipped], images[ref]))
            rows = medians(runs, COLUMNS)
            print(f"\n{name} (medians of {passes}; same bits: {same})")
            print_table(rows, COLUMNS, ratio=f"{shipped[:5]}/{ref[:4]}", label=12, width=9)
            results.append({"case": name, "scene": str(scene), "args": extra, "same": same,
                            "rows": rows})
    RESULTS.mkdir(exist_ok=True)
    out = RESULTS / result
    out.write_text(json.dumps({"passes": passes, "cases": results}, indent=1))
    print(f"\nwrote {out}")


if __name__ == "__main__":
    main()
