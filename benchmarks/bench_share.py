"""One-point rows for low-power shooters (``--sample-share``) against penumbra sampling for
every shot, in one process (issue 12, items 3 and 5).

For each scene (the bundled Cornell box; ``--scene PATH`` with ``--config TOML`` adds one, e.g.
RenderPark's classroom, which is not in the repository), the solve alone (steps 1–2 done
once) with ``--shots`` shots at ``sample_share = 0`` (every row sampled) and at each of
``--shares``, alternated ``--repeat`` times (medians, in this process, both cores): seconds,
rows computed sampled and from one point, and the relative RMS distance of ``B`` from a
reference solve of twice the shots at share 0 (the unconverged remainder included, so the
share-0 row shows what the shots alone leave).

``python -m benchmarks.bench_share [--scene PATH --config TOML] [--shots N] [--shares S,S]
[--repeat N]``; writes ``benchmarks/results/share.json``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

import numpy as np

from daskrad import direct, solve
from daskrad.distributed.executor import InProcess
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
CORNELL = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"


def _solve(light, settings):
    """``(solution, keys shot)`` of one solve on a fresh in-process executor."""
    ex = InProcess()
    keys: list[int] = []
    shots = ex.shots

    def recorded(n, k):
        keys.extend(np.asarray(k).tolist())
        return shots(n, k)

    ex.shots = recorded
    try:
        sol = solve.radiosity(light, settings, ex)
    finally:
        ex.close()
    return sol, np.array(keys, np.int64)


def _rel_rms(a, b) -> float:
    return float(np.sqrt(((a - b) ** 2).mean() / (b ** 2).mean()))


def bench_scene(path, config, shots: int, shares: list[float], repeat: int) -> dict:
    scene = load_scene(path, config)
    base = Settings(max_iterations=shots, tolerance=0.0)
    light = direct.light(scene, preprocess(scene, base), base, InProcess())
    n_patches = light.mesh.hierarchy.n_patches
    reference, _ = _solve(light, base.replace(max_iterations=2 * shots, sample_share=0.0))
    rows = {}
    for share in [0.0, *shares]:
        rows[share] = {"seconds": [], "sample_share": share}
    for _ in range(repeat):
        for share in rows:
            sol, keys = _solve(light, base.replace(sample_share=share))
            r = rows[share]
            r["seconds"].append(sol.seconds)
            r["sampled_rows"] = len(set(keys[keys < n_patches].tolist()))
            r["one_point_rows"] = len(set(keys[keys >= n_patches].tolist()))
            r["one_point_shots"] = int((keys >= n_patches).sum())
            r["rel_rms_to_reference"] = _rel_rms(sol.radiosity, reference.radiosity)
    out = {"scene": Path(path).name, "elements": int(light.mesh.hierarchy.n_elements),
           "patches": int(n_patches), "shots": shots, "rows": []}
    plain = statistics.median(rows[0.0]["seconds"])
    for r in rows.values():
        r["median_seconds"] = statistics.median(r["seconds"])
        r["speedup"] = plain / r["median_seconds"]
        out["rows"].append(r)
    return out


def main(argv: list[str] | None = None) -> list:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_share")
    parser.add_argument("--scene", help="another scene (OBJ or MGF), e.g. RenderPark's classroom")
    parser.add_argument("--config", help="its TOML sidecar (camera)")
    parser.add_argument("--shots", type=int, default=None,
                        help="shots per solve (default: 1,500 for the Cornell box, 4,000 else)")
    parser.add_argument("--shares", default="0.01,0.03",
                        help="sample shares to compare with 0, comma-separated")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args([] if argv is None else argv)
    shares = [float(s) for s in args.shares.split(",")]
    scenes = [(CORNELL, None, args.shots or 1500)]
    if args.scene:
        scenes.append((args.scene, args.config, args.shots or 4000))
    results = []
    for path, config, shots in scenes:
        r = bench_scene(path, config, shots, shares, args.repeat)
        results.append(r)
        print(f"\n{r['scene']}: {r['elements']:,} elements, {r['patches']:,} patches, "
              f"{shots:,} shots (solve only, medians of {args.repeat})")
        print(f"{'share':>8} {'seconds':>8} {'speedup':>8} {'sampled':>8} {'1-point':>8} "
              f"{'1-pt shots':>10} {'RMS to ref':>10}")
        for row in r["rows"]:
            print(f"{row['sample_share']:>8g} {row['median_seconds']:>8.2f} "
                  f"{row['speedup']:>8.2f} {row['sampled_rows']:>8} {row['one_point_rows']:>8} "
                  f"{row['one_point_shots']:>10} {row['rel_rms_to_reference']:>10.2e}")
        sys.stdout.flush()
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "share.json").write_text(json.dumps(results, indent=1))
    return results


if __name__ == "__main__":
    main(sys.argv[1:])
