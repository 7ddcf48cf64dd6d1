"""Form-factor methods side by side (issue 6): the paper's Tables 1 and 2, error against
resolution, and the time each method needs for a given error.

(a) **Tables 1 and 2** (Doi): the Cornell box meshed to about 132 patches / 548 elements and
    328 patches / 3,294 elements; 50 and 100 shots from the centroids of the largest patches
    (area order, stable) at R = 100. CPU seconds (``time.process_time``, best of 3, one core) of
    the form-factor work of each method, and the hemicube / hemisphere ratio, in one run.
(b) **Error against resolution** for every method: on the configurations of issue 6, item 2
    (relative L1 error ``Σ|F - F_exact| / Σ F_exact`` against Lambert's formula, and against the
    exact visible part for the occluded one), and on the Cornell box rows of Table 1 (against a
    reference: the default method at R = 2048, checked against 24 × 24 ray samples per element).
(c) **Equal error**: for target errors on the Cornell box rows, the smallest resolution of the
    sweep each method needs, and the CPU time of the Table 1 workload there.
(d) **Whole solution** (the paper's Figure 2): ``daskrad.run`` on the Table 1 mesh with 50
    shots per method, RMS error of the element radiosity against a reference solved with the
    default method at R = 1024 for the same number of shots and for a converged run, and the
    images side by side.

``python -m benchmarks.bench_methods``; writes ``benchmarks/results/methods.json``,
``methods_error.png`` (log-log error against resolution) and ``methods_figure2.png``.
"""

from __future__ import annotations

import json
import math
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from daskrad import formfactor as ff
from daskrad.mesh import build_hierarchy
from daskrad.scene import load_scene
from daskrad.testing import grid, merge, square_above

ROOT = Path(__file__).resolve().parent.parent
RESULTS = Path(__file__).parent / "results"
SCENE = ROOT / "scenes" / "cornell_box.obj"
#: (name, patch size, element size, shots): sizes found by a search for the paper's counts
TABLES = (("Table 1", 180.0, 90.0, 50), ("Table 2", 108.0, 33.0, 100))
PAPER = {"Table 1": {"patches": 132, "elements": 548, "ratio": "2.6-3.2"},
         "Table 2": {"patches": 328, "elements": 3294, "ratio": "2.6-3.2"}}
METHODS = ("hemisphere", "hemisphere-itembuffer", "hemisphere-scanline", "hemicube", "raycast")
RESOLUTIONS = (25, 35, 50, 70, 100, 140, 200, 280, 400, 560, 800)
#: ray samples per side standing in for "resolution" for the ray-cast method
RAY_SAMPLES = (1, 2, 3, 4, 6, 8, 12)
TARGETS = (0.05, 0.02, 0.01, 0.005)
UP = np.array([0.0, 0.0, 1.0])
ORIGIN = np.zeros(3)
#: What each timed method does per shot beyond its algorithm (all raster methods share the
#: rasterizer ``fill_polygon`` and its edge table).
OPTIMISATIONS = {
    "hemisphere": "cull (back-face, corners below horizon) before projecting; auto edge angle "
                  "(quarter-pixel sagitta); per-element path (cull, clip, project, fill) "
                  "in one loop, no calls; Lambert only where the visible fraction is > 0",
    "hemisphere-itembuffer": "cull (back-face, corners below horizon); auto edge angle; "
                             "per-element path in one loop",
    "hemisphere-scanline": "cull (back-face, corners below horizon); 1 deg edges (exact spans)",
    "hemicube": "cull (back-face, bounding sphere below horizon); per-face outcode trivial "
                "reject/accept before Sutherland-Hodgman; no per-shot allocation; "
                "fill written out in the per-face loop (as the hemisphere's)",
    "raycast": "voxel-grid shadow rays only for elements with Lambert > 0",
}
COLOURS = {"hemisphere": (200, 30, 30), "hemisphere-itembuffer": (240, 140, 0),
           "hemisphere-scanline": (30, 150, 30), "hemicube": (30, 60, 200),
           "raycast": (140, 40, 170)}


# --- timing -----------------------------------------------------------------------------------

