"""The render's ray work, each cut against what it replaced, in one process (issue 12, item 3).

For each scene (the bundled Cornell box; ``--scene PATH`` with ``--config TOML`` adds one, e.g.
RenderPark's office, which is not in the repository), solved with the defaults (``--shots``
caps the solve) at ``--size`` pixels, two comparisons, alternated ``--repeat`` times (medians):

- **fans** (:class:`daskrad.kernels.grid.Fan`): the junction gather's operator rows, the rays
  from each vertex skipping the triangles below its tangent plane, against the plain walk
  (:func:`daskrad.kernels.grid.closest_hit_one`, the same kernel otherwise). Both give the
  same rows (checked bit for bit). The rays of a gather by rays, whatever the scene's method
  (:func:`daskrad.render.gather_method`); the tiles below are those of the run's own gather
  (the disc in a scene of few polygons), the same in every arm.
- **light modes** (:func:`daskrad.render.light_modes`): the per-pixel pass's tiles (the gather
  applied once beforehand) when a light every corner of an element sees is taken as visible
  without shadow rays, against tracing every light at every hit. The images are compared:
  pixels that changed, the relative RMS of the change and the largest change relative to
  the pixel.
- **hidden lights** (:func:`daskrad.render.hidden_lights`): the same tiles with the lights
  proved hidden from an element skipped, against the light modes without them (every hidden
  light traced). Both give the same image (checked bit for bit).
- **shadow probes** (:data:`daskrad.render.SHADOW_PROBES`): the same tiles (light modes and
  all) when a traced area light is first probed from its four corner strata, against tracing
  every stratum. Probing is not exact, so both images are compared with a reference of the
  same tiles at 4× the shadow rays (8 × 8 a light, no probes; rendered once): relative RMS
  error and the pixels more than 5 % off; and the probed image against tracing every stratum
  (noise-free: the same rays but those spared): pixels changed, relative RMS of the change,
  the largest change relative to the pixel.
- **Lambert after the rays** (:data:`daskrad.render.LAMBERT_AFTER_RAYS`): the same tiles (probes
  and all) when an area light's ``F`` is computed only after one of its shadow rays came
  through, against computing it first. Both give the same image (checked bit for bit).
- **polygon occluders** (:data:`daskrad.render.POLYGON_OCCLUDERS`): the same tiles (all of the
  above) when the shadow rays walk the grid over the scene's polygons, against the grid over
  the elements. The same surfaces, so the same image but along an edge the elements add
  inside a polygon: pixels changed and the largest change relative to the pixel.
- **shadow cache** (:data:`daskrad.render.SHADOW_CACHE`): the same tiles (all of the above)
  when each area light's shadow rays first try the triangle that blocked its last ray,
  against walking the grid for every ray. Both give the same image (checked bit for bit).
- **shading kernels** (:func:`daskrad.kernels.shade.shade_hits`, :func:`~daskrad.kernels.
  shade.gouraud`): the same tiles (all of the above) when the Gouraud shading of the hits
  runs in one kernel pass, against the NumPy expressions it replaced (kept here as the
  reference arm), on one thread and on two (NumPy's fancy indexing holds the GIL). Both give
  the same image (checked bit for bit).

Seconds are wall time in this process, one thread (but where said). ``python -m
benchmarks.bench_perpixel [--scene PATH --config TOML] [--size W H] [--shots N] [--repeat N]
[--json NAME]``; writes ``benchmarks/results/perpixel.json`` (or ``NAME`` there).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit

from daskrad import direct, render, solve
from daskrad.distributed.executor import InProcess
from daskrad.kernels.direct import LIGHT_HIDDEN, LIGHT_TRACE, hash01
from daskrad.kernels.gather import cosine_direction
from daskrad.kernels.grid import aim_fan, closest_hit_fan, closest_hit_one, new_fan
from daskrad.kernels.pathtrace import tangent_frame
from daskrad.preprocess import preprocess
from daskrad.scene import load_scene
from daskrad.settings import Settings

RESULTS = Path(__file__).parent / "results"
CORNELL = Path(__file__).parent.parent / "scenes" / "cornell_box.obj"


@njit(cache=True)
def _gather_hits(grid, points, normals, seeds, off, side, fanned):
    """``(t, tri)`` of the gather's rays (:func:`daskrad.kernels.gather.gather_operator`'s
    directions), through a fan or the plain walk."""
    n, ss = points.shape[0], side * side
    t_out = np.empty(n * ss)
    tri_out = np.empty(n * ss, np.int64)
    fan = new_fan(grid)
    d = np.empty(3)
    for i in range(n):
        nrm = normals[i]
        t, s = tangent_frame(nrm)
        o = points[i] + off * nrm
        aim_fan(fan, grid, o, nrm, off)
        for k in range(ss):
            u = ((k % side) + hash01(seeds[i], 2 * k)) / side
            v = ((k // side) + hash01(seeds[i], 2 * k + 1)) / side
            cosine_direction(d, nrm, t, s, u, v)
            if fanned:
                th, tri, _, _ = closest_hit_fan(grid, fan, o, d, off, np.inf)
            else:
                th, tri, _, _ = closest_hit_one(grid, o, d, off, np.inf)
            t_out[i * ss + k] = th
            tri_out[i * ss + k] = tri
    return t_out, tri_out


def _gather_context(ctx: render.RenderContext) -> render.GatherContext:
    """The junction gather's rays of ``ctx`` (every gathered vertex), as the render casts
    them when it gathers by rays (a scene of few polygons gathers by the disc,
    :func:`daskrad.render.gather_method`: by rays here, whose walks this benchmark times)."""
    seen = {}
    original = render.gather_vertices
    few = render.DISC_POLYGONS

    def capture(gctx, start, stop):
        seen["gctx"] = gctx
        return original(gctx, start, stop)

    render.gather_vertices = capture
    render.DISC_POLYGONS = -1
    try:
        render.for_view(ctx)
    finally:
        render.gather_vertices = original
        render.DISC_POLYGONS = few
    return seen["gctx"]


def measure(path: Path, config: Path | None, size: tuple[int, int], shots: int,
            repeat: int) -> dict:
    settings = Settings(workers=0, width=size[0], height=size[1], max_iterations=shots)
    scene = load_scene(path, config)
    ex = InProcess(threads=1)
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    sol = solve.radiosity(light, settings, ex)
    ctx = render.context(scene, light, sol, settings, render.camera(scene, settings))
    g = _gather_context(ctx)
    args = (g.grid, g.points, g.normals, g.seeds, float(g.offset), int(g.side))
    _gather_hits(*args, True)                   # compile (or load) before timing
    times = {"plain": [], "fan": []}
    hits = {}
    for _ in range(repeat):
        for name, fanned in (("plain", False), ("fan", True)):
            t = time.perf_counter()
            hits[name] = _gather_hits(*args, fanned)
            times[name].append(time.perf_counter() - t)
    same_rays = all(np.array_equal(a, b) for a, b in zip(hits["plain"], hits["fan"],
                                                         strict=True))
    viewed = render.for_view(ctx)
    tracing = replace(viewed, elem_light_mode=None)
    modes = viewed.elem_light_mode
    unproved = (replace(viewed, elem_light_mode=np.where(
        modes == LIGHT_HIDDEN, LIGHT_TRACE, modes).astype(np.int8))
        if modes is not None else viewed)
    images = {}
    tiles = {"trace": [], "visible": [], "modes": []}
    for _ in range(repeat):
        for name, c in (("trace", tracing), ("visible", unproved), ("modes", viewed)):
            t = time.perf_counter()
            images[name] = render.render(c)
            tiles[name].append(time.perf_counter() - t)
    probes = _probes(viewed, repeat)
    a, b = images["trace"], images["visible"]
    diff = np.abs(a - b).max(axis=2)
    pp = viewed.elem_perpixel if viewed.elem_perpixel is not None else np.zeros(0, bool)
    return {
        "scene": path.name, "elements": int(len(ctx.elem_normal)),
        "gathered_vertices": int(len(g.points)), "gather_rays": int(len(g.points) * g.side**2),
        "gather_plain_s": float(np.median(times["plain"])),
        "gather_fan_s": float(np.median(times["fan"])),
        "gather_speedup": float(np.median(times["plain"]) / np.median(times["fan"])),
        "gather_same_hits": bool(same_rays),
        "perpixel_elements": int(pp.sum()),
        "perpixel_light_pairs": int(modes[pp].size) if modes is not None else 0,
        "perpixel_pairs_taken_visible": int((modes[pp] == 1).sum()) if modes is not None else 0,
        "tiles_trace_s": float(np.median(tiles["trace"])),
        "tiles_modes_s": float(np.median(tiles["modes"])),
        "tiles_visible_s": float(np.median(tiles["visible"])),
        "tiles_speedup": float(np.median(tiles["trace"]) / np.median(tiles["visible"])),
        "perpixel_pairs_proved_hidden": (int((modes[pp] == LIGHT_HIDDEN).sum())
                                         if modes is not None else 0),
        "hidden_speedup": float(np.median(tiles["visible"]) / np.median(tiles["modes"])),
        "hidden_same_bits": bool(np.array_equal(images["visible"], images["modes"])),
        "pixels": int(diff.size), "pixels_changed": int((diff > 0).sum()),
        "change_relative_rms": float(np.sqrt(((a - b) ** 2).mean()) / math.sqrt((a**2).mean())),
        "change_largest_relative": float((diff / np.maximum(a.max(axis=2), 1e-300)).max()),
        **probes,
        **_lambert(viewed, repeat),
        **_arms(viewed, "POLYGON_OCCLUDERS", "occluders", repeat),
        **_arms(viewed, "SHADOW_CACHE", "cache", repeat),
        **_shading(viewed, repeat),
    }


def _tiles_with(ctx: render.RenderContext, flag: str, value: bool):
    """``(image, seconds)``: the tiles of ``ctx`` with :mod:`daskrad.render`'s module flag
    ``flag`` set to ``value`` (restored after)."""
    keep = getattr(render, flag)
    setattr(render, flag, value)
    try:
        t = time.perf_counter()
        return render.render(ctx), time.perf_counter() - t
    finally:
        setattr(render, flag, keep)


def _alternated(ctx: render.RenderContext, flag: str, repeat: int):
    """``(seconds, images)`` keyed by the flag's value (False, True), the two arms alternated
    ``repeat`` times (:func:`_tiles_with`)."""
    seconds = {True: [], False: []}
    images = {}
    for k in range(repeat):
        for value in ((False, True) if k % 2 == 0 else (True, False)):
            images[value], t = _tiles_with(ctx, flag, value)
            seconds[value].append(t)
    return seconds, images


def _probes(ctx: render.RenderContext, repeat: int) -> dict:
    """The tiles of ``ctx`` with and without shadow probes, alternated ``repeat`` times, and
    each image's error against a reference at 4× the shadow rays without probes."""
    if ctx.lights is None:
        return {}
    seconds, images = _alternated(ctx, "SHADOW_PROBES", repeat)
    ref, _ = _tiles_with(replace(ctx, lights=replace(ctx.lights,
                                                     samples=2 * ctx.lights.samples)),
                         "SHADOW_PROBES", False)
    scale = math.sqrt((ref**2).mean())

    def error(image):
        off = np.abs(image - ref).max(axis=2) / np.maximum(ref.max(axis=2), 1e-300)
        return float(np.sqrt(((image - ref) ** 2).mean()) / scale), int((off > 0.05).sum())

    (full_rms, full_off), (probe_rms, probe_off) = error(images[False]), error(images[True])
    # the probes' own change, noise-free: the same rays but those spared
    change = np.abs(images[True] - images[False]).max(axis=2)
    largest = float((change / np.maximum(images[False].max(axis=2), 1e-300)).max())
    return {"tiles_every_stratum_s": float(np.median(seconds[False])),
            "tiles_probes_s": float(np.median(seconds[True])),
            "probes_speedup": float(np.median(seconds[False]) / np.median(seconds[True])),
            "every_stratum_error_rms": full_rms, "every_stratum_pixels_off_5pct": full_off,
            "probes_error_rms": probe_rms, "probes_pixels_off_5pct": probe_off,
            "probes_pixels_changed": int((change > 0).sum()),
            "probes_change_relative_rms": float(
                np.sqrt(((images[True] - images[False]) ** 2).mean()) / scale),
            "probes_change_largest_relative": largest}


