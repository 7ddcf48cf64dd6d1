"""What the client's store writes cost: every chunk written, against zarr's default.

zarr skips a chunk that holds only the fill value, and decides it by comparing each chunk
with a full array of the fill value before it writes it. The store writes every chunk
instead (:data:`daskrad.distributed.store.WRITE_EMPTY_CHUNKS`). This benchmark makes one
short run of a scene (default: the Cornell box at element size 7, ~73,000 elements), reads
back every array its store holds (the public results, the checkpoint slots, the task
contexts' blobs: what a run writes, with their own sizes, dtypes and compression), and
writes them all again into a scratch store the way the store writes them, alternating the
two arms ``--repeat`` times; medians of the seconds per kind of array.

``python -m benchmarks.bench_store [--scene PATH] [--element-size S] [--repeat N]``; writes
``benchmarks/results/store.json``.

``--blobs``: the task contexts of that run's store (its render context and step 2's state)
written again by :meth:`~daskrad.distributed.store.Store.put_context`, each chunk filled from
the context's arrays (:data:`daskrad.distributed.store.STREAM_BLOBS`) against the arrays joined
into one blob first, as a run writes them: each pass in a fresh process (a run writes a
context once, into pages it has not touched yet), the arms alternated ABBA; seconds and the
rise of the process's peak resident memory (``VmHWM``) while it writes, medians. Writes
``benchmarks/results/store_blobs.json``.
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
import zarr

from benchmarks.arms import medians, print_table, process_env
from daskrad.distributed import store as st
from daskrad.run import run
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
CORNELL = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"
ARMS = {"every chunk": True, "zarr default": False}
BLOB_ARMS = {"chunk by chunk": True, "joined": False}


def _kind(name: str) -> str:
    if name.startswith("internal/checkpoint"):
        return "checkpoint slots"
    if name.startswith("internal/context"):
        return "context blobs"
    return "public arrays"


def arrays_of(path: Path) -> dict[str, tuple[np.ndarray, bool, tuple]]:
    """Every array of the store at ``path``: ``{name: (data, compressed, chunks)}``."""
    root = zarr.open_group(path, mode="r")
    return {name: (arr[...], bool(arr.compressors), arr.chunks)
            for name, arr in root.members(max_depth=None) if isinstance(arr, zarr.Array)}


def write_all(arrays: dict, path: Path) -> dict[str, float]:
    """Write ``arrays`` into a new store at ``path`` as the store writes them; seconds per
    kind of array."""
    group = zarr.open_group(path, mode="w")
    seconds: dict[str, float] = {}
    for name, (data, compressed, chunks) in arrays.items():
        t = time.perf_counter()
        st.write_array(group, name, data, compress=compressed, chunks=chunks)
        seconds[_kind(name)] = seconds.get(_kind(name), 0.0) + time.perf_counter() - t
    seconds["all"] = sum(seconds.values())
    return seconds


def _peak_mib() -> float:
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmHWM")) / 1024


def put_contexts(store: Path, streamed: bool) -> dict[str, float]:
    """Every task context of ``store`` read back, then written into a scratch store beside it
    with :data:`~daskrad.distributed.store.STREAM_BLOBS` set to ``streamed``: seconds per
    context, ``all``, and ``peak MiB``, how far the peak resident memory rose meanwhile."""
    contexts = {kind: st.load_context(str(store), kind) for kind, _ in
                zarr.open_group(store, mode="r")["internal/context"].members()}
    st.STREAM_BLOBS = streamed
    scratch = st.Store(store.with_name(f"scratch-{streamed}.zarr"))
    scratch.group = zarr.open_group(scratch.path, mode="w")
    seconds: dict[str, float] = {}
    before = _peak_mib()
    for kind, ctx in sorted(contexts.items()):
        t = time.perf_counter()
        scratch.put_context(kind, ctx)
        seconds[kind] = time.perf_counter() - t
    seconds["all"] = sum(seconds.values())
    seconds["peak MiB"] = _peak_mib() - before
    return seconds


def blobs(args, tmp: Path) -> dict:
    out = tmp / "run.exr"
    report = run(args.scene, out, Settings(workers=0, element_size=args.element_size,
                                           max_iterations=64), progress=False)
    store = out.with_suffix(".zarr")
    megabytes = {kind: g["blob"].nbytes / 2**20 for kind, g in
                 zarr.open_group(store, mode="r")["internal/context"].members()}
    runs: dict[str, list[dict]] = {arm: [] for arm in BLOB_ARMS}
    for k in range(args.repeat):
        order = list(BLOB_ARMS.items())
        for arm, streamed in (order if k % 2 == 0 else order[::-1]):
            done = subprocess.run(
                [sys.executable, "-m", "benchmarks.bench_store", "--put", str(store),
                 "--streamed", str(int(streamed))], env=process_env(), check=True,
                capture_output=True, text=True)
            runs[arm].append(json.loads(done.stdout.strip().splitlines()[-1]))
    columns = list(runs[next(iter(BLOB_ARMS))][0])
    rows = medians(runs, columns)
    print(f"\n{args.scene.name}, {report['counts']['elements']:,} elements: its task contexts ("
          + ", ".join(f"{k} {v:.1f} MiB" for k, v in sorted(megabytes.items()))
          + f") written again in fresh processes; seconds and peak MiB, medians of "
          f"{args.repeat} passes, ABBA")
    print_table(rows, columns, label=16, width=14, digits=4)
    result = {"scene": str(args.scene), "element_size": args.element_size,
              "elements": report["counts"]["elements"], "blob_mebibytes": megabytes,
              "repeat": args.repeat, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "store_blobs.json").write_text(json.dumps(result, indent=1))
    return result


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="bench_store", description=__doc__.split("\n")[0])
    parser.add_argument("--scene", type=Path, default=CORNELL)
    parser.add_argument("--element-size", type=float, default=7.0)
    parser.add_argument("--repeat", type=int, default=8, help="passes (even: ABBA balanced)")
    parser.add_argument("--blobs", action="store_true",
                        help="the task contexts' blobs, chunk by chunk against joined")
    parser.add_argument("--put", type=Path, help=argparse.SUPPRESS)   # one --blobs pass
    parser.add_argument("--streamed", type=int, default=1, help=argparse.SUPPRESS)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if
                             __name__ == "__main__" else [])
    if args.put is not None:
        seconds = put_contexts(args.put, bool(args.streamed))
        print(json.dumps(seconds))
        return seconds
    if args.blobs:
        with tempfile.TemporaryDirectory(prefix="daskrad-store-") as tmp:
            return blobs(args, Path(tmp))
    before = st.WRITE_EMPTY_CHUNKS
    runs: dict[str, list[dict]] = {arm: [] for arm in ARMS}
    with tempfile.TemporaryDirectory(prefix="daskrad-store-") as tmp:
        out = Path(tmp) / "run.exr"
        report = run(args.scene, out, Settings(workers=0, element_size=args.element_size,
                                               max_iterations=64), progress=False)
        arrays = arrays_of(out.with_suffix(".zarr"))
        megabytes = sum(a[0].nbytes for a in arrays.values()) / 2**20
        try:
            for k in range(args.repeat + 1):              # the first pass warms up
                for arm, every in ARMS.items():
                    st.WRITE_EMPTY_CHUNKS = every
                    seconds = write_all(arrays, Path(tmp) / f"{arm}{k}.zarr")
                    if k:
                        runs[arm].append(seconds)
        finally:
            st.WRITE_EMPTY_CHUNKS = before
    columns = list(runs[next(iter(ARMS))][0])
    rows = medians(runs, columns)
    print(f"\n{args.scene.name}, {report['counts']['elements']:,} elements: its store's "
          f"{len(arrays)} arrays ({megabytes:.1f} MiB) written again; seconds, medians of "
          f"{args.repeat} alternated passes")
    print_table(rows, columns, label=14, width=18, digits=4)
    result = {"scene": str(args.scene), "element_size": args.element_size,
              "elements": report["counts"]["elements"], "arrays": len(arrays),
              "mebibytes": megabytes, "repeat": args.repeat, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "store.json").write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
