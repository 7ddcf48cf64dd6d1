"""What a resume costs: step 2 read back from the store against computed again.

A finished run of each scene (``--shots`` shots) is continued with ``--more`` shots more
(``--resume``), ``--repeat`` times per arm, the arms alternated in this process (a first
continuation, not counted, warms the imports). Each continuation starts from a fresh copy
of the same finished store. The arms:

- ``read back``: the store as a run writes it; the resume takes the direct pass and the
  adaptive subdivision from ``internal/context/direct_state`` (the default);
- ``computed``: that group removed from the copy first (a store of an older daskrad, and
  what every resume did before): the resume runs the direct pass and the subdivision again,
  and writes the group anew (which a resume before it did not: ~0.1–0.4 s of graz's solve
  step, small beside its direct step).

Both arms give the same bits (checked: every continuation's EXR against the first's).
Reported: medians of the whole continuation's wall seconds and of its steps (the report's
``seconds``: preprocess, direct, solve, render).

``python -m benchmarks.bench_resume [--scene PATH ...] [--shots N] [--more N] [--repeat N]
[--workers N]``; the default scene is the Cornell box of ``scenes/``; furnished rooms such as the
converted MGF scenes may be passed by path (never commit them). Writes
``benchmarks/results/resume.json`` (an entry per scene, by file name: a run replaces the
entries of its scenes and keeps the others).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks.arms import medians, print_table
from daskrad.io.image import read_exr
from daskrad.output import Outputs
from daskrad.run import run
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
CORNELL = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"
ARMS = ("read back", "computed")
STEPS = ("preprocess", "direct", "solve", "render")


def continuation(scene: Path, finished: Path, work: Path, settings: Settings,
                 arm: str) -> dict:
    """One continuation of ``finished`` (the .exr of a finished run of ``scene``; its files
    are copied into the empty folder ``work`` first) with ``settings``: the wall seconds,
    the report's step seconds and the image."""
    for src in finished.parent.iterdir():
        (shutil.copytree if src.is_dir() else shutil.copy2)(src, work / src.name)
    out = work / finished.name
    if arm == "computed":
        shutil.rmtree(Outputs(out).store / "internal" / "context" / "direct_state")
    t = time.perf_counter()
    report = run(scene, out, settings, progress=False, resume=True)
    seconds = time.perf_counter() - t
    return {"total": seconds, **{s: report["seconds"][s] for s in STEPS},
            "resumed_from": report["resumed_from"], "shots": report["iterations"],
            "elements": report["counts"]["elements"], "image": read_exr(out)}


def bench_scene(scene: Path, shots: int, more: int, repeat: int, workers: int) -> dict:
    first = Settings(workers=workers, max_iterations=shots)
    settings = first.replace(max_iterations=shots + more)
    runs: dict[str, list[dict]] = {arm: [] for arm in ARMS}
    with tempfile.TemporaryDirectory(prefix="daskrad-resume-") as tmp:
        finished = Path(tmp) / "finished" / "run.exr"
        finished.parent.mkdir()
        run(scene, finished, first, progress=False)
        work = Path(tmp) / "warm"
        work.mkdir()
        reference = continuation(scene, finished, work, settings, ARMS[0])["image"]
        for k in range(repeat):
            for arm in ARMS:
                work = Path(tmp) / f"{arm.replace(' ', '_')}{k}"
                work.mkdir()
                r = continuation(scene, finished, work, settings, arm)
                if not np.array_equal(r.pop("image"), reference):
                    raise AssertionError(f"{scene.name}, {arm}: the image differs")
                runs[arm].append(r)
                shutil.rmtree(work)
    columns = ("total", *STEPS)
    rows = medians(runs, columns)
    one = runs[ARMS[0]][0]
    print(f"\n{scene.name}, {one['elements']:,} elements: {shots} shots continued to "
          f"{one['shots']} (from shot {one['resumed_from']}), workers {workers}; wall "
          f"seconds, medians of {repeat} alternated continuations")
    print_table(rows, columns)
    return {"scene": str(scene), "shots": shots, "more": more, "workers": workers,
            "repeat": repeat, "rows": rows}


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(prog="bench_resume", description=__doc__.split("\n")[0])
    parser.add_argument("--scene", type=Path, action="append", default=[])
    parser.add_argument("--shots", type=int, default=320)
    parser.add_argument("--more", type=int, default=160)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--workers", type=int, default=0)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if
                             __name__ == "__main__" else [])
    results = [bench_scene(scene, args.shots, args.more, args.repeat, args.workers)
               for scene in (args.scene or [CORNELL])]
    # the scenes measured now replace their earlier entries; the others are kept (a furnished
    # room takes minutes, the Cornell box seconds: they are run apart)
    path = RESULTS / "resume.json"
    done = {r["scene"] for r in results}
    kept = [r for r in (json.loads(path.read_text()) if path.exists() else [])
            if Path(r["scene"]).name not in {Path(d).name for d in done}]
    RESULTS.mkdir(exist_ok=True)
    path.write_text(json.dumps(kept + results, indent=1))
    return results


if __name__ == "__main__":
    main()
