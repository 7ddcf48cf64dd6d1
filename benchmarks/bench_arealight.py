"""Area lights at vertices: shadow rays against the paper's window method, time against error.

The Cornell box lit by its area light (two emitting patches), at two meshes: the default
elements (30 mm) and fine ones (15 mm). For every element vertex the direct irradiance from
the light is computed by the two methods of :data:`daskrad.direct.AREA_METHODS`:

- ``rays``: Lambert's unoccluded term × visibility from ``s × s`` stratified shadow rays;
- ``hemisphere``: Lambert's term × the visible fraction of the light's pixels in an ``R × R``
  z-buffer over its min–max window on the hemisphere base (:mod:`daskrad.kernels.arealight`).

Both are exact where the light is wholly visible or hidden, so errors are reported over all
vertices and over the **penumbra** alone (vertices where the reference is strictly between
0 and the unoccluded value, the only place the methods differ). References:

- ``hemisphere`` at ``R = 1024`` (its distance to ``R = 512`` is printed: converged);
- ``rays`` at 32 × 32 (independent of the window method; its distance to the first reference
  is printed, and it is its own sampling error, which shrinks with more rays).

Errors are relative: RMS of the difference over the RMS of the reference on the same
vertices, and the largest difference over the largest reference value. Seconds are the best
of three in-process runs of :func:`daskrad.direct.compute` (kernels compiled beforehand).
"""

from __future__ import annotations

import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from daskrad import direct, tolerances
from daskrad.kernels.arealight import area_irradiance_stats
from daskrad.kernels.grid import build_grid
from daskrad.mesh import build_hierarchy, default_sizes, hierarchy_triangles
from daskrad.scene import load_scene

RESULTS = Path(__file__).parent / "results"
SCENE = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"

RAYS = [1, 2, 3, 4, 6, 8, 12, 16]
WINDOWS = [4, 6, 8, 12, 16, 24, 32, 48, 64, 128]
REF_WINDOW = 1024
REF_RAYS = 32
MESHES = [("default elements (30 mm)", None), ("fine elements (15 mm)", 15.0)]


def _timed(ctx, n, repeat=3):
    best = np.inf
    H = None
    for _ in range(repeat):
        t = time.perf_counter()
        H = direct.compute(ctx, 0, n)
        best = min(best, time.perf_counter() - t)
    return H, best


def _err(H, ref, sel):
    d = (H - ref).sum(axis=1)[sel]
    r = ref.sum(axis=1)[sel]
    if not len(r):
        return {"relative_rms": 0.0, "relative_max": 0.0}
    return {"relative_rms": float(np.sqrt(np.mean(d**2)) / np.sqrt(np.mean(r**2))),
            "relative_max": float(np.abs(d).max() / np.abs(r).max())}


def _mesh(scene, element_size):
    patch, elem = default_sizes(scene)
    h = build_hierarchy(scene, patch, element_size or elem)
    grid = build_grid(hierarchy_triangles(h)[0])
    ctx = direct.make_context(scene, h, grid)
    # point and directional lights would add the same to both methods: area lights only
    ctx = replace(ctx, point_position=np.zeros((0, 3)), point_intensity=np.zeros((0, 3)),
                  dir_direction=np.zeros((0, 3)), dir_irradiance=np.zeros((0, 3)))
    return h, ctx