def cpu_seconds(fn, repeats=3):
    """Best CPU time of ``repeats`` calls after one warm-up call (numba compile / cache load)."""
    fn()
    best = math.inf
    for _ in range(repeats):
        t = time.process_time()
        fn()
        best = min(best, time.process_time() - t)
    return best


def workload(patch_size, element_size, shots):
    """The Cornell box hierarchy and ``shots`` shooting points (largest patches' centroids)."""
    h = build_hierarchy(load_scene(SCENE), patch_size, element_size)
    order = np.argsort(-h.patch_area, kind="stable")[:shots]
    points = np.ascontiguousarray(h.patch_centroid[order])
    normals = np.ascontiguousarray(h.patch_normal[order])
    return h, points, normals


def run_options(method, resolution):
    """(resolution, options) of a method at a sweep point (the ray-cast method sweeps samples)."""
    if method == "raycast":
        return 2, {"samples": resolution}
    return resolution, {}


# --- (a) Tables 1 and 2 --------------------------------------------------------------------------

def tables():
    rows = []
    for name, ps, es, shots in TABLES:
        h, points, normals = workload(ps, es, shots)
        row = {"table": name, "patch_size": ps, "element_size": es, "patches": h.n_patches,
               "elements": h.n_elements, "shots": shots, "resolution": 100, "seconds": {}}
        for method in METHODS:
            row["seconds"][method] = cpu_seconds(
                lambda m=method, p=points, n=normals, v=h.vertices, e=h.elem_verts:
                ff.shooter_rows(p, n, v, e, m, 100))
        s = row["seconds"]
        row["ratio_hemicube_over_hemisphere"] = s["hemicube"] / s["hemisphere"]
        row["ratio_hemicube_over_itembuffer"] = s["hemicube"] / s["hemisphere-itembuffer"]
        rows.append(row)
    return rows


# --- (b) error against resolution ----------------------------------------------------------------

def lam(verts, elems):
    return ff.analytic_point_to_elements(ORIGIN, UP, verts, elems)


def configurations():
    """Issue 6 item 2's configurations: name -> (vertices, elements, exact F per element)."""
    tilted = np.array([[1.0, -0.6, -0.5], [1.0, 0.7, -0.3], [0.4, 0.8, 0.9], [0.3, -0.5, 1.1]])
    tilted_e = np.array([[3, 2, 1, 0]], np.int32)
    if np.cross(tilted[1] - tilted[0], tilted[2] - tilted[0]) @ -tilted[0] > 0:
        tilted_e = tilted_e[:, ::-1].copy()
    out = {}
    for name, (v, e) in {
        "large": square_above(-0.5, 0.5, -0.5, 0.5, 1.0),
        "small": square_above(0.30, 0.32, -0.21, -0.19, 1.0),
        "far": square_above(20.0, 21.0, -0.5, 0.5, 56.0),
        "grazing": grid([6.0, -0.5, 0.1], [0, 0, 0.5], [0, 1.0, 0]),
        "below-horizon": (tilted, tilted_e),
        "mesh": square_above(-3.0, 3.0, -3.0, 3.0, 2.0, n=24),
    }.items():
        out[name] = (v, e, lam(v, e))
    # occluded: a 2 × 2 square meshed 4 × 4 at height 2 behind a 0.4 square at height 1, whose
    # shadow is the rectangle [0.1, 0.9] × [-0.6, 0.2] (exact visible part per element)
    big = square_above(-1.0, 1.0, -1.0, 1.0, 2.0, n=4)
    small = square_above(0.05, 0.45, -0.3, 0.1, 1.0)
    exact = []
    for k in range(16):
        c = big[0][big[1][k]]
        x0, x1, y0, y1 = c[:, 0].min(), c[:, 0].max(), c[:, 1].min(), c[:, 1].max()
        f = lam(*square_above(x0, x1, y0, y1, 2.0))[0]
        ix0, ix1, iy0, iy1 = max(x0, 0.1), min(x1, 0.9), max(y0, -0.6), min(y1, 0.2)
        if ix1 > ix0 and iy1 > iy0:
            f -= lam(*square_above(ix0, ix1, iy0, iy1, 2.0))[0]
        exact.append(f)
    v, e = merge(big, small)
    out["occluded"] = (v, e, np.array(exact + [lam(*small)[0]]))
    return out


