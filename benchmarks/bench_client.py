"""The solve's client on Dask workers: where its time goes, and what taking work off it saves
(issue 12, item 2).

On 2 workers the client is the solve's one serial thread: between two batches it applies the
shots, checkpoints, publishes progress for the dashboard and offers rows to compute ahead,
while the workers wait for its next batch once the rows are cached. This benchmark runs whole
runs of one scene (default: the Cornell box at element size 7, ~73,000 elements) on a
LocalCluster of 2 thread workers, alternating the arms ``--repeat`` times in this process
(a first run, not counted, warms the imports), and reports medians: the client's seconds in
the monitor (checkpoints, progress, preview), in the row offers and applying the shots, the
solve's and the whole run's. The arms:

- ``publisher thread``: progress and the preview go through the executor's
  :class:`~daskrad.distributed.dask_executor.Publisher` thread (the default);
- ``in line``: sent from the client's own thread, waiting for the scheduler's answer, the
  preview rendered there (:data:`~daskrad.distributed.dask_executor.PUBLISH_THREAD` False,
  the code before).

The results are the same bits (checked: the EXR of every run against the first).

``python -m benchmarks.bench_client [--scene PATH] [--element-size S] [--workers N]
[--repeat N]``; writes ``benchmarks/results/client.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.arms import medians, print_table
from daskrad import solve
from daskrad.distributed import dask_executor, monitor
from daskrad.io.image import read_exr
from daskrad.run import run
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
CORNELL = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"
ARMS = {"publisher thread": True, "in line": False}


class _Clock:
    """Seconds the client spends in a few of its calls, summed over a run."""

    def __init__(self):
        self.seconds: dict[str, float] = {}
        self._undo: list = []

    def time(self, owner, name: str, label: str) -> None:
        original = getattr(owner, name)
        seconds = self.seconds

        def timed(*args, **kwargs):
            t = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                seconds[label] = seconds.get(label, 0.0) + time.perf_counter() - t

        setattr(owner, name, timed)
        self._undo.append((owner, name, original))

    def restore(self) -> None:
        for owner, name, original in reversed(self._undo):
            setattr(owner, name, original)


def one_run(scene: Path, out: Path, settings: Settings, thread: bool) -> dict:
    dask_executor.PUBLISH_THREAD = thread
    clock = _Clock()
    clock.time(monitor.Watch, "__call__", "monitor")
    clock.time(dask_executor.DaskExecutor, "prefetch", "row offers")
    clock.time(solve, "apply_shot", "applying shots")
    try:
        report = run(scene, out, settings, progress=False)
    finally:
        clock.restore()
        dask_executor.PUBLISH_THREAD = True
    return {**clock.seconds, "solve": report["seconds"]["solve"],
            "total": report["seconds"]["total"], "elements": report["counts"]["elements"],
            "shots": report["iterations"]}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="bench_client", description=__doc__.split("\n")[0])
    parser.add_argument("--scene", type=Path, default=CORNELL)
    parser.add_argument("--element-size", type=float, default=7.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if
                             __name__ == "__main__" else [])
    settings = Settings(workers=args.workers, dashboard="127.0.0.1:0",
                        element_size=args.element_size)
    runs: dict[str, list[dict]] = {arm: [] for arm in ARMS}
    with tempfile.TemporaryDirectory() as tmp:
        first = Path(tmp) / "first.exr"
        one_run(args.scene, first, settings, True)        # warms the imports; not counted
        reference = read_exr(first)
        for k in range(args.repeat):
            for arm, thread in ARMS.items():
                out = Path(tmp) / f"{k}.exr"
                runs[arm].append(one_run(args.scene, out, settings, thread))
                if not np.array_equal(read_exr(out), reference):
                    raise AssertionError(f"{arm}: the image differs from the first run's")
    columns = ["monitor", "row offers", "applying shots", "solve", "total"]
    rows = medians(runs, columns)
    print(f"\n{args.scene.name}, {runs['in line'][0]['elements']:,} elements, "
          f"{runs['in line'][0]['shots']} shots, {args.workers} thread workers: client "
          f"seconds, medians of {args.repeat} alternated runs")
    print_table(rows, columns, "ratio to in line", label=18, width=17)
    result = {"scene": str(args.scene), "element_size": args.element_size,
              "workers": args.workers, "repeat": args.repeat, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "client.json").write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
