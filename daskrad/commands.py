"""The ``daskrad`` subcommands over the pipeline: ``run``, ``info``, ``render`` and ``export``
(the CLI parses, these compose the steps of :mod:`daskrad.run`).

``render`` and ``export`` read a finished solution store and never write into it: the render
context the run's image came from is kept in the store (``internal/context/render``), so a new
view is :func:`daskrad.render.pixels` of that context with another camera — no direct pass and
no solve — and gives the same bits as a full run with that camera.
"""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

from daskrad.errors import Interrupted, Terminated, interrupted
from daskrad.scene import load_scene
from daskrad.settings import Settings


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


def resume_hint(output: str) -> str:
    """What an interrupted run of ``output`` leaves: a store ``--resume`` continues (a new
    run's partial store, or the finished one of an earlier run), or none yet."""
    from daskrad.output import Outputs, is_store, store_attributes

    outs = Outputs(Path(output))
    partial = store_attributes(outs.partial)       # read once: None when there is no store
    if partial is not None and partial.get("checkpoint") is not None:   # a slot: 0 is one
        shot = partial.get("iteration")
        at = f" (shot {shot:,})" if isinstance(shot, int) and not isinstance(shot, bool) else ""
        return f"the last checkpoint{at} is kept (use --resume)"
    if partial is None and is_store(outs.store):
        return "the last checkpoint is kept (use --resume)"
    if partial is not None:
        return "it stopped before its first checkpoint: nothing to resume yet"
    return "it stopped before its solution store was written: nothing to resume"


def run_command(args) -> None:
    settings = settings_from_args(args).validate()   # a bad option before Dask and zarr load
    from daskrad import warmup
    from daskrad.run import run

    output = args.output or str(Path(args.scene).with_suffix(".exr").name)
    try:        # a Ctrl-C from here on says what it leaves, even before the run starts
        if not warmup.is_warm():
            # bad input is still one line and exit 2, before any compiling is announced
            from daskrad.distributed import check_scheduler
            from daskrad.output import Outputs
            from daskrad.preprocess import check_size

            check_scheduler(settings)       # as run() does: before the outputs' probe
            Outputs.of(output)
            check_size(load_scene(args.scene, args.config, args.camera), settings)
            warmup.announce()
            warmup.warmup(verbose=False)
        report = run(args.scene, output, settings, progress=not args.quiet,
                     config=args.config, resume=args.resume, camera=args.camera)
    except (SystemError, KeyboardInterrupt) as err:
        # Ctrl-C inside a numba kernel surfaces as "SystemError: ... returned a result with
        # an exception set" chained to the KeyboardInterrupt: report it as the interrupt
        stop = interrupted(err)
        if stop is None:
            raise
        raise Interrupted(resume_hint(output), isinstance(stop, Terminated)) from None
    out = Path(output)
    if args.dashboard is not None and not report["workers"] and settings.scheduler is None:
        from daskrad.output import warn

        warn(f"--dashboard {args.dashboard} was not used: the run stayed in this process, "
             "with no Dask cluster (give --workers N for one)")
    print(f"wrote {out}, {out.with_suffix('.png')}, {out.with_suffix('.json')} and the "
          f"store {out.with_suffix('.zarr')}")


def warmup_command() -> None:
    """``daskrad warmup``: compile every kernel into numba's on-disk cache."""
    from daskrad import warmup

    warmup.warmup(verbose=True)


def info_text(args) -> str:
    """``daskrad info``: the hierarchy, emitters and lights, bounding box and grid size."""
    from daskrad.mesh import default_sizes
    from daskrad.preprocess import preprocess

    scene = load_scene(args.scene, args.config, args.camera)
    settings = Settings(patch_size=args.patch_size, element_size=args.element_size).validate()
    mesh = preprocess(scene, settings)
    h, grid, tris = mesh.hierarchy, mesh.grid, mesh.triangles
    patch_size, element_size = (args.patch_size or default_sizes(scene)[0],
                                args.element_size or default_sizes(scene)[1])
    lo, hi = scene.bounds + scene.origin          # in the file's coordinates
    quads = int((scene.polygons[:, 3] >= 0).sum())
    n_emit = int(scene.emitting.sum())
    lines = [
        f"scene       {scene.path}",
        f"polygons    {len(scene.polygons)} ({quads} quads, {len(scene.polygons) - quads} "
        "triangles)" + (f", {scene.dropped_degenerate} degenerate dropped"
                        if scene.dropped_degenerate else ""),
        f"patches     {h.n_patches} (edge <= {patch_size:.4g})",
        f"elements    {h.n_elements} (edge <= {element_size:.4g}; a run adds those of adaptive "
        "subdivision)",
        f"vertices    {len(h.vertices)}",
        f"materials   {len(scene.materials)}: {', '.join(scene.materials.names)}",
        f"emitters    {n_emit} polygon{'s' if n_emit != 1 else ''}",
        f"lights      {len(scene.point_lights)} point, {len(scene.directional_lights)} "
        "directional",
        f"bounds      [{lo[0]:.4g}, {lo[1]:.4g}, {lo[2]:.4g}] .. "
        f"[{hi[0]:.4g}, {hi[1]:.4g}, {hi[2]:.4g}]",
        f"grid        {grid.dims[0]} x {grid.dims[1]} x {grid.dims[2]} cells over "
        f"{len(tris)} triangles",
    ]
    return "\n".join(lines)