def rel_l1(f, exact):
    return float(np.abs(f - exact).sum() / exact.sum())


def error_vs_resolution(configs, cornell, reference):
    """Per method and sweep point: error on every configuration and on the Cornell rows."""
    h, points, normals = cornell
    rows = []
    for method in METHODS:
        sweep = RAY_SAMPLES if method == "raycast" else RESOLUTIONS
        for value in sweep:
            r, opts = run_options(method, value)
            row = {"method": method, "resolution": value, "configs": {}}
            for name, (v, e, exact) in configs.items():
                f = ff.point_to_elements(ORIGIN, UP, v, e, method, r, **opts)
                row["configs"][name] = rel_l1(f, exact)
            row["worst_config"] = max(row["configs"].values())
            t = time.process_time()
            rows_f = ff.shooter_rows(points, normals, h.vertices, h.elem_verts, method, r, **opts)
            row["cornell_seconds"] = time.process_time() - t
            row["cornell"] = cornell_error(rows_f, reference)
            rows.append(row)
    return rows


def cornell_error(rows_f, reference):
    """Mean over shooters of the relative L1 row error against the reference rows."""
    ref, keep = reference
    err = np.abs(rows_f - ref)[keep].sum(1) / ref[keep].sum(1)
    return float(err.mean())


# --- (c) equal error ---------------------------------------------------------------------------

def equal_error(sweep_rows, cornell):
    h, points, normals = cornell
    out = []
    for target in TARGETS:
        entry = {"target": target, "methods": {}}
        for method in METHODS:
            hits = [r for r in sweep_rows if r["method"] == method and r["cornell"] <= target]
            if not hits:
                entry["methods"][method] = None
                continue
            value = min(hits, key=lambda r: r["resolution"])["resolution"]
            res, opts = run_options(method, value)
            secs = cpu_seconds(lambda m=method, r=res, o=opts: ff.shooter_rows(
                points, normals, h.vertices, h.elem_verts, m, r, **o), repeats=2)
            entry["methods"][method] = {"resolution": value, "seconds": secs}
        out.append(entry)
    return out


# --- (d) whole solution ------------------------------------------------------------------------

def whole_solution():
    """Solution error of each method (Table 1 mesh) and the images side by side."""
    try:
        from daskrad.io import write_png  # noqa: F401  (the images are written by run())
        from daskrad.run import run, solve_scene
        from daskrad.settings import Settings
    except ImportError as exc:  # the pipeline is not there yet
        return {"skipped": f"pipeline unavailable: {exc}"}
    scene = load_scene(SCENE)
    _, ps, es, shots = TABLES[0]
    base = dict(resolution=100, patch_size=ps, element_size=es, max_iterations=shots,
                tolerance=1e-9)

    def radiosity(**changes):
        return solve_scene(scene, Settings(**{**base, **changes}))[2].radiosity

    ref_same = radiosity(method="hemisphere", resolution=1024)
    ref_conv = radiosity(method="hemisphere", resolution=1024, max_iterations=5000,
                         tolerance=1e-4)
    out = {"shots": shots, "reference": "hemisphere at R = 1024", "methods": {}}
    tmp = Path(tempfile.mkdtemp())
    images = []
    for method in ("hemicube", "hemisphere", "hemisphere-itembuffer"):
        t = time.process_time()
        b = radiosity(method=method)
        secs = time.process_time() - t
        conv = radiosity(method=method, max_iterations=5000, tolerance=1e-4)
        out["methods"][method] = {
            "solve_seconds_50_shots": secs,
            "rms_rel_error_same_shots": float(np.sqrt(((b - ref_same) ** 2).mean())
                                              / np.sqrt((ref_same ** 2).mean())),
            "rms_rel_error_converged": float(np.sqrt(((conv - ref_conv) ** 2).mean())
                                             / np.sqrt((ref_conv ** 2).mean())),
        }
        exr = tmp / f"{method}.exr"
        run(SCENE, exr, Settings(method=method, **base), progress=False)
        images.append((method, exr.with_suffix(".png")))
    exr = tmp / "reference.exr"
    run(SCENE, exr, Settings(method="hemisphere", **{**base, "resolution": 1024}),
        progress=False)
    images.append(("reference R=1024", exr.with_suffix(".png")))
    side_by_side(images, RESULTS / "methods_figure2.png")
    shutil.rmtree(tmp, ignore_errors=True)
    out["figure"] = "benchmarks/results/methods_figure2.png"
    return out