def _lambert(ctx: render.RenderContext, repeat: int) -> dict:
    """The tiles of ``ctx`` with Lambert's ``F`` after the shadow rays and before them,
    alternated ``repeat`` times."""
    if ctx.lights is None:
        return {}
    seconds, images = _alternated(ctx, "LAMBERT_AFTER_RAYS", repeat)
    return {"tiles_lambert_first_s": float(np.median(seconds[False])),
            "tiles_lambert_after_s": float(np.median(seconds[True])),
            "lambert_after_speedup": float(np.median(seconds[False])
                                           / np.median(seconds[True])),
            "lambert_after_same_bits": bool(np.array_equal(images[True], images[False]))}


def _arms(ctx: render.RenderContext, flag: str, name: str, repeat: int) -> dict:
    """The tiles of ``ctx`` with :mod:`daskrad.render`'s ``flag`` off and on, alternated
    ``repeat`` times: medians, their ratio, and how the image changed."""
    if ctx.lights is None:
        return {}
    seconds, images = _alternated(ctx, flag, repeat)
    a, b = images[False], images[True]
    change = np.abs(a - b).max(axis=2)
    return {f"tiles_{name}_off_s": float(np.median(seconds[False])),
            f"tiles_{name}_on_s": float(np.median(seconds[True])),
            f"{name}_speedup": float(np.median(seconds[False]) / np.median(seconds[True])),
            f"{name}_same_bits": bool(np.array_equal(a, b)),
            f"{name}_pixels_changed": int((change > 0).sum()),
            f"{name}_change_largest_relative": float(
                (change / np.maximum(a.max(axis=2), 1e-300)).max())}


