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

``--scene PATH`` (repeatable; e.g. RenderPark's office and classroom, which are not in the
repository) measures instead the window method's early stop on a scene with many luminaires
(issue 12, item 5): over ``--vertices`` vertices (default 8000; 16 runs of consecutive
vertices spread over the scene, as the direct pass lights consecutive vertices in a task), CPU
seconds of the window at 32² as the direct pass runs it (the face test first,
:mod:`daskrad.kernels.faces`, then the window with the hint and the early stop), and of the
window alone with the slab search and early stop (``SLABS``), with and without the hint (the
occluders that last hid a light searched first, ``HINT``), against the exhaustive reference
(``slabs = 0``: every pyramid searched whole, every candidate drawn), alternated in one
process, with the vertex-light pairs by kind. The window's modes must give the same bits; the
face test's vertices that moved (where it proved ``V = 0`` and the raster let a pixel or two
through) are counted, with their largest change; and the face test and window again with every
row of each pyramid's box walked (``prune=False``: the same bits, it must be slower).
The direct pass takes its occluders from the scene's polygons (``Mesh.occluders``,
:data:`daskrad.direct.POLYGON_OCCLUDERS`): the face test and window as the pass runs them
through that grid (``polygons``) are timed in the same alternation against the element grid
(``faces``); the irradiance they give is compared (relative RMS and largest change, the
lights' classes that changed), and at the 16 vertices that moved most both are set beside
32 × 32 stratified shadow rays (``rays``; they give the same value through either grid).
Results go to ``results/arealight_scenes.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from daskrad import direct, tolerances
from daskrad.kernels.arealight import HINT, SLABS, area_irradiance_stats
from daskrad.kernels.direct import LIGHT_VISIBLE, irradiance_points
from daskrad.kernels.faces import UNION_RAYS, no_faces
from daskrad.kernels.grid import build_grid
from daskrad.kernels.lambert import lambert_polygon
from daskrad.mesh import build_hierarchy, default_sizes, hierarchy_triangles
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

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
    tris, _, tri_element = hierarchy_triangles(h)
    ctx = direct.make_context(scene, h, build_grid(tris), tri_element=tri_element)
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
    _, work, _ = area_irradiance_stats(
        ctx.grid, ctx.faces, ctx.area_points, ctx.normals, ctx.offset,
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


def _pairs(ctx, P, N) -> dict:
    """Vertex-light pairs: all, with the vertex on the emitting side, and with ``F > 0``."""
    C, en = ctx.emitter_corners, ctx.emitter_normal
    side = np.einsum("mk,vmk->vm", en, P[:, None, :] - C[None, :, 0, :]) > 0
    lit = 0
    for v, m in zip(*np.nonzero(side), strict=True):
        lit += lambert_polygon(*P[v], *N[v], C[m], int(ctx.emitter_count[m])) > 0
    return {"pairs": int(side.size), "emitting_side": int(side.sum()), "lit": int(lit)}


def _scene(path: str, vertices: int) -> dict:
    """The early stop, with and without the hint, against the exhaustive window on
    ``vertices`` vertices of a scene (:data:`CHUNKS` runs of consecutive vertices, evenly
    spread: the direct pass lights consecutive vertices in one task, which the hint uses)."""
    scene = load_scene(path)
    settings = Settings()
    mesh = preprocess(scene, settings)
    ctx = direct.make_context(scene, mesh.hierarchy, mesh.grid, method="hemisphere",
                              tri_element=mesh.tri_element)
    V = len(ctx.area_points)
    run_len = max(1, min(vertices, V) // CHUNKS)
    starts = np.linspace(0, V - run_len, CHUNKS).astype(np.int64)
    idx = np.unique(np.concatenate([np.arange(a, a + run_len) for a in starts]))
    P = np.ascontiguousarray(ctx.area_points[idx])
    N = np.ascontiguousarray(ctx.normals[idx])
    args = (ctx.offset, ctx.offset * tolerances.HORIZON_EPS / tolerances.RAY_OFFSET,
            ctx.emitter_corners, ctx.emitter_count, ctx.emitter_normal, ctx.emitter_radiance,
            direct.AREA_RESOLUTION, np.radians(tolerances.EDGE_ANGLE_DEG))
    window = no_faces(len(ctx.grid.triangles))
    polygons = mesh.occluders
    # each mode: faces, slabs, hint, prune, union (rays of the several-faces proof)
    modes = {"polygons": (polygons.faces, SLABS, HINT, True, UNION_RAYS),
             "one face": (polygons.faces, SLABS, HINT, True, 0),
             "faces": (ctx.faces, SLABS, HINT, True, UNION_RAYS),
             "every row": (ctx.faces, SLABS, HINT, False, UNION_RAYS),
             "hint": (window, SLABS, HINT, True, 0), "early stop": (window, SLABS, 0, True, 0),
             "exhaustive": (window, 0, 0, False, 0)}
    def grid_of(name):
        return polygons.grid if name in ("polygons", "one face") else ctx.grid

    for name, (faces, slabs, hint, prune, union) in modes.items():  # compile (or load)
        area_irradiance_stats(grid_of(name), faces, P[:4], N[:4], *args, slabs, hint, prune,
                              union)
    best = dict.fromkeys(modes, np.inf)
    out = {}
    for _ in range(2):
        for name, (faces, slabs, hint, prune, union) in modes.items():
            t = time.process_time()
            out[name] = area_irradiance_stats(grid_of(name), faces, P, N, *args, slabs, hint,
                                              prune, union)
            best[name] = min(best[name], time.process_time() - t)
    one = out["one face"][0]
    several = (out["polygons"][0] != one).any(axis=1)
    moved = np.abs(out["faces"][0] - out["exhaustive"][0]).sum(axis=1)
    total = out["exhaustive"][0].sum(axis=1)
    return {**_polygons(ctx, polygons.grid, P, N, out["faces"], out["polygons"]),
            "cpu_seconds_polygons": best["polygons"],
            "cpu_seconds_polygons_one_face": best["one face"],
            "several_faces_moved_vertices": int(several.sum()),
            "several_faces_moved_max": float(np.abs(out["polygons"][0] - one).max()
                                             / max(one.max(), 1e-300)),
            "scene": Path(path).name, "vertices": len(P), "of_vertices": V,
            "emitter_patches": int(len(ctx.emitter_corners)), **_pairs(ctx, P, N),
            "cpu_seconds_faces": best["faces"],
            "cpu_seconds_every_row": best["every row"],
            "cpu_seconds_hint": best["hint"],
            "cpu_seconds_early_stop": best["early stop"],
            "cpu_seconds_exhaustive": best["exhaustive"],
            "candidates_faces": int(out["faces"][1].sum()),
            "candidates_hint": int(out["hint"][1].sum()),
            "candidates_early_stop": int(out["early stop"][1].sum()),
            "candidates_exhaustive": int(out["exhaustive"][1].sum()),
            "faces_moved_vertices": int((moved > 0).sum()),
            "faces_moved_relative": float(moved.sum() / total.sum()),
            "faces_moved_max": float(moved.max() / total.max()),
            "same_bits": bool(np.array_equal(out["hint"][0], out["exhaustive"][0])
                              and np.array_equal(out["early stop"][0], out["exhaustive"][0])
                              and all(np.array_equal(a, b) for a, b in
                                      zip(out["faces"], out["every row"], strict=True)))}


def _polygons(ctx, grid, P, N, elements, polygons) -> dict:
    """How the window's irradiance and classes through the polygons' grid differ from the
    elements' (``(H, work, classes)`` of each), and at the 16 vertices that moved most, the
    mean distance of each to 32 × 32 shadow rays."""
    He, Hp = elements[0], polygons[0]
    d = Hp - He
    top = np.argsort(-np.abs(d).sum(axis=1))[:16]
    z3 = np.zeros((0, 3))
    rays = {}
    for name, g in (("elements", ctx.grid), ("polygons", grid)):
        rays[name], _ = irradiance_points(
            g, P[top], P[top], N[top], top.astype(np.int64), float(ctx.offset), z3, z3, z3,
            z3, ctx.emitter_corners, ctx.emitter_count, ctx.emitter_normal,
            ctx.emitter_radiance, ctx.emitter_area, 32)
    ref = rays["polygons"].sum(axis=1)
    ce, cp = elements[2], polygons[2]
    return {"polygons_relative_rms": float(np.sqrt((d**2).mean() / (He**2).mean())),
            "polygons_relative_max": float(np.abs(d).max() / He.max()),
            "polygons_classes_changed": int((ce != cp).sum()),
            "polygons_visible_lost": int(((ce == LIGHT_VISIBLE) & (cp != LIGHT_VISIBLE)).sum()),
            "polygons_visible_gained": int(((ce != LIGHT_VISIBLE)
                                            & (cp == LIGHT_VISIBLE)).sum()),
            "rays_same_through_both_grids": bool(np.array_equal(rays["elements"],
                                                                rays["polygons"])),
            "moved_most_vs_rays_elements": float(np.abs(He[top].sum(axis=1) - ref).mean()),
            "moved_most_vs_rays_polygons": float(np.abs(Hp[top].sum(axis=1) - ref).mean())}


#: Runs of consecutive vertices :func:`_scene` takes, evenly spread over the scene.
CHUNKS = 16


def scenes(paths: list[str], vertices: int) -> list[dict]:
    rows = [_scene(p, vertices) for p in paths]
    for r in rows:
        print(f"{Path(r['scene']).name}: {r['vertices']} of {r['of_vertices']} vertices x "
              f"{r['emitter_patches']} emitter patches = {r['pairs']} pairs, "
              f"{r['emitting_side']} on the emitting side, {r['lit']} with F > 0; window 32², "
              f"CPU s (candidates): faces first {r['cpu_seconds_faces']:.2f} "
              f"({r['candidates_faces']}; x{r['cpu_seconds_hint'] / r['cpu_seconds_faces']:.2f}"
              f" over the window alone; {r['faces_moved_vertices']} vertices moved, by "
              f"{r['faces_moved_relative']:.1e} of the total, at most "
              f"{r['faces_moved_max']:.1e} of the largest; every row of the pyramid's "
              f"box walked {r['cpu_seconds_every_row']:.2f}, "
              f"x{r['cpu_seconds_every_row'] / r['cpu_seconds_faces']:.2f}), "
              f"hint {r['cpu_seconds_hint']:.2f} "
              f"({r['candidates_hint']}), early stop {r['cpu_seconds_early_stop']:.2f} "
              f"({r['candidates_early_stop']}), exhaustive "
              f"{r['cpu_seconds_exhaustive']:.2f} ({r['candidates_exhaustive']}); hint "
              f"x{r['cpu_seconds_early_stop'] / r['cpu_seconds_hint']:.2f} over the early "
              f"stop, same bits: {r['same_bits']}")
        print(f"  several faces together (faces_hide) through the polygons: CPU s "
              f"{r['cpu_seconds_polygons']:.2f} against {r['cpu_seconds_polygons_one_face']:.2f}"
              f" one face at a time; {r['several_faces_moved_vertices']} vertices moved, at "
              f"most {r['several_faces_moved_max']:.1e} of the largest")
        print(f"  occluders from the polygons: CPU s {r['cpu_seconds_polygons']:.2f} against "
              f"{r['cpu_seconds_faces']:.2f} through the elements "
              f"(x{r['cpu_seconds_faces'] / r['cpu_seconds_polygons']:.2f}); irradiance "
              f"relative RMS change {r['polygons_relative_rms']:.1e}, largest "
              f"{r['polygons_relative_max']:.1e} of the largest; classes changed "
              f"{r['polygons_classes_changed']} (visible lost {r['polygons_visible_lost']}, "
              f"gained {r['polygons_visible_gained']}); at the 16 vertices moved most, mean "
              f"distance to 32² shadow rays elements {r['moved_most_vs_rays_elements']:.2e}, "
              f"polygons {r['moved_most_vs_rays_polygons']:.2e} (rays the same through both "
              f"grids: {r['rays_same_through_both_grids']})")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / "arealight_scenes.json").write_text(json.dumps(rows, indent=2) + "\n")
    return rows


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_arealight")
    parser.add_argument("--scene", action="append", default=[],
                        help="a scene with many luminaires: early stop vs exhaustive window")
    parser.add_argument("--vertices", type=int, default=8000)
    args = parser.parse_args([] if argv is None else argv)
    if args.scene:
        return {"scenes": scenes(args.scene, args.vertices)}
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
    main(sys.argv[1:])
