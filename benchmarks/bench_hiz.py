"""Hierarchical z in the hemisphere base: form-factor rows with and without it, per scene.

For each scene: the depth complexity the solve decides by
(:func:`daskrad.formfactor.shooting.depth_complexity`, hierarchical z above
:data:`~daskrad.formfactor.shooting.HIZ_DEPTH`), then the default method's rows of ``--patches``
shooting patches spread through the patch indices, at the points the solve samples them
(:func:`~daskrad.formfactor.shooting.shooter_points`), computed with ``hiz`` off and on,
alternating, ``--repeats`` times: medians of the CPU seconds and their ratio, measured in one
run. Also: whether every element wins the same pixels both ways (it must), and how far the rows
move (the elements left out that the bilinear test at their centroid counted partly visible).

``python -m benchmarks.bench_hiz [--scene PATH ...]``; the bundled Cornell box and lit room
by default (RenderPark's MGF interiors, converted, by path). Writes
``benchmarks/results/hiz.json``.
"""

from __future__ import annotations

import argparse
import json
import time
import warnings
from pathlib import Path

import numpy as np

from daskrad import formfactor as ff
from daskrad import tolerances
from daskrad.formfactor import shooting
from daskrad.kernels.hemisphere import hemisphere_visibility
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results" / "hiz.json"
SCENES = Path(__file__).parent.parent / "scenes"
DEFAULT = [SCENES / "cornell_box.obj", SCENES / "lit_room.obj"]


def _shooters(ctx, patches: int):
    picks = np.unique(np.linspace(0, len(ctx.patch_area) - 1, patches).astype(np.int64))
    out = []
    for p in picks:
        points, _ = shooting.shooter_points(ctx, int(p))
        out.append((np.ascontiguousarray(points),
                    np.ascontiguousarray(np.repeat(ctx.patch_normal[p][None], len(points), 0))))
    return out


def _rows(ctx, shooters, hiz: bool) -> tuple[float, list[np.ndarray]]:
    rows = []
    t = time.process_time()
    for points, normals in shooters:
        rows.append(ff.shooter_rows(points, normals, ctx.vertices, ctx.elem_verts,
                                    "hemisphere", ctx.resolution, hiz=hiz))
    return time.process_time() - t, rows


def _same_pixels(ctx, shooters) -> bool:
    r, angle, plane = ff.methods._raster_args(ctx.resolution)
    for points, normals in shooters[::4]:
        args = (points, normals, ctx.vertices, ctx.elem_verts, r, angle, plane,
                tolerances.HORIZON_EPS)
        if not np.array_equal(hemisphere_visibility(*args, False)[0],
                              hemisphere_visibility(*args, True)[0]):
            return False
    return True


def scene(path: Path, patches: int, repeats: int) -> dict:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        loaded = load_scene(path)
    settings = Settings()
    mesh = preprocess(loaded, settings)
    h = mesh.hierarchy
    ctx = shooting.make_context(h, settings.method, settings.resolution, grid=mesh.grid,
                                tri_element=mesh.tri_element)
    shooters = _shooters(ctx, patches)
    _rows(ctx, shooters[:2], False)        # compile or load both ways
    _rows(ctx, shooters[:2], True)
    off, on = [], []
    for _ in range(repeats):
        t_off, rows_off = _rows(ctx, shooters, False)
        t_on, rows_on = _rows(ctx, shooters, True)
        off.append(t_off)
        on.append(t_on)
    moved = np.concatenate([np.abs(a - b).sum(axis=1) for a, b in zip(rows_off, rows_on,
                                                                       strict=True)])
    row = {"scene": str(path), "elements": int(len(h.elem_area)),
           "patches_shot": len(shooters), "passes": int(sum(len(p) for p, _ in shooters)),
           "depth_complexity": shooting.depth_complexity(h),
           "hiz_chosen": bool(ctx.options["hiz"]),
           "cpu_seconds_off": float(np.median(off)), "cpu_seconds_on": float(np.median(on)),
           "speedup": float(np.median(off) / np.median(on)),
           "same_pixels_won": _same_pixels(ctx, shooters),
           "row_l1_change_median": float(np.median(moved)),
           "row_l1_change_max": float(moved.max())}
    print(f"{path.name:>18} {row['elements']:>7} {row['passes']:>6} "
          f"{row['depth_complexity']:>6.2f} {'on' if row['hiz_chosen'] else 'off':>6} "
          f"{row['cpu_seconds_off']:>8.2f} {row['cpu_seconds_on']:>8.2f} "
          f"{row['speedup']:>6.2f}x {str(row['same_pixels_won']):>5} "
          f"{row['row_l1_change_median']:>9.1e} {row['row_l1_change_max']:>9.1e}", flush=True)
    return row


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_hiz")
    parser.add_argument("--scene", action="append", default=[], type=Path,
                        help="a scene (OBJ with its .toml beside it, glTF, MGF); repeatable")
    parser.add_argument("--patches", type=int, default=150)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args([] if argv is None else argv)
    print(f"{'scene':>18} {'elems':>7} {'passes':>6} {'depth':>6} {'auto':>6} {'off s':>8} "
          f"{'on s':>8} {'ratio':>7} {'same':>5} {'ΔF med':>9} {'ΔF max':>9}")
    rows = [scene(p, args.patches, args.repeats) for p in (args.scene or DEFAULT)]
    RESULTS.parent.mkdir(exist_ok=True)
    RESULTS.write_text(json.dumps(rows, indent=2) + "\n")
    return rows


if __name__ == "__main__":
    main(__import__("sys").argv[1:])
