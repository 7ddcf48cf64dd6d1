"""The pipeline on one screen: load → mesh → direct → solve → render → write (DESIGN §1)."""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

from daskrad import render, shoot, solve
from daskrad.distributed.monitor import Preview, Watch
from daskrad.distributed.store import Store
from daskrad.errors import OptionError
from daskrad.io import write_exr, write_png, write_report
from daskrad.kernels.grid import build_grid
from daskrad.mesh import build_hierarchy, default_sizes, hierarchy_triangles, vertex_average
from daskrad.scene import load_scene
from daskrad.settings import Settings


def run(scene_path, output, settings: Settings, progress: bool = True,
        config=None, resume: bool = False, executor=None) -> dict:
    """Solve and render ``scene_path``; write ``output`` (.exr), .png, .json and the solution
    store .zarr beside it. ``resume``: continue from the store's last checkpoint.
    ``executor``: run on this one (left open) instead of the settings' choice.

    Returns the run report (also written as JSON).
    """
    output = Path(output)
    if output.suffix.lower() != ".exr":
        raise OptionError(f"the output must end in .exr, got {output.name}")
    if not output.parent.is_dir():
        raise OptionError(f"no such directory for the output: {output.parent}")
    seconds: dict[str, float] = {}
    t = time.perf_counter()

    scene = load_scene(scene_path, config)                                   # 1 preprocess
    if settings.workers is None:
        settings = settings.replace(workers=_auto_workers(scene, settings))
    store = Store(output.with_suffix(".zarr"), settings, resume=resume)
    executor = executor or _executor(settings, store)
    try:
        store.open()                  # a new store, or the checkpoint to resume from
        if executor.dashboard_link:
            print(f"daskrad: dashboard {executor.dashboard_link} (progress: "
                  f"{executor.dashboard_link.rsplit('/', 1)[0]}/daskrad)", file=sys.stderr)
        bar = _Bar(settings, enabled=progress)
        extra: dict = {}
        h, reflectance, sol, grid_parts = solve_scene(scene, settings, executor, seconds,
                                                      on_batch=bar, extra=extra,
                                                      store=store)              # 2, 3
        bar.close()
        t = time.perf_counter()
        tris, tri_verts, tri_elem, grid = grid_parts
        amb = solve.ambient(h, reflectance, sol.unshot)                      # 4 per-pixel pass
        camera = _camera(scene, settings)
        ctx = _render_context(scene, settings, h, reflectance, sol, amb, extra,
                              (tri_verts, tri_elem, grid), camera)
        tiles = render.tiles(camera.width, camera.height)
        image = np.zeros((camera.height, camera.width, 3))
        for (rows, cols), tile in zip(tiles, executor.tiles(ctx, tiles), strict=True):
            image[rows, cols] = tile
        store.finish(ctx.vertex_radiance * math.pi)
        seconds["render"], t = time.perf_counter() - t, time.perf_counter()
    finally:
        executor.close()

    write_exr(output, image)                                                 # 5 output
    write_png(output.with_suffix(".png"), image)
    warnings = [w for w in (_unlit_warning(scene, h, reflectance, sol, extra),) if w]
    for w in warnings:
        print(f"daskrad: warning: {w}", file=sys.stderr)
    report = {
        "scene": str(scene_path),
        "output": str(output),
        "counts": {"polygons": len(scene.polygons), "patches": h.n_patches,
                   "elements": h.n_elements, "vertices": len(h.vertices),
                   "emitters": int(scene.emitting.sum()),
                   "point_lights": len(scene.point_lights),
                   "directional_lights": len(scene.directional_lights),
                   "dropped_degenerate": scene.dropped_degenerate,
                   # eq. 9: elements whose direct light the per-pixel pass recomputes
                   "perpixel_elements": int(ctx.elem_perpixel.sum())
                   if ctx.elem_perpixel is not None else 0},
        "iterations": sol.iteration,
        "converged": sol.converged,
        "unshot_rms_history": [
            {"iteration": i, "relative_unshot_rms": r, "seconds": s} for i, r, s in sol.history],
        "ambient": amb,
        "seconds": seconds,
        "workers": executor.workers,
        "settings": settings.as_dict(),
        "image": {"width": camera.width, "height": camera.height,
                  "mean_radiance": image.reshape(-1, 3).mean(axis=0)},
        "warnings": warnings,
    }
    seconds["write"] = time.perf_counter() - t
    write_report(output.with_suffix(".json"), report)
    if not sol.converged:
        print(f"daskrad: warning: not converged after {sol.iteration} shots (relative unshot "
              f"RMS {sol.history[-1][1] if sol.history else 1.0:.3g} > {settings.tolerance:g});"
              " the image adds an ambient term", file=sys.stderr)
    return report