def _camera_of(args, stored):
    """The camera of ``daskrad render``: the run's (``stored``), or ``--config``'s
    ``[camera]``, with each option given replacing its field; :class:`OptionError` for a
    camera that cannot form an image."""
    import numpy as np

    from daskrad.errors import OptionError
    from daskrad.scene.config import read_config

    cam = stored
    if args.config:
        cfg = read_config(args.config)
        if cfg.camera is None:
            raise OptionError("has no [camera] table", args.config)
        cam = cfg.camera
    fields = {k: np.asarray(getattr(args, k), float) for k in ("eye", "look_at", "up")
              if getattr(args, k) is not None}
    for k in ("fov", "width", "height"):
        if getattr(args, k) is not None:
            fields[k] = getattr(args, k)
    cam = replace(cam, **fields)
    if not 0.0 < cam.fov < 180.0:
        raise OptionError(f"--fov must be in (0, 180) degrees, got {cam.fov:g}")
    forward = np.asarray(cam.look_at, float) - np.asarray(cam.eye, float)
    if not np.linalg.norm(forward) > 0:
        raise OptionError("the camera's eye and look-at are the same point")
    up = np.asarray(cam.up, float)
    if not np.linalg.norm(np.cross(forward, up)) > 1e-9 * np.linalg.norm(forward) * \
            np.linalg.norm(up):
        raise OptionError("the camera's up is zero or parallel to the view direction")
    return cam


def render_command(args) -> None:
    """``daskrad render STORE -o VIEW.exr``: a new view of a finished solution."""
    from daskrad.distributed.executor import InProcess
    from daskrad.distributed.store import Result
    from daskrad.errors import OptionError
    from daskrad.io import write_exr, write_png
    from daskrad.output import Outputs, note, replaced_note
    from daskrad.progress import Heartbeat
    from daskrad.render import pixels

    # the store and the options first (reading only), then the outputs, whose check probes
    # their folder with a file of its own
    result = Result(args.store)
    if Path(args.store).absolute() in Path(args.output).absolute().parents:
        raise OptionError("the image must be written outside the store", args.output)
    ctx = result.render_context()
    cam = _camera_of(args, ctx.camera)
    spp = args.spp or ctx.spp
    edge_spp = ctx.edge_spp if args.edge_spp is None else args.edge_spp
    Settings(width=cam.width, height=cam.height, spp=spp, edge_spp=edge_spp).validate()
    outputs = Outputs.of(args.output)
    t = time.perf_counter()
    # the view's junction gather and tiles on every core, as an in-process run renders
    ex = InProcess()
    beat = Heartbeat(not args.quiet)        # a log hears a long render every 30 s
    try:
        beat.say(f"rendering {cam.width} x {cam.height}")
        image = pixels(replace(ctx, camera=cam, spp=spp, edge_spp=edge_spp), ex)
    finally:
        beat.close()
        ex.close()
    replaced = [p for p in (outputs.exr, outputs.png) if p.exists()]
    write_exr(outputs.exr, image)
    write_png(outputs.png, image, stops=args.exposure or 0.0)
    if replaced:
        note(replaced_note(replaced))
    if not args.quiet:
        print(f"rendered {cam.width} x {cam.height} from {args.store} in "
              f"{time.perf_counter() - t:.1f} s")
    print(f"wrote {outputs.exr}, {outputs.png}")


def export_command(args) -> None:
    """``daskrad export STORE OUT.ply|OUT.glb|OUT.obj``: the mesh with its vertex radiance."""
    from daskrad.distributed.store import Result
    from daskrad.io.mesh import write_mesh

    result = Result(args.store)
    ctx = result.render_context()
    vertices = result.array("vertices")
    write_mesh(args.output, vertices, ctx.tri_verts, ctx.vertex_radiance,
               stops=args.exposure or 0.0)
    print(f"wrote {args.output} ({len(ctx.tri_verts)} triangles, {len(vertices)} vertices)")
