"""Overshooting (``--relaxation ω``) against plain progressive refinement, in one process
(issue 12, items 3 and 5).

For each scene (the bundled Cornell box and lit room; ``--scene PATH --config TOML``, given
once per scene, adds others, e.g. RenderPark's MGF interiors, which are not in the
repository), the solve alone (steps 1–2 done once) to the default tolerance at ``ω = 1`` and
at each of ``--omegas``, alternated ``--repeat`` times (medians, in this process, both cores):
shots, rows computed (distinct row keys: a re-shot reuses its patch's row), seconds, and the
relative RMS distance of ``B`` from a reference solve at ``ω = 1`` to a thirtieth of the
tolerance (the error the stopping rule leaves, which a lower shot count must not buy by
stopping early). The default ω runs once more with each patch's row chosen afresh at every
shot (``solve.KEEP_ROWS = False``, the rule before each patch kept its first row), which let an
overshot solve end with ``B < 0`` (column ``B < 0``: elements below zero).

``python -m benchmarks.bench_relaxation [--scene PATH --config TOML]... [--omegas W,W]
[--repeat N]``; writes ``benchmarks/results/relaxation.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from benchmarks.bench_share import _rel_rms, _solve
from daskrad import direct, solve
from daskrad.distributed.executor import InProcess
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"
#: The reference's tolerance, as a share of the run's.
REFERENCE = 1.0 / 30.0


def bench_scene(path, config, omegas: list[float], repeat: int) -> dict:
    scene = load_scene(path, config)
    base = Settings(max_iterations=1_000_000)
    light = direct.light(scene, preprocess(scene, base), base, InProcess())
    h = light.mesh.hierarchy
    reference, _ = _solve(light, base.replace(relaxation=1.0,
                                              tolerance=base.tolerance * REFERENCE))
    # each ω with every patch keeping its first row (solve.KEEP_ROWS, the default), and the
    # default ω with rows chosen afresh at every shot (the rule before)
    arms = [(w, True) for w in [1.0, *omegas]] + [(base.relaxation, False)]
    rows = {arm: {"relaxation": arm[0], "keep_rows": arm[1], "seconds": []} for arm in arms}
    for _ in range(repeat):
        for (w, keep), r in rows.items():
            solve.KEEP_ROWS = keep
            try:
                sol, keys = _solve(light, base.replace(relaxation=w))
            finally:
                solve.KEEP_ROWS = True
            r["seconds"].append(sol.seconds)
            r["shots"] = int(sol.iteration)
            r["converged"] = bool(sol.converged)
            r["rows"] = len(set(keys.tolist()))
            r["rel_rms_to_reference"] = _rel_rms(sol.radiosity, reference.radiosity)
            r["negative_elements"] = int((sol.radiosity < 0).any(axis=1).sum())
            r["min_radiosity"] = float(sol.radiosity.min())
    out = {"scene": Path(path).name, "elements": int(h.n_elements),
           "patches": int(h.n_patches), "tolerance": base.tolerance,
           "reference_shots": int(reference.iteration), "rows": []}
    plain = rows[(1.0, True)]
    for r in rows.values():
        r["median_seconds"] = statistics.median(r["seconds"])
        r["speedup"] = statistics.median(plain["seconds"]) / r["median_seconds"]
        r["shots_ratio"] = r["shots"] / plain["shots"]
        out["rows"].append(r)
    return out


def main(argv: list[str] | None = None) -> list:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_relaxation")
    parser.add_argument("--scene", action="append", default=[],
                        help="another scene (OBJ or MGF); once per scene")
    parser.add_argument("--config", action="append", default=[],
                        help="its TOML sidecar (camera), in the order of --scene")
    parser.add_argument("--omegas", default="1.2,1.3,1.4,1.5",
                        help="relaxation factors to compare with 1, comma-separated")
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args([] if argv is None else argv)
    if len(args.config) not in (0, len(args.scene)):
        parser.error("give one --config per --scene, or none")
    omegas = [float(s) for s in args.omegas.split(",")]
    scenes = [(SCENES / "cornell_box.obj", None), (SCENES / "lit_room.obj", None),
              *zip(args.scene, args.config or [None] * len(args.scene), strict=True)]
    results = []
    for path, config in scenes:
        r = bench_scene(path, config, omegas, args.repeat)
        results.append(r)
        print(f"\n{r['scene']}: {r['elements']:,} elements, {r['patches']:,} patches, to "
              f"tolerance {r['tolerance']:g} (reference: {r['reference_shots']:,} shots; "
              f"solve only, medians of {args.repeat})")
        print(f"{'omega':>6} {'rows kept':>9} {'shots':>7} {'ratio':>6} {'rows':>6} "
              f"{'seconds':>8} {'speedup':>8} {'RMS to ref':>10} {'B < 0':>6}")
        for row in r["rows"]:
            print(f"{row['relaxation']:>6g} {'yes' if row['keep_rows'] else 'no':>9} "
                  f"{row['shots']:>7,} {row['shots_ratio']:>6.2f} "
                  f"{row['rows']:>6,} {row['median_seconds']:>8.2f} {row['speedup']:>8.2f} "
                  f"{row['rel_rms_to_reference']:>10.2e} {row['negative_elements']:>6,}")
        sys.stdout.flush()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "relaxation.json").write_text(json.dumps(results, indent=1))
    return results


if __name__ == "__main__":
    main(sys.argv[1:])
