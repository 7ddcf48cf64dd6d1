"""Step 5, output: the HDR image, its PNG preview and the run report (docs/design.md §7).

:class:`Outputs` names every file a run writes, from the ``-o OUT.exr`` the user gave, and is
checked before anything is loaded or written; :func:`write` writes the image files and the
report at the end. The solution store (``OUT.zarr``) is written along the way by
:mod:`daskrad.distributed.store`, an observer of the solve.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

from daskrad.direct import DirectLight
from daskrad.errors import OptionError
from daskrad.io import write_exr, write_png, write_report
from daskrad.render import Image
from daskrad.scene.types import Scene
from daskrad.settings import Settings
from daskrad.solve import Solution


@dataclass(frozen=True)
class Outputs:
    """The files of one run: ``exr`` (linear radiance), ``png`` (preview), ``json`` (report)
    and ``store`` (the Zarr solution store), all beside each other with one stem."""

    exr: Path

    @classmethod
    def of(cls, output: str | Path) -> Outputs:
        """The outputs of ``-o OUTPUT``; :class:`OptionError` unless it is ``*.exr`` in an
        existing directory."""
        output = Path(output)
        if output.suffix.lower() != ".exr":
            raise OptionError(f"the output must end in .exr, got {output.name}")
        if not output.parent.is_dir():
            raise OptionError(f"no such directory for the output: {output.parent}")
        return cls(output)

    @property
    def png(self) -> Path:
        return self.exr.with_suffix(".png")

    @property
    def json(self) -> Path:
        return self.exr.with_suffix(".json")

    @property
    def store(self) -> Path:
        return self.exr.with_suffix(".zarr")


def unlit_warning(scene: Scene, light: DirectLight, sol: Solution) -> str | None:
    """The warning for a scene where no surface receives light, else ``None``.

    No element got direct irradiance (point, directional or gathered area light) and no shot
    reflected anything (``B = E`` everywhere): typically every face points away from every
    light, and the image would be black but for the emitters, silently (issue 7). A scene
    that reflects nothing (ρ = 0 everywhere) is dark by design and not warned about.
    """
    mesh = light.mesh
    if not (mesh.reflectance > 0).any():
        return None
    H = light.irradiance
    if (H is not None and (H > 0).any()) or (sol.radiosity > mesh.emission).any():
        return None
    return ("no surface receives any light (zero direct irradiance and nothing received from "
            "emitters): the image shows only the emitters; check that faces and lights point "
            "at each other")


def report(scene: Scene, outputs: Outputs, settings: Settings, light: DirectLight,
           sol: Solution, image: Image, *, workers: int, seconds: dict,
           warnings: list[str]) -> dict:
    """The run report (written as ``OUT.json``): counts, convergence, timings, settings."""
    from daskrad.mesh import default_sizes
    from daskrad.mesh.refine import MIN_SIZE_DIVISOR

    h = light.mesh.hierarchy
    patch_size, element_size = default_sizes(scene)
    patch_size, element_size = (settings.patch_size or patch_size,
                                settings.element_size or element_size)
    cam = image.camera
    return {
        "scene": str(scene.path),
        "output": str(outputs.exr),
        "store": str(outputs.store),
        "versions": versions(),
        # the sizes used, the automatic ones resolved (settings keeps None for them)
        "sizes": {"patch_size": patch_size, "element_size": element_size,
                  "min_element_size": (settings.min_element_size
                                       or element_size / MIN_SIZE_DIVISOR)},
        "camera": {"eye": cam.eye, "look_at": cam.look_at, "up": cam.up, "fov": cam.fov,
                   "width": cam.width, "height": cam.height},
        "counts": {"polygons": len(scene.polygons), "patches": h.n_patches,
                   "elements": h.n_elements, "vertices": len(h.vertices),
                   "emitters": int(scene.emitting.sum()),
                   "point_lights": len(scene.point_lights),
                   "directional_lights": len(scene.directional_lights),
                   "dropped_degenerate": scene.dropped_degenerate,
                   # eq. 9: elements whose direct light the per-pixel pass recomputes
                   "perpixel_elements": image.perpixel_elements},
        "iterations": sol.iteration,
        "converged": sol.converged,
        "unshot_rms_history": [
            {"iteration": i, "relative_unshot_rms": r, "seconds": s} for i, r, s in sol.history],
        "ambient": image.ambient,
        "seconds": seconds,
        "workers": workers,
        "settings": settings.as_dict(),
        "image": {"width": image.camera.width, "height": image.camera.height,
                  "mean_radiance": image.pixels.reshape(-1, 3).mean(axis=0)},
        "warnings": warnings,
    }


def versions() -> dict:
    """The versions of Python, daskrad and the packages whose behaviour the result depends on."""
    import platform
    from importlib import metadata

    from daskrad import __version__

    out = {"python": platform.python_version(), "daskrad": __version__}
    for name in ("numpy", "numba", "dask", "distributed", "zarr", "trimesh", "openexr"):
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out


def load(scene_path, config) -> tuple[Scene, list[str]]:
    """Step 1's loading, with the warnings it raised (dropped faces) printed as daskrad
    warnings and returned for the report."""
    import warnings

    from daskrad.scene import load_scene

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(scene_path, config)
    said = [str(w.message) for w in caught if issubclass(w.category, UserWarning)]
    for w in said:
        warn(w)
    return scene, said


def warn(message: str) -> None:
    """One warning line on stderr."""
    print(f"daskrad: warning: {message}", file=sys.stderr)


def not_converged(sol: Solution, settings: Settings) -> str | None:
    """The warning for a solve stopped by ``max_iterations``, else ``None``."""
    if sol.converged:
        return None
    rms = sol.history[-1][1] if sol.history else 1.0
    return (f"not converged after {sol.iteration} shots (relative unshot RMS {rms:.3g} > "
            f"{settings.tolerance:g}); the image adds an ambient term")


def write(outputs: Outputs, image: Image, report: dict, exposure: float = 0.0) -> None:
    """Step 5: the EXR (float32 linear radiance), the tone-mapped PNG (``exposure`` stops over
    the automatic exposure) and the JSON report."""
    write_exr(outputs.exr, image.pixels)
    write_png(outputs.png, image.pixels, stops=exposure)
    write_report(outputs.json, report)