def _measure(name, ctx, n):
    hemi = replace(ctx, area_method="hemisphere")
    rays = replace(ctx, area_method="rays")
    ref, ref_s = _timed(replace(hemi, area_resolution=REF_WINDOW), n, 1)
    half = direct.compute(replace(hemi, area_resolution=REF_WINDOW // 2), 0, n)
    ref_rays, ref_rays_s = _timed(replace(rays, samples=REF_RAYS), n, 1)
    # unoccluded: the window method with an empty grid finds no occluder, V = 1
    lambert = direct.compute(replace(hemi, grid=build_grid(np.zeros((0, 3, 3)))), 0, n)
    total = ref.sum(axis=1)
    _, work = area_irradiance_stats(
        ctx.grid, ctx.area_points, ctx.normals, ctx.offset,
        ctx.offset * tolerances.HORIZON_EPS / tolerances.RAY_OFFSET, ctx.emitter_corners,
        ctx.emitter_count, ctx.emitter_normal, ctx.emitter_radiance, 4,
        np.radians(tolerances.EDGE_ANGLE_DEG))
    penumbra = (total > 0) & (total < lambert.sum(axis=1) * (1 - 1e-9))
    rows = []
    for method, values in (("rays", RAYS), ("hemisphere", WINDOWS)):
        for v in values:
            c = replace(rays, samples=v) if method == "rays" else replace(hemi,
                                                                         area_resolution=v)
            H, sec = _timed(c, n)
            rows.append({
                "method": method, "parameter": v,
                "label": f"rays {v}x{v}" if method == "rays" else f"window {v}x{v}",
                "seconds": sec, "us_per_vertex": 1e6 * sec / n,
                "vs_window_ref": _err(H, ref, slice(None)),
                "vs_window_ref_penumbra": _err(H, ref, penumbra),
                "vs_rays_ref": _err(H, ref_rays, slice(None)),
                "vs_rays_ref_penumbra": _err(H, ref_rays, penumbra),
            })
    return {
        "mesh": name, "vertices": n, "emitter_patches": int(len(ctx.emitter_corners)),
        "penumbra_vertices": int(penumbra.sum()),
        "lit_vertices": int((total > 0).sum()),
        "vertices_with_candidates": int((work > 0).sum()),
        "candidates_per_vertex": float(work.mean()),
        "reference_window": REF_WINDOW, "reference_window_seconds": ref_s,
        "reference_window_vs_half": _err(half, ref, penumbra),
        "reference_rays": REF_RAYS, "reference_rays_seconds": ref_rays_s,
        "reference_rays_vs_window_ref": _err(ref_rays, ref, penumbra),
        "configs": rows,
    }


def _choose(result) -> dict:
    """Equal error and equal time against the shipped ray default (4 × 4), penumbra errors
    against the converged window reference, on the default mesh."""
    rows = result["configs"]
    base = next(r for r in rows if r["method"] == "rays" and r["parameter"] == 4)
    target = base["vs_window_ref_penumbra"]["relative_rms"]
    out = {"baseline": base["label"], "baseline_seconds": base["seconds"],
           "baseline_penumbra_rms": target}
    for method in ("rays", "hemisphere"):
        mine = [r for r in rows if r["method"] == method]
        ok = [r for r in mine if r["vs_window_ref_penumbra"]["relative_rms"] <= target]
        cheapest = min(ok, key=lambda r: r["seconds"]) if ok else None
        in_time = [r for r in mine if r["seconds"] <= 1.25 * base["seconds"]]
        best = min(in_time, key=lambda r: r["vs_window_ref_penumbra"]["relative_rms"],
                   default=None)
        out[method] = {
            "cheapest_at_baseline_error": cheapest and cheapest["label"],
            "cheapest_seconds": cheapest and cheapest["seconds"],
            "best_within_baseline_time": best and best["label"],
            "best_penumbra_rms": best and best["vs_window_ref_penumbra"]["relative_rms"],
        }
    return out


def main() -> dict:
    scene = load_scene(SCENE)
    results = []
    for name, size in MESHES:
        h, ctx = _mesh(scene, size)
        n = len(h.vertices)
        # compile (or load) both kernels before any timing
        direct.compute(replace(ctx, area_method="hemisphere"), 0, min(n, 64))
        direct.compute(replace(ctx, area_method="rays"), 0, min(n, 64))
        results.append(_measure(name, ctx, n))
    for res in results:
        print(f"\nCornell box, {res['mesh']}: {res['vertices']} vertices, "
              f"{res['emitter_patches']} emitter patches, {res['lit_vertices']} lit, "
              f"{res['penumbra_vertices']} in penumbra; window method: "
              f"{res['vertices_with_candidates']} vertices rasterize, "
              f"{res['candidates_per_vertex']:.1f} candidate occluders per vertex")
        print(f"references: window {res['reference_window']}² "
              f"({res['reference_window_seconds']:.2f} s; vs {res['reference_window'] // 2}²: "
              f"penumbra RMS {res['reference_window_vs_half']['relative_rms']:.1e}), "
              f"rays {res['reference_rays']}² ({res['reference_rays_seconds']:.2f} s; vs the "
              f"window ref: penumbra RMS "
              f"{res['reference_rays_vs_window_ref']['relative_rms']:.1e})")
        print(f"{'method':<16}{'seconds':>9}{'us/vert':>9}{'all RMS':>10}{'pen RMS':>10}"
              f"{'pen max':>10}{'pen RMS':>10}   (window ref | rays ref)")
        for r in res["configs"]:
            a, p, q = r["vs_window_ref"], r["vs_window_ref_penumbra"], r["vs_rays_ref_penumbra"]
            print(f"{r['label']:<16}{r['seconds']:>9.3f}{r['us_per_vertex']:>9.1f}"
                  f"{a['relative_rms']:>10.2e}{p['relative_rms']:>10.2e}"
                  f"{p['relative_max']:>10.2e}{q['relative_rms']:>10.2e}")
    choice = _choose(results[0])
    print(f"\nagainst {choice['baseline']} ({choice['baseline_seconds']:.3f} s, penumbra RMS "
          f"{choice['baseline_penumbra_rms']:.2e}):")
    for method in ("rays", "hemisphere"):
        c = choice[method]
        print(f"  {method:<11} cheapest at that error: {c['cheapest_at_baseline_error']} "
              f"({c['cheapest_seconds'] or float('nan'):.3f} s); best within its time: "
              f"{c['best_within_baseline_time']} (penumbra RMS "
              f"{c['best_penumbra_rms'] or float('nan'):.2e})")
    out = {"meshes": results, "choice": choice}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "arealight.json").write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
