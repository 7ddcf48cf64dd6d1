"""Step 5, output: the HDR image, its PNG preview and the run report (docs/design.md §7).

:class:`Outputs` names every file a run writes, from the ``-o OUT.exr`` the user gave, and is
checked before anything is loaded or written; :func:`write` writes the image files and the
report at the end. The solution store (``OUT.zarr``) is written along the way by
:mod:`daskrad.distributed.store`, an observer of the solve.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

from daskrad.direct import DirectLight
from daskrad.errors import OptionError
from daskrad.io import write_exr, write_png, write_report
from daskrad.io.files import check_directory
from daskrad.io.image import written_by_daskrad
from daskrad.render import Image
from daskrad.scene.types import Scene
from daskrad.settings import Settings
from daskrad.solve import Solution

#: What a daskrad store's root ``zarr.json`` holds in ``attributes.format`` (any version).
STORE_FORMAT_PREFIX = "daskrad-solution/"


def is_store(path: Path) -> bool:
    """Whether ``path`` is a directory holding a daskrad solution store (a real directory,
    not a link, whose root metadata names daskrad's format)."""
    return store_attributes(path) is not None


def store_attributes(path: Path) -> dict | None:
    """The root attributes of the daskrad store at ``path`` (:func:`is_store`), else None."""
    meta = Path(path) / "zarr.json"
    if Path(path).is_symlink() or not Path(path).is_dir() or not meta.is_file():
        return None
    try:
        attrs = json.loads(meta.read_text()).get("attributes", {})
    except (OSError, ValueError, AttributeError):
        return None
    if not isinstance(attrs, dict) or \
            not str(attrs.get("format", "")).startswith(STORE_FORMAT_PREFIX):
        return None
    return attrs


@dataclass(frozen=True)
class Outputs:
    """The files of one run: ``exr`` (linear radiance), ``png`` (preview), ``json`` (report)
    and ``store`` (the Zarr solution store), all beside each other with one stem.

    A run solves into :attr:`partial`, a hidden store beside ``store`` (a resumed run into a
    copy of the finished one), and swaps it in only when it has finished (:meth:`publish`): a
    run that fails or is stopped leaves the earlier results as they were. Earlier results
    are replaced, as other renderers do, and the run says so; anything at these paths that
    daskrad did not make is refused, never removed.
    """

    exr: Path

    @classmethod
    def of(cls, output: str | Path, resume: bool = False) -> Outputs:
        """The outputs of ``-o OUTPUT``, checked before anything is loaded or written:
        :class:`OptionError` unless it is ``*.exr`` in a writable directory and every path it
        names is either free or a result of daskrad's."""
        output = Path(output)
        if output.suffix.lower() != ".exr":
            raise OptionError(f"the output must end in .exr, got {output.name}")
        check_directory(output.parent, "output")
        outputs = cls(output)
        for path in (outputs.exr, outputs.png, outputs.json):
            if path.is_symlink() or (path.exists() and not path.is_file()):
                raise OptionError("exists and is not a regular file; daskrad replaces only "
                                  "its own results (choose another -o)", path)
            if path.exists() and not written_by_daskrad(path):
                raise OptionError("exists and was not written by daskrad; daskrad never "
                                  "replaces what it did not make (move it or choose another "
                                  "-o)", path)
        for path in (outputs.store, outputs.partial):
            if (path.exists() or path.is_symlink()) and not is_store(path):
                raise OptionError("exists and is not a daskrad solution store; daskrad never "
                                  "removes what it did not make (move it or choose another -o)",
                                  path)
        return outputs

    @property
    def png(self) -> Path:
        return self.exr.with_suffix(".png")

    @property
    def json(self) -> Path:
        return self.exr.with_suffix(".json")

    @property
    def store(self) -> Path:
        return self.exr.with_suffix(".zarr")

    @property
    def partial(self) -> Path:
        """Where a run's store lives until it has finished (a new run's, or a resumed run's
        copy of the finished one)."""
        return self.exr.with_name(f".{self.exr.stem}.zarr.partial")

    def earlier(self) -> list[Path]:
        """The results of an earlier run that this one will replace."""
        return [p for p in (self.exr, self.png, self.json, self.store) if p.exists()]

    def working_store(self, resume: bool) -> Path:
        """The store a run solves into, always :attr:`partial`: a new run's own; a resumed run
        continues an interrupted run's partial store if there is one, else a copy of the
        finished store made now (:func:`clone_store`), so that a continuation stopped or
        failed half-way leaves the finished results, ``daskrad render`` and ``export`` of
        them, as they were until it has finished and is swapped in (:meth:`publish`)."""
        if resume and not is_store(self.partial):
            if not is_store(self.store):
                return self.store        # nothing to resume: the store says so, naming it
            clone_store(self.store, self.partial)
        return self.partial

    def publish(self, working: Path) -> None:
        """Swap the finished store ``working`` in for the earlier one (checked in :meth:`of`
        to be daskrad's)."""
        working = Path(working).absolute()
        if not is_store(working):
            raise OptionError("the finished solution store is missing; the earlier results "
                              "are kept", working)
        old = self.exr.with_name(f".{self.exr.stem}.zarr.old")
        if old.exists() and is_store(old):
            shutil.rmtree(old)
        if self.store.exists():
            if not is_store(self.store):       # appeared during the run: not ours to replace
                raise OptionError("appeared during the run and is not a daskrad solution "
                                  f"store; the solution is kept in {working}", self.store)
            os.replace(self.store, old)
        os.replace(working, self.store)
        if old.exists():
            shutil.rmtree(old)

    def discard(self, working: Path) -> None:
        """Remove the partial store of a run that failed (it made it; a stopped run keeps it
        for ``--resume``), or a resumed run's copy of the finished store that it stopped
        before writing to."""
        if Path(working).absolute() == self.partial.absolute() and is_store(working):
            shutil.rmtree(working, ignore_errors=True)

    @contextlib.contextmanager
    def lock(self):
        """Hold the lock of these outputs: a second run on the same ``-o`` is refused with one
        line instead of both writing the same files.

        The lock is ``flock`` on the empty hidden file ``.NAME.lock``, removed again when the
        run ends (well or not). Invariant: a run holds the lock only on the file that is at
        the path *now*; a run that opened the file just before the holder removed it finds,
        after taking the lock, that the path names another file (or none) and starts over, so
        two runs never hold locks on different files at once."""
        path = self.exr.with_name(f".{self.exr.stem}.lock")
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                os.close(fd)
                raise OptionError("another daskrad run is writing these outputs; wait for "
                                  "it or choose another -o", self.exr) from None
            if _same_file(fd, path):
                break
            os.close(fd)
        try:
            yield self
        finally:
            # removed while still held; an empty file only (a lock file never holds bytes,
            # so anything else at this name is not daskrad's)
            if _same_file(fd, path) and os.fstat(fd).st_size == 0:
                os.unlink(path)
            os.close(fd)


def clone_store(src: Path, dst: Path) -> None:
    """Copy the store ``src`` to the new path ``dst``, whole or not at all: every file is a
    hard link (the converted office's store, 113,886 elements and 113 MB in 108 files, clones
    in 14 ms), a copy where the file system has none. Links are safe because the store is
    never written in place: zarr replaces each chunk and ``zarr.json`` by writing a new file
    and renaming it over the old (docs/stack.md), which leaves the other name's file as it
    was. The clone is built under a temporary name of its own (``tempfile.mkdtemp``: made
    here, so removed here on failure) and renamed to ``dst`` last, so a clone stopped
    half-way is never taken for a store."""
    tmp = Path(tempfile.mkdtemp(prefix=f"{dst.name}.", suffix=".tmp", dir=dst.parent))
    try:
        shutil.copytree(src, tmp, symlinks=True, copy_function=_link_or_copy,
                        dirs_exist_ok=True)
        os.replace(tmp, dst)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)     # made here, and only part of a clone
        raise