def _unlit_warning(scene, h, reflectance, sol, extra) -> str | None:
    """The warning for a scene where no surface receives light, else ``None``.

    No element got direct irradiance (point, directional or gathered area light) and no shot
    reflected anything (``B = E`` everywhere): typically every face points away from every
    light, and the image would be black but for the emitters, silently (issue 7). A scene
    that reflects nothing (ρ = 0 everywhere) is dark by design and not warned about.
    """
    if not (reflectance > 0).any():
        return None
    H = extra.get("vertex_irradiance")
    emission = math.pi * scene.materials.emission[h.elem_material]
    if (H is not None and (H > 0).any()) or (sol.radiosity > emission).any():
        return None
    return ("no surface receives any light (zero direct irradiance and nothing received from "
            "emitters): the image shows only the emitters; check that faces and lights point "
            "at each other")


def solve_scene(scene, settings: Settings, executor=None, seconds: dict | None = None,
                on_batch=None, extra: dict | None = None, store=None):
    """Steps 1–3 on a loaded scene: hierarchy, grid, direct light and subdivision, shooting.

    Returns ``(hierarchy, reflectance (E, 3), solution, (triangles, tri_verts, tri_element,
    grid))``, the hierarchy after adaptive subdivision. ``executor`` defaults to in-process;
    ``seconds`` collects step timings; ``extra`` (a dict) receives the direct pass's
    ``vertex_irradiance (V, 3)``, ``tvertices``, ``direct_context`` and ``levels``.
    ``store`` (a :class:`~daskrad.distributed.store.Store`) receives the hierarchy and
    checkpoints, and when resuming gives the solution to continue from.
    """
    from daskrad.distributed.executor import InProcess

    seconds = {} if seconds is None else seconds
    executor = executor or InProcess()
    t = time.perf_counter()
    h = build_hierarchy(scene, settings.patch_size, settings.element_size)
    tris, tri_verts, tri_elem = hierarchy_triangles(h)
    grid = build_grid(tris)
    emission = math.pi * scene.materials.emission[h.elem_material]  # Ke radiance; exitance πKe
    seconds["preprocess"], t = time.perf_counter() - t, time.perf_counter()

    h, grid, tris, tri_verts, tri_elem, sol = _direct_pass(
        scene, settings, h, grid, tris, tri_verts, tri_elem, emission, executor, seconds, extra)
    reflectance = scene.materials.diffuse[h.elem_material]
    t = time.perf_counter()
    watch = None
    if store is not None:  # hierarchy once per generation; checkpoints; dashboard progress
        sol = store.begin(h, reflectance, sol)
        preview = Preview(h, reflectance, tri_verts, tri_elem, grid, _camera(scene, settings))
        on_batch = watch = Watch(store, executor, settings, h, str(scene.path), preview,
                                 then=on_batch)
    executor.set_geometry(shoot.make_context(h, settings.method, settings.resolution,
                                             edge_angle=settings.edge_angle), h.generation)
    sol = solve.solve(h, reflectance, sol, executor.shots, batch=settings.batch,
                      tolerance=settings.tolerance, max_iterations=settings.max_iterations,
                      on_batch=on_batch)
    if watch is not None:
        watch.finish(sol)
    seconds["solve"] = time.perf_counter() - t
    return h, reflectance, sol, (tris, tri_verts, tri_elem, grid)


def _render_context(scene, settings, h, reflectance, sol, amb, extra, grid_parts, camera):
    """The tile renderer's context: vertex radiance split into its interpolated part and the
    direct part (exact at vertices), T-vertices resolved from their edges (no seams)."""
    from daskrad import direct
    from daskrad.mesh.refine import TVertices, resolve_tvertices

    tri_verts, tri_elem, grid = grid_parts
    H = extra.get("vertex_irradiance")
    tv = extra.get("tvertices") or TVertices.empty()
    if H is None:
        indirect = vertex_average(h, sol.radiosity + reflectance * amb)
        direct_v = np.zeros_like(indirect)
    else:
        # the direct part is known exactly at every vertex: E + ρ H (one polygon per vertex)
        emission = math.pi * scene.materials.emission[h.elem_material]
        direct_v = (direct.vertex_reflectance(h, emission)
                    + direct.vertex_reflectance(h, reflectance) * H)
        indirect = vertex_average(h, sol.radiosity - sol.direct + reflectance * amb)
        # what the direct pass gathered beyond E + ρH of the vertices (nothing, in two-pass;
        # with emitters shot, their direct light is part of `indirect`)
    indirect = resolve_tvertices(indirect, tv) / math.pi
    direct_v = resolve_tvertices(direct_v, tv) / math.pi
    ctx = render.RenderContext(grid=grid, tri_verts=tri_verts, tri_element=tri_elem,
                               elem_normal=h.elem_normal, vertex_radiance=indirect + direct_v,
                               camera=camera, spp=settings.spp)
    # step 4: per-pixel direct light (eq. 9), Phong highlights, mirrors; the plain context
    # comes back when the scene needs none of them
    dctx = extra.get("direct_context")
    mats = scene.materials
    return render.perpixel_context(
        ctx, h.elem_verts, vertex_indirect=indirect, vertex_direct=direct_v,
        elem_reflectance=reflectance, elem_emission=mats.emission[h.elem_material],
        elem_specular=mats.specular[h.elem_material],
        elem_shininess=mats.shininess[h.elem_material], elem_mirror=mats.mirror[h.elem_material],
        lights=direct.lights_of(dctx) if (H is not None and dctx is not None) else None,
        rdiff=settings.rdiff if settings.per_pixel else None,
        mirror_depth=settings.mirror_depth, diagonal=scene.diagonal)


