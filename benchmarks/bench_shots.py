"""Seconds per shot of the solver (issue 3): against element count and resolution, and the
furnace error against run time.

A *shot* here is the whole form-factor task of one patch
(:func:`daskrad.formfactor.shooting.shoot_row`: hemisphere pass, near-field correction) plus the
client's update; medians of repeats.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from daskrad import solve
from daskrad.formfactor import shooting
from daskrad.mesh import build_hierarchy
from daskrad.run import solve_scene
from daskrad.scene import box_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"


def _box(elements: int):
    """A closed 1×1.5×2 box meshed to about ``elements`` elements (one patch ≈ 16 elements)."""
    area = 2 * (1 * 1.5 + 1 * 2 + 1.5 * 2)
    esize = math.sqrt(area / elements)
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=0.5, emission_per_face=1 / math.pi)
    return scene, build_hierarchy(scene, 4 * esize, esize)


def time_shots(h, resolution: int, shots: int = 12, repeats: int = 3) -> float:
    """Median seconds per shot: form factors of ``shots`` patches and their updates."""
    ctx = shooting.make_context(h, "hemisphere", resolution)
    refl = np.full((h.n_elements, 3), 0.5)
    ids = np.linspace(0, h.n_patches - 1, shots).astype(int)
    shooting.shoot_rows(ctx, ids[:1])  # compile / warm the numba cache
    times = []
    for _ in range(repeats):
        sol = solve.initial_solution(h, np.ones((h.n_elements, 3)))
        t = time.perf_counter()
        for p, (eids, f) in zip(ids, shooting.shoot_rows(ctx, ids), strict=True):
            solve.apply_shot(h, refl, sol, int(p), eids, f)
        times.append((time.perf_counter() - t) / shots)
    return float(np.median(times))


def main() -> dict:
    rows = []
    for n in (500, 5_000, 50_000):
        scene, h = _box(n)
        rows.append({"sweep": "elements", "elements": h.n_elements, "patches": h.n_patches,
                     "resolution": 256, "ms_per_shot": 1e3 * time_shots(h, 256)})
    scene, h = _box(50_000)
    for r in (64, 128, 256, 512):
        rows.append({"sweep": "resolution", "elements": h.n_elements, "patches": h.n_patches,
                     "resolution": r, "ms_per_shot": 1e3 * time_shots(h, r)})
    print(f"{'sweep':<11}{'elements':>9}{'patches':>8}{'R':>5}{'ms/shot':>9}")
    for row in rows:
        print(f"{row['sweep']:<11}{row['elements']:>9}{row['patches']:>8}"
              f"{row['resolution']:>5}{row['ms_per_shot']:>9.2f}")

    # furnace: B = E / (1 − ρ) exactly; error against run time as the tolerance tightens
    furnace = []
    scene = box_scene(size=(1.0, 1.5, 2.0), diffuse=0.8, emission_per_face=1 / math.pi)
    # warm every kernel of the pipeline first, so no row pays for numba's compilation
    solve_scene(scene, Settings(patch_size=0.25, element_size=0.0625, max_iterations=1))
    for tol in (1e-1, 1e-2, 1e-3, 1e-4):
        t = time.perf_counter()
        h, _, sol, _ = solve_scene(scene, Settings(patch_size=0.25, element_size=0.0625,
                                                   tolerance=tol, max_iterations=100_000))
        seconds = time.perf_counter() - t
        err = float(np.abs(sol.radiosity / 5.0 - 1.0).max())
        furnace.append({"tolerance": tol, "shots": sol.iteration, "seconds": seconds,
                        "max_relative_error": err, "elements": h.n_elements})
    print(f"\nfurnace rho=0.8 ({furnace[0]['elements']} elements): error against run time")
    print(f"{'tolerance':>10}{'shots':>7}{'seconds':>9}{'max rel err':>13}")
    for f in furnace:
        print(f"{f['tolerance']:>10g}{f['shots']:>7}{f['seconds']:>9.2f}"
              f"{f['max_relative_error']:>13.2e}")
    result = {"shots": rows, "furnace": furnace}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "shots.json").write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
