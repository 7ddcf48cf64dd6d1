"""Where a shooter's row is taken from, against what it replaced (issue 12, item 3).

:func:`daskrad.formfactor.shooting.shooter_points` is run for every patch of a scene's mesh
after the direct pass (the mesh the solve shoots from), once with the kernel that finds the
points inside a closed object (:func:`daskrad.kernels.blockers.enclosed_points`) and once with
the NumPy it replaced (kept here as the reference arm: a batch of ``closest_hit`` rays, every
probe of every point, and NumPy's products), alternated ``--repeat`` times, one thread:
medians of the whole pass, and whether both give the same points and weights (bit for bit).

Scenes: the bundled Cornell box and lit room, and ``--scene PATH`` (e.g. RenderPark's MGF
scenes converted to OBJ, not in the repository).

``python -m benchmarks.bench_rows [--scene PATH ...] [--repeat N]``; writes
``benchmarks/results/rows.json``.
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
from daskrad.formfactor import shooting
from daskrad.kernels.geometry import orthonormal_basis
from daskrad.kernels.grid import closest_hit
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
SCENES = Path(__file__).parent.parent / "scenes"


def numpy_enclosed(grid, tri_element, elem_normal, two_sided, elem_polygon, points, normal,
                   lift, probes):
    """The NumPy test :func:`daskrad.kernels.blockers.enclosed_points` replaced (same
    arguments, same answer)."""
    t1x, t1y, t1z, t2x, t2y, t2z = orthonormal_basis(*normal)
    frame = np.array([[t1x, t1y, t1z], [t2x, t2y, t2z], normal])
    dirs = probes @ frame
    origins = np.repeat(points + lift * normal, len(dirs), axis=0)
    d = np.tile(dirs, (len(points), 1))
    _, tri, _, _ = closest_hit(grid, origins, d, 0.0, np.inf)
    back = np.zeros(len(tri), bool)
    hit = tri >= 0
    elem = tri_element[tri[hit]]
    back[hit] = ((np.einsum("ij,ij->i", elem_normal[elem], d[hit]) > 0.0)
                 & ~two_sided[elem_polygon[elem]])
    return back.reshape(len(points), len(dirs)).all(axis=1)


def _pass(ctx: shooting.ShootContext) -> tuple[list, float]:
    t = time.perf_counter()
    out = [shooting.shooter_points(ctx, p) for p in range(len(ctx.patch_area))]
    return out, time.perf_counter() - t


def measure(path: Path, repeat: int) -> dict:
    settings = Settings(workers=0)
    scene = load_scene(path)
    ex = InProcess(threads=1)
    mesh = direct.light(scene, preprocess(scene, settings), settings, ex).mesh
    ex.close()
    h = mesh.hierarchy
    ctx = shooting.make_context(h, settings.method, settings.resolution, grid=mesh.grid,
                                tri_element=mesh.tri_element)
    arms = {"numpy": numpy_enclosed, "kernel": shooting.enclosed_points}
    seconds: dict = {a: [] for a in arms}
    points: dict = {}
    try:
        for k in range(repeat + 1):
            for arm in (list(arms) if k % 2 == 0 else list(arms)[::-1]):
                shooting.enclosed_points = arms[arm]
                points[arm], s = _pass(ctx)
                if k:                                      # the first pass compiles or loads
                    seconds[arm].append(s)
    finally:
        shooting.enclosed_points = arms["kernel"]
    same = all(np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
               for a, b in zip(points["numpy"], points["kernel"], strict=True))
    sampled = sum(len(w) > 1 for _, w in points["kernel"])
    med = {a: statistics.median(v) for a, v in seconds.items()}
    return {"scene": path.name, "patches": int(h.n_patches), "elements": int(h.n_elements),
            "patches_sampled": int(sampled), "numpy_s": med["numpy"], "kernel_s": med["kernel"],
            "speedup": med["numpy"] / med["kernel"], "same_points": bool(same)}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_rows")
    parser.add_argument("--scene", type=Path, action="append", default=[])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args([] if argv is None else argv)
    rows = [measure(p, args.repeat)
            for p in [SCENES / "cornell_box.obj", SCENES / "lit_room.obj", *args.scene]]
    print(f"shooter_points of every patch, one thread, medians of {args.repeat} alternated: "
          "the enclosed-point test in NumPy and as a kernel")
    print(f"{'scene':<16}{'patches':>8}{'sampled':>8}{'numpy s':>9}{'kernel s':>9}{'x':>6}"
          "  same points")
    for r in rows:
        print(f"{r['scene']:<16}{r['patches']:>8,}{r['patches_sampled']:>8,}"
              f"{r['numpy_s']:>9.3f}{r['kernel_s']:>9.3f}{r['speedup']:>6.2f}"
              f"  {r['same_points']}")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "rows.json").write_text(json.dumps(rows, indent=2) + "\n")
    return {"rows": rows}


if __name__ == "__main__":
    main(sys.argv[1:])