def _direct_pass(scene, settings, h, grid, tris, tri_verts, tri_elem, emission, executor,
                 seconds, extra):
    """Step 2: direct light at vertices, adaptive subdivision, the start of the solution.

    With ``settings.two_pass`` area lights are gathered here and never shot; otherwise they
    are shot like any patch and only point and directional lights are gathered.
    """
    from daskrad import direct
    from daskrad.mesh.refine import MIN_SIZE_DIVISOR, TVertices, refine

    extra = {} if extra is None else extra
    has_point = len(scene.point_lights) or len(scene.directional_lights)
    if not (has_point or (settings.two_pass and scene.emitting.any())):
        extra.update(vertex_irradiance=None, tvertices=TVertices.empty(), direct_context=None,
                     levels=0)
        return h, grid, tris, tri_verts, tri_elem, solve.initial_solution(h, emission)
    t = time.perf_counter()
    ctx = direct.make_context(scene, h, grid, settings.area_samples, method=settings.area_method)
    if not settings.two_pass:  # emitters are shot: gather point and directional lights only
        ctx = _without_emitters(ctx)
    H = direct.compute(ctx, 0, len(h.vertices), executor)
    diffuse = scene.materials.diffuse

    def evaluate(h2, start, stop):
        part = direct.compute(direct.with_hierarchy(ctx, h2), start, stop, executor)
        parts.append(part)
        rho = direct.vertex_reflectance(h2, diffuse[h2.elem_material])[start:stop]
        return rho * part

    parts = [H]
    element_size = settings.element_size or default_sizes(scene)[1]
    min_size = settings.min_element_size or element_size / MIN_SIZE_DIVISOR
    rho_v = direct.vertex_reflectance(h, diffuse[h.elem_material])
    h, _, tv, levels = refine(h, rho_v * H, evaluate, threshold=settings.subdivide,
                              min_size=min_size)
    H = np.concatenate(parts)
    if levels:
        tris, tri_verts, tri_elem = hierarchy_triangles(h)
        grid = build_grid(tris)
        ctx = direct.with_hierarchy(ctx, h)
    mat = h.elem_material
    emission = math.pi * scene.materials.emission[mat]
    reflected = diffuse[mat] * direct.element_mean(h, H)
    if settings.two_pass:
        sol = solve.initial_solution(h, emission, reflected)
    else:  # emitters are shot like any patch, on top of the gathered point/directional light
        sol = solve.initial_solution(h, emission)
        sol.radiosity += reflected
        sol.direct += reflected
        sol.unshot += solve.patch_average(h, reflected)
        sol.initial_rms = solve.unshot_rms(sol.unshot, h.patch_area)
    extra.update(vertex_irradiance=H, tvertices=tv, direct_context=ctx, levels=levels)
    seconds["direct"] = time.perf_counter() - t
    return h, grid, tris, tri_verts, tri_elem, sol


def _without_emitters(ctx):
    """The direct context with no area light (emitters are shot instead)."""
    from dataclasses import replace

    return replace(ctx, emitter_corners=np.zeros((0, 4, 3)),
                   emitter_count=np.zeros(0, np.int64), emitter_normal=np.zeros((0, 3)),
                   emitter_radiance=np.zeros((0, 3)), emitter_area=np.zeros(0))


#: Without --workers, a scene of fewer elements (estimated) runs in-process: starting a
#: LocalCluster costs 2–3 s, more than 2 workers save on the default Cornell box (~6 s).
AUTO_CLUSTER_ELEMENTS = 20_000


