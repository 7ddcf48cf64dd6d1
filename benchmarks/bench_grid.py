"""Rays per second through the uniform voxel grid vs brute force (issue 2, item 5).

Scenes: a random triangle soup in the unit cube (triangle size ~ the mean spacing) and a
gridded surface (a height field, two triangles per square), each with 1k, 10k and 100k
triangles. Rays start at uniform points of the scene's box with uniform unit directions, as
secondary and shadow rays do; shadow rays (any hit) have ``tmax`` uniform in ``[0, diag]``.
Brute force tests every triangle, so it runs on fewer rays (2,000 at 100k triangles). Figures
are medians of several repeats after a warm-up on a few rays (compilation excluded).

``python -m benchmarks.bench_grid`` prints the table and writes ``benchmarks/results/grid.json``.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np

from daskrad.kernels import grid as G

RESULTS = Path(__file__).parent / "results" / "grid.json"
SIZES = (1_000, 10_000, 100_000)
GRID_RAYS = 100_000
BRUTE_RAYS = {1_000: 20_000, 10_000: 5_000, 100_000: 2_000}
REPEATS = 5
BRUTE_REPEATS = 3


def soup(rng, n):
    """``n`` random triangles in the unit cube, each about the mean spacing in size."""
    centres = rng.uniform(0.0, 1.0, (n, 1, 3))
    return centres + rng.normal(0.0, 0.5 / n ** (1 / 3), (n, 3, 3))


def surface(n):
    """A height field over the unit square with about ``n`` triangles."""
    m = max(1, int(round(np.sqrt(n / 2))))
    x, y = np.meshgrid(np.linspace(0, 1, m + 1), np.linspace(0, 1, m + 1), indexing="ij")
    p = np.stack([x, y, 0.2 * np.sin(6 * x) * np.cos(5 * y)], axis=-1)
    a, b, c, d = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    return np.concatenate([np.stack([a, b, c], -2).reshape(-1, 3, 3),
                           np.stack([a, c, d], -2).reshape(-1, 3, 3)])


def rays(rng, tris, n):
    lo, hi = tris.min(axis=(0, 1)), tris.max(axis=(0, 1))
    o = rng.uniform(lo, hi, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmax = rng.uniform(0.0, np.linalg.norm(hi - lo), n)
    return o, d, np.zeros(n), np.full(n, np.inf), tmax


def median_seconds(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def measure(rng, name, tris):
    t_build = median_seconds(lambda: G.build_grid(tris), 3)
    grid = G.build_grid(tris)
    n_tri = len(tris)
    o, d, tmin, tinf, tmax = rays(rng, tris, GRID_RAYS)
    nb = BRUTE_RAYS[min(BRUTE_RAYS, key=lambda k: abs(k - n_tri))]
    ob, db, tminb, tinfb, tmaxb = o[:nb], d[:nb], tmin[:nb], tinf[:nb], tmax[:nb]
    for fn in (G.closest_hit, G.closest_hit_brute):  # warm-up: compilation
        fn(grid, o[:8], d[:8], tmin[:8], tinf[:8])
    for fn in (G.any_hit, G.any_hit_brute):
        fn(grid, o[:8], d[:8], tmin[:8], tmax[:8])
    s_closest = median_seconds(lambda: G.closest_hit(grid, o, d, tmin, tinf), REPEATS)
    s_any = median_seconds(lambda: G.any_hit(grid, o, d, tmin, tmax), REPEATS)
    b_closest = median_seconds(
        lambda: G.closest_hit_brute(grid, ob, db, tminb, tinfb), BRUTE_REPEATS)
    b_any = median_seconds(lambda: G.any_hit_brute(grid, ob, db, tminb, tmaxb), BRUTE_REPEATS)
    # Sanity: the grid agrees with brute force on the brute-force rays.
    tg, ig, _, _ = G.closest_hit(grid, ob, db, tminb, tinfb)
    tb, ib, _, _ = G.closest_hit_brute(grid, ob, db, tminb, tinfb)
    agree = bool(np.array_equal(ig >= 0, ib >= 0)
                 and np.allclose(tg[ig >= 0], tb[ib >= 0], rtol=1e-9, atol=0)
                 and np.array_equal(G.any_hit(grid, ob, db, tminb, tmaxb),
                                    G.any_hit_brute(grid, ob, db, tminb, tmaxb)))
    hit_rate = float(np.mean(G.closest_hit(grid, o, d, tmin, tinf)[1] >= 0))
    return {
        "scene": name,
        "triangles": n_tri,
        "dims": [int(x) for x in grid.dims],
        "items_per_triangle": len(grid.cell_items) / n_tri,
        "build_s": t_build,
        "grid_rays": GRID_RAYS,
        "brute_rays": nb,
        "closest_grid_rays_per_s": GRID_RAYS / s_closest,
        "closest_brute_rays_per_s": nb / b_closest,
        "any_grid_rays_per_s": GRID_RAYS / s_any,
        "any_brute_rays_per_s": nb / b_any,
        "closest_hit_rate": hit_rate,
        "agrees_with_brute_force": agree,
    }


def on_threads(threads: int, fn, *args):
    """``fn(*args)`` with numba's threads set to ``threads`` (restored after)."""
    import numba

    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        return fn(*args)
    finally:
        numba.set_num_threads(before)


