"""The view's junction gather applied in the blocks its tasks computed, against one operator
joined from them (issue 12, item 5: the render's time and the peak memory it reports).

:func:`daskrad.render.for_view` applies the junction gather's operator three times (its
first pass and two corrections). Its tasks compute it in row blocks
(:class:`daskrad.render.GatherOperator` each); the render used to join them into one CSR
operator first, a copy of ~600 nonzeros a vertex (RenderPark's classroom: 15,477
vertices, 9.9 million nonzeros, 160 MB). Arms:

- ``blocks``: :class:`daskrad.render.GatherBlocks`, each block applied in turn (the code);
- ``joined``: the blocks copied into one operator, then applied (the code before, kept here
  as :class:`JoinedGather`).

Each pass runs :func:`~daskrad.render.for_view` of a finished run's store once per arm, each in
a fresh process (in-process, a thread per core), in the order ABBA…; the columns are its
seconds and the process's peak resident memory (MiB), medians over ``--passes``; the ratio row
is ``blocks / joined``. Both arms' vertex radiance must be the same bits (``same``).

Stores: each ``--store PATH`` (an ``OUT.zarr`` a run wrote, e.g. of the classroom converted to
OBJ, which is not in the repository); by default the bundled Cornell box at ``--element-size
7`` (~73,000 elements), run first in-process into a temporary directory.

``python -m benchmarks.bench_operator [--store PATH ...] [--passes N]``; writes
``benchmarks/results/operator.json``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.arms import ROOT, medians, print_table, process_env
from daskrad import render

RESULTS = Path(__file__).parent / "results"
CORNELL = ROOT / "scenes" / "cornell_box.obj"
ARMS = ("blocks", "joined")
COLUMNS = ("seconds", "peak MiB")


class JoinedGather(render.GatherBlocks):
    """The operator before :class:`daskrad.render.GatherBlocks`: the blocks joined into one
    CSR operator, which is then applied whole."""

    def __init__(self, parts):
        super().__init__(parts)
        if not self.parts:
            return
        offsets = np.cumsum([0] + [len(p.cols) for p in self.parts])
        indptr = np.concatenate([[0]] + [p.indptr[1:] + o for p, o in
                                         zip(self.parts, offsets[:-1], strict=True)])
        self.parts = [render.GatherOperator(
            indptr.astype(np.int64), np.concatenate([p.cols for p in self.parts]),
            np.concatenate([p.weights for p in self.parts]), self.excluded)]


def child(arm: str, store: str) -> dict:
    """One arm's :func:`~daskrad.render.for_view` of ``store`` in this process."""
    from daskrad.distributed.executor import InProcess
    from daskrad.distributed.store import Result

    if arm == "joined":
        render.GatherBlocks = JoinedGather
    ctx = Result(store).render_context()
    ex = InProcess()
    try:
        t = time.perf_counter()
        out = render.for_view(ctx, ex)
        seconds = time.perf_counter() - t
    finally:
        ex.close()
    return {"seconds": seconds,
            "peak MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
            "digest": hashlib.sha256(out.vertex_radiance.tobytes()).hexdigest()}


def _scene(store: Path) -> dict:
    """The scene a store's run solved (its report beside it) and its element count."""
    from daskrad.distributed.store import Result

    report = Path(store).with_suffix(".json")
    scene = json.loads(report.read_text()).get("scene") if report.is_file() else None
    return {"scene": Path(scene).name if scene else None,
            "elements": Result(store).attrs.get("n_elements")}


def _run_arm(arm: str, store: Path) -> dict:
    done = subprocess.run([sys.executable, "-m", "benchmarks.bench_operator", "--child", arm,
                           str(store)], env=process_env(), check=True, capture_output=True,
                          text=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="bench_operator", description=__doc__.split("\n")[0])
    parser.add_argument("--store", type=Path, action="append", default=[])
    parser.add_argument("--passes", type=int, default=4)
    parser.add_argument("--element-size", type=float, default=7.0)
    parser.add_argument("--child", nargs=2, metavar=("ARM", "STORE"), help=argparse.SUPPRESS)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if
                             __name__ == "__main__" else [])
    if args.child:
        print(json.dumps(child(*args.child)))
        return {}
    out: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        stores = list(args.store)
        if not stores:
            exr = Path(tmp) / "cornell.exr"
            subprocess.run([sys.executable, "-m", "daskrad", "run", "--workers", "0",
                            "--element-size", str(args.element_size), "-q", "-o", str(exr),
                            str(CORNELL)], env=process_env(), check=True, capture_output=True)
            stores = [exr.with_suffix(".zarr")]
        for store in stores:
            runs: dict[str, list[dict]] = {arm: [] for arm in ARMS}
            digests = set()
            for k in range(args.passes):
                for arm in ARMS if k % 2 == 0 else ARMS[::-1]:
                    r = _run_arm(arm, store)
                    digests.add(r.pop("digest"))
                    runs[arm].append(r)
            rows = medians(runs, COLUMNS)
            same = len(digests) == 1
            print(f"\n{store} ({_scene(store)}): for_view, medians of {args.passes} passes (ABBA), "
                  f"{'the same bits' if same else 'DIFFERENT BITS'}")
            print_table(rows, COLUMNS, "blocks / joined", label=16, width=12)
            out.append({"store": str(store), **_scene(store), "passes": args.passes,
                        "same": same, "rows": rows})
            if not same:
                raise AssertionError(f"{store}: the arms' vertex radiance differs")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "operator.json").write_text(json.dumps(out, indent=1))
    return {"stores": out}


if __name__ == "__main__":
    main()
