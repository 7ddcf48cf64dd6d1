"""The two-arm tables of the benchmarks that alternate a change against what it replaces
(bench_client, bench_resume, bench_store, bench_leaves): medians per arm and the first arm's
ratio to the second, measured in one run; and the environment of an arm run as a process."""

from __future__ import annotations

import os
import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def process_env(**extra: str) -> dict:
    """The environment of a benchmark's ``daskrad`` process: this one's, with ``extra`` set and
    the repository first on ``PYTHONPATH`` (the arm runs this checkout's code)."""
    env = dict(os.environ, **extra)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return env


def medians(runs: dict[str, list[dict]], columns) -> list[dict]:
    """One row per arm of ``runs`` (``{arm: [one pass's {column: seconds}, ...]}``, in the
    arms' order): ``{"arm", each column's median over the passes (0 where a pass lacks it),
    "passes"}``."""
    return [{"arm": arm, **{c: statistics.median(r.get(c, 0.0) for r in done)
                            for c in columns}, "passes": done}
            for arm, done in runs.items()]


def print_table(rows: list[dict], columns, ratio: str = "ratio", label: int = 12,
                width: int = 12, digits: int = 3) -> None:
    """Print ``rows`` (:func:`medians`) under a header of ``columns``, then the first row's
    ratio to the second's per column (nan where the second is 0)."""
    print(f"{'arm':<{label}}" + "".join(f"{c:>{width}}" for c in columns))
    for r in rows:
        print(f"{r['arm']:<{label}}" + "".join(f"{r[c]:>{width}.{digits}f}" for c in columns))
    first, second = rows[0], rows[1]
    print(f"{ratio:<{label}}" + "".join(
        f"{(first[c] / second[c] if second[c] else float('nan')):>{width}.2f}"
        for c in columns))