def _numpy_gouraud(values, tri_verts, tri, u, v):
    """The NumPy Gouraud shading :func:`daskrad.kernels.shade.gouraud` replaced."""
    c = tri_verts[tri]
    uh, vh = u[:, None], v[:, None]
    return (1.0 - uh - vh) * values[c[:, 0]] + uh * values[c[:, 1]] + vh * values[c[:, 2]]


def _numpy_shade_hits(values, tri_verts, tri_element, elem_normal, directions, tri, u, v):
    """The NumPy shading of hits :func:`daskrad.kernels.shade.shade_hits` replaced."""
    n = len(tri)
    out, front = np.zeros((n, 3)), np.zeros(n, bool)
    hit = tri >= 0
    if hit.any():
        th = tri[hit]
        f = np.einsum("ij,ij->i", directions[hit], elem_normal[tri_element[th]]) < 0.0
        out[hit] = np.where(f[:, None], _numpy_gouraud(values, tri_verts, th, u[hit], v[hit]),
                            0.0)
        front[hit] = f
    return out, front


def _shading(ctx: render.RenderContext, repeat: int) -> dict:
    """The tiles of ``ctx`` with the shading kernels and with the NumPy they replaced,
    alternated ``repeat`` times, on one thread and on two."""
    arms = {"numpy": (_numpy_shade_hits, _numpy_gouraud),
            "kernels": (render.shade_hits, render.gouraud)}
    seconds: dict = {(a, t): [] for a in arms for t in (1, 2)}
    images = {}
    ex = InProcess(threads=2)
    try:
        for k in range(repeat):
            for arm in (list(arms) if k % 2 == 0 else list(arms)[::-1]):
                render.shade_hits, render.gouraud = arms[arm]
                try:
                    for threads in (1, 2):
                        t = time.perf_counter()
                        images[arm, threads] = (render.render(ctx) if threads == 1
                                                else render.pixels(ctx, ex))
                        seconds[arm, threads].append(time.perf_counter() - t)
                finally:
                    render.shade_hits, render.gouraud = arms["kernels"]
    finally:
        ex.close()
    med = {k: float(np.median(v)) for k, v in seconds.items()}
    return {"tiles_numpy_shading_s": med["numpy", 1], "tiles_shading_kernels_s": med["kernels", 1],
            "shading_speedup": med["numpy", 1] / med["kernels", 1],
            "tiles_numpy_shading_2threads_s": med["numpy", 2],
            "tiles_shading_kernels_2threads_s": med["kernels", 2],
            "shading_speedup_2threads": med["numpy", 2] / med["kernels", 2],
            "shading_same_bits": bool(all(np.array_equal(images["numpy", t],
                                                         images["kernels", t])
                                          for t in (1, 2)))}


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_perpixel")
    parser.add_argument("--scene", type=Path, action="append", default=[])
    parser.add_argument("--config", type=Path, action="append", default=[],
                        help="a TOML config (camera) per --scene, in order")
    parser.add_argument("--size", type=int, nargs=2, default=(192, 144))
    parser.add_argument("--shots", type=int, default=352)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--json", default="perpixel.json",
                        help="the results file's name in benchmarks/results")
    args = parser.parse_args([] if argv is None else argv)
    configs = args.config + [None] * (len(args.scene) - len(args.config))
    rows = [measure(CORNELL, None, tuple(args.size), args.shots, args.repeat)]
    rows += [measure(p, c, tuple(args.size), args.shots, args.repeat)
             for p, c in zip(args.scene, configs, strict=True)]
    print(f"{'scene':<18}{'gather rays':>12}{'plain':>8}{'fan':>7}{'x':>6}  "
          f"{'pp pairs':>9}{'visible':>8}{'trace':>8}{'modes':>7}{'x':>6}"
          f"{'changed':>9}{'rel RMS':>9}{'largest':>9}  {'hidden':>8}{'tiles':>7}{'x':>6}")
    for r in rows:
        print(f"{r['scene']:<18}{r['gather_rays']:>12,}{r['gather_plain_s']:>8.2f}"
              f"{r['gather_fan_s']:>7.2f}{r['gather_speedup']:>6.2f}  "
              f"{r['perpixel_light_pairs']:>9,}{r['perpixel_pairs_taken_visible']:>8,}"
              f"{r['tiles_trace_s']:>8.2f}{r['tiles_visible_s']:>7.2f}"
              f"{r['tiles_speedup']:>6.2f}"
              f"{r['pixels_changed']:>9,}{r['change_relative_rms']:>9.1e}"
              f"{r['change_largest_relative']:>9.1e}  "
              f"{r['perpixel_pairs_proved_hidden']:>8,}{r['tiles_modes_s']:>7.2f}"
              f"{r['hidden_speedup']:>6.2f}")
        if not r["hidden_same_bits"]:
            print(f"  {r['scene']}: skipping the proved hidden lights changed the image!")
        if not r["gather_same_hits"]:
            print(f"  {r['scene']}: the fan's gather hits differ from the plain walk's!")
    print(f"\n{'shadow probes':<18}{'every':>8}{'probes':>8}{'x':>6}  "
          f"{'rel RMS error (every / probes)':>31}  {'pixels > 5 % (every / probes)':>30}"
          f"{'changed':>9}{'rel RMS':>9}{'largest':>9}")
    for r in rows:
        if "probes_speedup" in r:
            print(f"{r['scene']:<18}{r['tiles_every_stratum_s']:>8.2f}"
                  f"{r['tiles_probes_s']:>8.2f}{r['probes_speedup']:>6.2f}  "
                  f"{r['every_stratum_error_rms']:>15.2e} / {r['probes_error_rms']:<13.2e}  "
                  f"{r['every_stratum_pixels_off_5pct']:>14,} / {r['probes_pixels_off_5pct']:<13,}"
                  f"{r['probes_pixels_changed']:>9,}{r['probes_change_relative_rms']:>9.1e}"
                  f"{r['probes_change_largest_relative']:>9.1e}")
    print(f"\n{'Lambert after rays':<18}{'first':>8}{'after':>8}{'x':>6}  same bits")
    for r in rows:
        if "lambert_after_speedup" in r:
            print(f"{r['scene']:<18}{r['tiles_lambert_first_s']:>8.2f}"
                  f"{r['tiles_lambert_after_s']:>8.2f}{r['lambert_after_speedup']:>6.2f}  "
                  f"{r['lambert_after_same_bits']}")
    print(f"\n{'shadow rays':<18}{'elements':>9}{'polygons':>9}{'x':>6}{'changed':>9}"
          f"{'largest':>9}   {'no cache':>9}{'cache':>7}{'x':>6}  same bits")
    for r in rows:
        if "occluders_speedup" in r:
            print(f"{r['scene']:<18}{r['tiles_occluders_off_s']:>9.2f}"
                  f"{r['tiles_occluders_on_s']:>9.2f}{r['occluders_speedup']:>6.2f}"
                  f"{r['occluders_pixels_changed']:>9,}"
                  f"{r['occluders_change_largest_relative']:>9.1e}   "
                  f"{r['tiles_cache_off_s']:>9.2f}{r['tiles_cache_on_s']:>7.2f}"
                  f"{r['cache_speedup']:>6.2f}  {r['cache_same_bits']}")
    print(f"\n{'shading':<18}{'numpy':>8}{'kernels':>8}{'x':>6}   {'2 threads':>9}"
          f"{'kernels':>8}{'x':>6}  same bits")
    for r in rows:
        print(f"{r['scene']:<18}{r['tiles_numpy_shading_s']:>8.2f}"
              f"{r['tiles_shading_kernels_s']:>8.2f}{r['shading_speedup']:>6.2f}   "
              f"{r['tiles_numpy_shading_2threads_s']:>9.2f}"
              f"{r['tiles_shading_kernels_2threads_s']:>8.2f}"
              f"{r['shading_speedup_2threads']:>6.2f}  {r['shading_same_bits']}")
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return {"perpixel": rows}


if __name__ == "__main__":
    main(sys.argv[1:])