def threads_table(rng) -> list[dict]:
    """The client's two grid kernels on one thread and on every core, alternated
    (``REPEATS`` pairs, medians): registering the triangles (:func:`G.build_grid`, which a
    run does for its element and polygon grids, again after subdivision) and the view
    region's primary rays (:func:`G.located_triangles`, a furnished room's 480,000), with
    the same grid and the same triangles either way."""
    import numba

    cores = numba.get_num_threads()
    rows = []
    print(f"\nthe client's grid kernels, 1 thread against {cores} (medians of {REPEATS} "
          "alternated pairs)")
    print(f"{'scene':8} {'tris':>7} {'build 1':>9} {f'build {cores}':>9} {'ratio':>6} "
          f"{'rays 1':>9} {f'rays {cores}':>9} {'ratio':>6} same")
    for name, tris in (("soup", soup(rng, 100_000)), ("surface", surface(100_000))):
        grid = G.build_grid(tris)
        loc = G.locator(tris)
        o, d, _, _, _ = rays(rng, tris, 480_000)
        G.located_triangles(grid, loc, grid, o[:8], d[:8], 0.0, np.inf)    # compile
        times = {k: [] for k in ("build 1", "build n", "rays 1", "rays n")}
        for _ in range(REPEATS):
            for label, threads in (("1", 1), ("n", cores)):
                t = time.perf_counter()
                built = on_threads(threads, G.build_grid, tris)
                times[f"build {label}"].append(time.perf_counter() - t)
                t = time.perf_counter()
                hit = on_threads(threads, G.located_triangles, grid, loc, grid, o, d, 0.0,
                                 np.inf)
                times[f"rays {label}"].append(time.perf_counter() - t)
                if label == "1":
                    ref = (built, hit)
        same = bool(np.array_equal(ref[0].cell_start, built.cell_start)
                    and np.array_equal(ref[0].cell_items, built.cell_items)
                    and np.array_equal(ref[1], hit))
        m = {k: float(np.median(v)) for k, v in times.items()}
        rows.append({"scene": name, "triangles": len(tris), "threads": cores, **m,
                     "same": same})
        print(f"{name:8} {len(tris):>7} {m['build 1']:>8.3f}s {m['build n']:>8.3f}s "
              f"{m['build n'] / m['build 1']:>6.2f} {m['rays 1']:>8.3f}s {m['rays n']:>8.3f}s "
              f"{m['rays n'] / m['rays 1']:>6.2f} {'yes' if same else 'NO'}", flush=True)
    return rows


def main() -> dict:
    rng = np.random.default_rng(2026)
    rows = []
    header = (f"{'scene':8} {'tris':>7} {'dims':>13} {'build':>7} {'closest grid':>13} "
              f"{'brute':>9} {'speedup':>8} {'any grid':>10} {'brute':>9} {'speedup':>8} "
              f"{'hit%':>5} ok")
    print(header)
    print("-" * len(header))
    for name in ("soup", "surface"):
        for n in SIZES:
            tris = soup(rng, n) if name == "soup" else surface(n)
            r = measure(rng, name, tris)
            rows.append(r)
            cg, cb = r["closest_grid_rays_per_s"], r["closest_brute_rays_per_s"]
            ag, ab = r["any_grid_rays_per_s"], r["any_brute_rays_per_s"]
            dims = "x".join(str(x) for x in r["dims"])
            print(f"{name:8} {r['triangles']:>7} {dims:>13} {r['build_s']:>6.3f}s "
                  f"{cg:>11.3g}/s {cb:>7.3g}/s {cg / cb:>7.0f}x {ag:>8.3g}/s {ab:>7.3g}/s "
                  f"{ag / ab:>7.0f}x {100 * r['closest_hit_rate']:>4.0f}% "
                  f"{'yes' if r['agrees_with_brute_force'] else 'NO'}", flush=True)
    result = {
        "benchmark": "grid",
        "units": "rays per second (median of repeats), build in seconds",
        "density": G.DEFAULT_DENSITY,
        "repeats": REPEATS,
        "brute_repeats": BRUTE_REPEATS,
        "python": platform.python_version(),
        "machine": platform.machine(),
        "rows": rows,
        "threads": threads_table(rng),
    }
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps(result, indent=2) + "\n")
    return result


if __name__ == "__main__":
    main()