def _auto_workers(scene, settings: Settings) -> int:
    """``--workers`` not given: 2 local workers, or 0 for a small scene (DESIGN §4)."""
    from daskrad.mesh import polygon_areas

    size = settings.element_size or default_sizes(scene)[1]
    estimate = float(polygon_areas(scene).sum()) / size**2
    return 0 if estimate < AUTO_CLUSTER_ELEMENTS else 2


def _executor(settings: Settings, store=None):
    from daskrad.distributed.executor import InProcess

    if settings.workers == 0 and settings.scheduler is None:
        return InProcess()
    from daskrad.distributed import connect

    return connect(settings, store)


def _camera(scene, settings: Settings):
    cam = scene.camera or render.default_camera(scene.bounds, inside=render.faces_inward(scene))
    return dataclasses.replace(cam, width=settings.width or cam.width,
                               height=settings.height or cam.height)


class _Bar:
    """Progress: shots done and the relative unshot RMS against the tolerance (tqdm, stderr)."""

    def __init__(self, settings: Settings, enabled: bool):
        self.bar = None
        if enabled:
            from tqdm import tqdm

            # the bar counts decades of unshot RMS reduction: 0 → log10(1/tolerance)
            self.total = max(1e-9, math.log10(1.0 / settings.tolerance))
            self.bar = tqdm(total=round(self.total, 2), desc="shooting", unit="dec",
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}",
                            file=sys.stderr)

    def __call__(self, sol: solve.Solution) -> None:
        if self.bar is None or not sol.history:
            return
        it, rms, sec = sol.history[-1]
        done = min(self.total, math.log10(1.0 / max(rms, 1e-300)))
        self.bar.n = round(max(0.0, done), 2)
        self.bar.set_postfix_str(f"shot {it}, unshot {rms:.2e}, {sec:.1f}s", refresh=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def settings_from_args(args) -> Settings:
    """Settings from the CLI's namespace: options not given keep their defaults."""
    fields = Settings.__dataclass_fields__
    given = {k: v for k, v in vars(args).items()
             if k in fields and v is not None}
    if given.get("scheduler") is not None:
        given["workers"] = 0
    elif "workers" not in given:
        given["workers"] = None            # chosen from the scene's size by run()
    return Settings(**given)


def run_cli(args) -> None:
    settings = settings_from_args(args)
    output = args.output or str(Path(args.scene).with_suffix(".exr").name)
    try:
        run(args.scene, output, settings, progress=not args.quiet, config=args.config,
            resume=args.resume)
    except SystemError as err:
        # Ctrl-C inside a numba kernel surfaces as "SystemError: ... returned a result with
        # an exception set" chained to the KeyboardInterrupt: report it as the interrupt
        cause = err
        while cause is not None and not isinstance(cause, KeyboardInterrupt):
            cause = cause.__cause__ or cause.__context__
        if cause is None:
            raise
        raise KeyboardInterrupt from None
    print(f"wrote {output}, {Path(output).with_suffix('.png')}, "
          f"{Path(output).with_suffix('.json')}")


def info_text(args) -> str:
    """``daskrad info``: the hierarchy, emitters and lights, bounding box and grid size."""
    scene = load_scene(args.scene, args.config)
    h = build_hierarchy(scene, args.patch_size, args.element_size)
    patch_size, element_size = (args.patch_size or default_sizes(scene)[0],
                                args.element_size or default_sizes(scene)[1])
    tris, _, _ = hierarchy_triangles(h)
    grid = build_grid(tris)
    lo, hi = scene.bounds
    quads = int((scene.polygons[:, 3] >= 0).sum())
    lines = [
        f"scene       {scene.path}",
        f"polygons    {len(scene.polygons)} ({quads} quads, {len(scene.polygons) - quads} "
        "triangles)" + (f", {scene.dropped_degenerate} degenerate dropped"
                        if scene.dropped_degenerate else ""),
        f"patches     {h.n_patches} (edge <= {patch_size:.4g})",
        f"elements    {h.n_elements} (edge <= {element_size:.4g})",
        f"vertices    {len(h.vertices)}",
        f"materials   {len(scene.materials)}: {', '.join(scene.materials.names)}",
        f"emitters    {int(scene.emitting.sum())} polygons",
        f"lights      {len(scene.point_lights)} point, {len(scene.directional_lights)} "
        "directional",
        f"bounds      [{lo[0]:.4g}, {lo[1]:.4g}, {lo[2]:.4g}] .. "
        f"[{hi[0]:.4g}, {hi[1]:.4g}, {hi[2]:.4g}]",
        f"grid        {grid.dims[0]} x {grid.dims[1]} x {grid.dims[2]} cells over "
        f"{len(tris)} triangles",
    ]
    return "\n".join(lines)
