"""The ``daskrad`` subcommands over the pipeline: ``run`` and ``info`` (the CLI parses,
these compose the steps of :mod:`daskrad.run`)."""

from __future__ import annotations

from pathlib import Path

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


def run_command(args) -> None:
    from daskrad import warmup
    from daskrad.run import interrupted, run

    settings = settings_from_args(args)
    output = args.output or str(Path(args.scene).with_suffix(".exr").name)
    if not warmup.is_warm():
        # bad input is still one line and exit 2, before any compiling is announced
        from daskrad.output import Outputs

        settings.validate()
        Outputs.of(output)
        from daskrad.preprocess import check_size

        check_size(load_scene(args.scene, args.config, args.camera), settings)
        warmup.announce()
        warmup.warmup(verbose=False)
    try:
        run(args.scene, output, settings, progress=not args.quiet, config=args.config,
            resume=args.resume, camera=args.camera)
    except SystemError as err:
        # Ctrl-C inside a numba kernel surfaces as "SystemError: ... returned a result with
        # an exception set" chained to the KeyboardInterrupt: report it as the interrupt
        if not interrupted(err):
            raise
        raise KeyboardInterrupt from None
    out = Path(output)
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
