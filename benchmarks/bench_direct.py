"""The direct pass's vertex ranges: levels of adaptive subdivision cut into tasks for every
core (issue 12, items 1 and 3).

Step 2 computes the direct light at the mesh's vertices in ranges (``direct.batches``), then
at the vertices each level of subdivision adds. A level adds a few hundred to a few thousand
vertices; in ranges of 2,048 it ran as one or two tasks, on one core. This benchmark times
step 2 alone (steps 1 done once) in this process on every core, alternating the arms
``--repeat`` times, and reports medians and whether the irradiance is the same bits:

- ``one range per 2,048``: :data:`daskrad.direct.BATCH_SPLIT` 1 (the code before);
- ``at least 8 a level``: the default, each range cut into 8 tasks of at least 256 vertices.

and the same for the window method's lights, the irradiance compared (relative RMS and
largest change, of the largest value):

- ``patches``: :data:`daskrad.direct.MERGE_LAMPS` off, each emitting patch a light;
- ``lamps``: the default, an emitting polygon split into patches one light
  (:func:`daskrad.direct.lamps_of`).

Scenes: the Cornell box and the lit room of ``scenes/`` at their own sizes, the Cornell box at
element size 7 (~73,000 elements), and ``--scene PATH`` (``--config TOML``) for another.

``python -m benchmarks.bench_direct [--scene PATH --config TOML] [--repeat N]``; writes
``benchmarks/results/direct.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from daskrad import direct
from daskrad.distributed.executor import InProcess
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"
ARMS = {"one range per 2,048": 1, "at least 8 a level": 8}
#: Each comparison: the module flag of :mod:`daskrad.direct` and its value in each arm (the
#: second arm is the default).
COMPARISONS = {"ranges": ("BATCH_SPLIT", ARMS),
               "lamps": ("MERGE_LAMPS", {"patches": False, "lamps": True})}


def bench_scene(label: str, path: Path, config, settings: Settings, repeat: int,
                comparison: str = "ranges") -> dict:
    flag, arms = COMPARISONS[comparison]
    scene = load_scene(path, config)
    mesh = preprocess(scene, settings)
    ex = InProcess()
    seconds: dict[str, list[float]] = {arm: [] for arm in arms}
    irradiance = {}
    keep = getattr(direct, flag)
    try:
        direct.light(scene, mesh, settings, ex)            # warms the kernels and the pool
        for k in range(repeat):
            for arm, value in (list(arms.items()) if k % 2 == 0 else list(arms.items())[::-1]):
                setattr(direct, flag, value)
                t = time.perf_counter()
                light = direct.light(scene, mesh, settings, ex)
                seconds[arm].append(time.perf_counter() - t)
                irradiance[arm] = light.irradiance
    finally:
        setattr(direct, flag, keep)
        ex.close()
    before, after = irradiance.values()
    same = before.shape == after.shape and bool(np.array_equal(before, after))
    scale = max(np.abs(before).max(), 1e-300)
    return {"scene": label, "comparison": comparison,
            "vertices": len(light.mesh.hierarchy.vertices),
            "levels": light.levels, "threads": ex.threads,
            **{arm: statistics.median(v) for arm, v in seconds.items()},
            "passes": seconds, "same bits": same,
            "max relative change": None if before.shape != after.shape else
            float(np.abs(after - before).max() / scale),
            "relative RMS change": None if before.shape != after.shape else
            float(np.sqrt(((after - before) ** 2).mean() / (before**2).mean()))}


def _change(value: float | None) -> str:
    """A change column: ``None`` where the arms' subdivisions made other vertices."""
    return f"{'other mesh':>12}" if value is None else f"{value:>12.1e}"


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="bench_direct", description=__doc__.split("\n")[0])
    parser.add_argument("--scene", type=Path)
    parser.add_argument("--config", type=Path)
    parser.add_argument("--repeat", type=int, default=7)
    args = parser.parse_args(argv if argv is not None else sys.argv[1:] if
                             __name__ == "__main__" else [])
    cases = [("Cornell box", SCENES / "cornell_box.obj", None, Settings()),
             ("lit room", SCENES / "lit_room.obj", None, Settings()),
             ("Cornell box, element 7", SCENES / "cornell_box.obj", None,
              Settings(element_size=7.0))]
    if args.scene is not None:
        cases.append((args.scene.name, args.scene, args.config, Settings()))
    rows = [bench_scene(*case, args.repeat, comparison) for comparison in COMPARISONS
            for case in cases]
    print(f"\nStep 2 alone, in-process on every core: seconds, medians of {args.repeat} "
          "alternated runs")
    for comparison, (_, arms) in COMPARISONS.items():
        a, b = arms
        print(f"\n{'scene':<26}{'vertices':>10}{'levels':>8}{a:>22}{b:>22}{'ratio':>8}"
              f"{'same bits':>11}{'rel RMS':>12}{'largest':>12}")
        for r in rows:
            if r["comparison"] == comparison:
                print(f"{r['scene']:<26}{r['vertices']:>10,}{r['levels']:>8}{r[a]:>22.4f}"
                      f"{r[b]:>22.4f}{r[b] / r[a]:>8.2f}{str(r['same bits']):>11}"
                      f"{_change(r['relative RMS change'])}{_change(r['max relative change'])}")
    result = {"repeat": args.repeat, "rows": rows}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "direct.json").write_text(json.dumps(result, indent=1))
    return result


if __name__ == "__main__":
    main()