def _link_or_copy(src: str, dst: str) -> None:
    try:
        os.link(src, dst)
    except OSError:
        shutil.copy2(src, dst)


def _same_file(fd: int, path: Path) -> bool:
    """Whether ``path`` still names the open file ``fd``."""
    try:
        st = os.stat(path)
    except FileNotFoundError:
        return False
    own = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)


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
           warnings: list[str], memory: dict | None = None,
           resumed_from: int | None = None) -> dict:
    """The run report (written as ``OUT.json``): counts, convergence, timings, settings;
    ``memory``: peak memory of the client and the workers, MiB, and the row caches' use
    (the executor's ``memory()``); ``resumed_from``: the shots of the checkpoint a
    ``--resume`` continued from (``None`` for a new run)."""
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
        # the scene is worked in coordinates relative to this point (scene.origin)
        "origin": scene.origin,
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
        "resumed_from": resumed_from,
        "converged": sol.converged,
        # seconds of solving since the first shot, summed over a run and the runs it resumed
        # (``seconds.solve`` is this run's alone)
        "unshot_rms_history": [
            {"iteration": i, "relative_unshot_rms": r, "seconds": s} for i, r, s in sol.history],
        "ambient": image.ambient,
        "seconds": seconds,
        "workers": workers,
        "memory": memory or {},
        "settings": settings.as_dict(),
        "image": {"width": image.camera.width, "height": image.camera.height,
                  "mean_radiance": image.pixels.reshape(-1, 3).mean(axis=0),
                  # pixels sampled again at --edge-spp (render.render_tile_stats)
                  "edge_pixels": int(image.stats.get("edges", 0))},
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


def warn(message: str) -> None:
    """One warning line on stderr."""
    print(f"daskrad: warning: {message}", file=sys.stderr)


def note(message: str) -> None:
    """One line of information on stderr."""
    print(f"daskrad: {message}", file=sys.stderr)


def replaced_note(paths: list[Path]) -> str:
    """The note for earlier outputs ``paths`` (beside each other) that a command replaced:
    their names and their folder as the user gave it, e.g. ``replaced the earlier results
    c.exr, c.png in out`` (a new user could not tell which folder a bare name meant)."""
    folder = paths[0].parent
    where = "the current folder" if str(folder) == "." else str(folder)
    return f"replaced the earlier results {', '.join(p.name for p in paths)} in {where}"


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