def side_by_side(images, path):
    tiles = [(name, Image.open(p).convert("RGB")) for name, p in images]
    w = sum(im.width for _, im in tiles) + 10 * (len(tiles) - 1)
    hgt = max(im.height for _, im in tiles) + 20
    canvas = Image.new("RGB", (w, hgt), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    x = 0
    for name, im in tiles:
        canvas.paste(im, (x, 20))
        draw.text((x + 4, 4), name, fill=(0, 0, 0))
        x += im.width + 10
    canvas.save(path)


# --- plot --------------------------------------------------------------------------------------

def plot(sweep_rows, path):
    """Two log-log panels: Cornell row error and worst configuration error against resolution."""
    width, height, pad = 520, 400, 60
    canvas = Image.new("RGB", (2 * width, height + 70), (255, 255, 255))
    draw = ImageDraw.Draw(canvas)
    for panel, key, title in ((0, "cornell", "Cornell box rows (Table 1), rel. L1 error"),
                              (1, "worst_config", "issue 6 configurations, worst rel. L1")):
        ox = panel * width
        pts = [(r["resolution"], r[key]) for r in sweep_rows
               if r["method"] != "raycast" and r[key] > 0]
        xlo, xhi = math.log10(min(p[0] for p in pts)), math.log10(max(p[0] for p in pts))
        ylo = math.floor(math.log10(min(p[1] for p in pts)))
        yhi = math.ceil(math.log10(max(p[1] for p in pts)))

        def xy(res, err, ox=ox, xlo=xlo, xhi=xhi, ylo=ylo, yhi=yhi):
            u = (math.log10(res) - xlo) / (xhi - xlo)
            v = (math.log10(max(err, 10.0 ** ylo)) - ylo) / (yhi - ylo)
            return ox + pad + u * (width - 2 * pad), height - pad - v * (height - 2 * pad)

        draw.rectangle([ox + pad, pad, ox + width - pad, height - pad], outline=(0, 0, 0))
        for k in range(ylo, yhi + 1):
            _, y = xy(10 ** xlo, 10.0 ** k)
            draw.line([ox + pad, y, ox + width - pad, y], fill=(220, 220, 220))
            draw.text((ox + 8, y - 6), f"1e{k}", fill=(0, 0, 0))
        for res in (25, 50, 100, 200, 400, 800):
            x, _ = xy(res, 10.0 ** ylo)
            draw.line([x, pad, x, height - pad], fill=(220, 220, 220))
            draw.text((x - 8, height - pad + 6), str(res), fill=(0, 0, 0))
        draw.text((ox + pad, 20), title, fill=(0, 0, 0))
        draw.text((ox + width // 2 - 30, height - pad + 24), "resolution R", fill=(0, 0, 0))
        for method in METHODS:
            if method == "raycast":
                continue
            line = [xy(r["resolution"], r[key]) for r in sweep_rows if r["method"] == method]
            draw.line(line, fill=COLOURS[method], width=2)
            for x, y in line:
                draw.ellipse([x - 2, y - 2, x + 2, y + 2], fill=COLOURS[method])
    for k, method in enumerate(m for m in METHODS if m != "raycast"):
        x = 20 + k * 200
        draw.line([x, height + 40, x + 30, height + 40], fill=COLOURS[method], width=3)
        draw.text((x + 36, height + 34), method, fill=(0, 0, 0))
    canvas.save(path)


# --- main --------------------------------------------------------------------------------------

def print_tables(table_rows, sweep_rows, equal, solution):
    print("(a) Tables 1 and 2: CPU seconds of form-factor work, R = 100, one core")
    head = f"{'':9}{'patches':>8}{'elems':>7}{'shots':>6}" + "".join(
        f"{m[:13]:>14}" for m in METHODS) + f"{'cube/hemi':>10}{'cube/item':>10}"
    print(head)
    print("-" * len(head))
    for r in table_rows:
        print(f"{r['table']:9}{r['patches']:>8}{r['elements']:>7}{r['shots']:>6}"
              + "".join(f"{r['seconds'][m]:>14.4f}" for m in METHODS)
              + f"{r['ratio_hemicube_over_hemisphere']:>10.2f}"
              + f"{r['ratio_hemicube_over_itembuffer']:>10.2f}")
    print("paper: 132/548 and 328/3,294, hemicube/hemisphere 2.6-3.2")
    print("optimisations in each timed method:")
    for m, text in OPTIMISATIONS.items():
        print(f"  {m:<22}{text}")
    print("\n(b) error against resolution (rel. L1; raycast: samples per side)")
    names = list(sweep_rows[0]["configs"])
    head = f"{'method':<22}{'R':>5}{'cornell':>9}{'s/50':>8}" + "".join(
        f"{n[:9]:>10}" for n in names)
    print(head)
    print("-" * len(head))
    for r in sweep_rows:
        print(f"{r['method']:<22}{r['resolution']:>5}{r['cornell']:>9.4f}"
              f"{r['cornell_seconds']:>8.3f}"
              + "".join(f"{r['configs'][n]:>10.2e}" for n in names))
    print("\n(c) equal error on the Cornell rows: resolution needed and CPU s for Table 1")
    print(f"{'target':>8}" + "".join(f"{m[:20]:>22}" for m in METHODS))
    for e in equal:
        cells = []
        for m in METHODS:
            v = e["methods"][m]
            cells.append(f"{'-':>22}" if v is None
                         else f"{'R=' + str(v['resolution']):>10}{v['seconds']:>10.4f} s  ")
        print(f"{e['target']:>8.3f}" + "".join(cells))
    print("\n(d) whole solution, Table 1 mesh, 50 shots")
    if "skipped" in solution:
        print("skipped:", solution["skipped"])
    else:
        for m, v in solution["methods"].items():
            print(f"{m:<24}solve {v['solve_seconds_50_shots']:.3f} s  RMS error "
                  f"{v['rms_rel_error_same_shots']:.4f} (50 shots)  "
                  f"{v['rms_rel_error_converged']:.4f} (converged)")


def main():
    RESULTS.mkdir(parents=True, exist_ok=True)
    table_rows = tables()
    _, ps, es, shots = TABLES[0]
    cornell = workload(ps, es, shots)
    h, points, normals = cornell
    ref = ff.shooter_rows(points, normals, h.vertices, h.elem_verts, "hemisphere", 2048)
    rays = ff.shooter_rows(points, normals, h.vertices, h.elem_verts, "raycast", samples=24)
    # Shooters whose centroid lies under a block see nothing (the ray reference); the raster
    # methods cull the block's faces as back-facing and see through it. Leave those out.
    keep = rays.sum(1) > 0.05
    reference = (ref, keep)
    ref_check = cornell_error(rays, reference)
    sweep_rows = error_vs_resolution(configurations(), cornell, reference)
    equal = equal_error(sweep_rows, cornell)
    solution = whole_solution()
    plot(sweep_rows, RESULTS / "methods_error.png")
    print_tables(table_rows, sweep_rows, equal, solution)
    print(f"\nreference rows: hemisphere R=2048; 24x24 ray samples differ by {ref_check:.4f}; "
          f"{int(keep.sum())}/{len(keep)} shooters kept")
    (RESULTS / "methods.json").write_text(json.dumps({
        "benchmark": "methods",
        "machine": platform.platform(),
        "paper": PAPER,
        "optimisations": OPTIMISATIONS,
        "tables": table_rows,
        "error_vs_resolution": sweep_rows,
        "equal_error": equal,
        "whole_solution": solution,
        "reference": {"rows": "hemisphere R=2048", "raycast_24_rel_l1": ref_check,
                      "shooters_kept": int(keep.sum()), "shooters": int(len(keep))},
    }, indent=2))
    return table_rows


if __name__ == "__main__":
    main()
