"""The pipeline on one screen, the paper's five steps (docs/design.md §1).

1. preprocess: load and triangulate the scene, mesh it into polygons → patches → elements,
   build the voxel grid;
2. direct light at every element vertex, with adaptive subdivision;
3. shooting, from the patch with the most unshot energy until the unshot RMS is small;
4. the per-pixel pass: primary rays, Gouraud interpolation, direct light recomputed per pixel
   where vertex colours differ by more than ``Rdiff`` (eq. 9), specular light;
5. output: the EXR image, its PNG preview, the run report (the store is written along).

Each step is a public function with a frozen result. The store, the progress bar and the
dashboard observe the solve (``on_batch``); they never change what it computes.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

from daskrad import direct, output, render, solve
from daskrad.distributed import auto_workers, check_scheduler, executor_for, start_early
from daskrad.distributed.monitor import Preview, Watch
from daskrad.distributed.store import Store
from daskrad.errors import interrupted
from daskrad.mesh import Hierarchy
from daskrad.preprocess import preprocess
from daskrad.progress import Bar, Heartbeat
from daskrad.scene import load_scene
from daskrad.settings import Settings


def run(scene_path: str | Path, out: str | Path, settings: Settings, progress: bool = True,
        config: str | Path | None = None, resume: bool = False, executor=None,
        camera: str | None = None) -> dict:
    """Solve and render ``scene_path``; write ``out`` (.exr), .png, .json and the solution
    store .zarr beside it. ``resume``: continue from the store's last checkpoint;
    ``executor``: run on this one instead of the settings' choice; ``camera``: the glTF camera
    to look through.
    Returns the run report (also written as JSON)."""
    # the options first, the scheduler's address next: nothing is touched yet (the outputs'
    # check probes their folder with a file of its own)
    settings.validate()
    check_scheduler(settings)
    outputs = output.Outputs.of(out, resume)
    beat = Heartbeat(progress)      # a log hears a line every 30 s of a long run
    try:
        with outputs.lock():
            return _run(scene_path, outputs, settings, progress, config, resume, executor,
                        camera, beat)
    finally:
        beat.close()


def _run(scene_path, outputs, settings, progress, config, resume, executor, camera,
         beat) -> dict:
    seconds: dict[str, float] = {}
    t = start = time.perf_counter()
    early = start_early(settings) if executor is None else None   # starts as the scene loads
    copied = False
    try:
        scene = load_scene(scene_path, config, camera)                             # 1
        if settings.workers is None:
            settings = settings.replace(workers=auto_workers(scene, settings))
        mesh = preprocess(scene, settings)                                        # 1
        settings = settings.with_patches(mesh.hierarchy.n_patches)
        seconds["preprocess"], t = time.perf_counter() - t, time.perf_counter()
        replaced = outputs.earlier()
        # a resume with no interrupted run to continue continues a copy of the finished store
        copied = resume and not output.is_store(outputs.partial)
        store = Store(outputs.working_store(resume), settings, resume=resume, scene=scene,
                      shown=outputs.store if copied else None)
        ex = executor or (early.get() if early is not None else executor_for(settings, store))
    except BaseException:
        if early is not None:       # a bad scene, or Ctrl-C while the cluster starts
            early.close()
        if copied:                  # the copy of the finished store holds nothing new
            outputs.discard(outputs.partial)
        raise
    ex.use_store(store)
    bar = None
    began = False
    try:
        store.open()           # a new store, or the checkpoint to resume from
        _announce(ex, settings)
        # a resume takes step 2 from the store when an earlier run of it wrote it
        state = store.direct_state() if resume else None
        beat.say(f"direct light at {len(mesh.hierarchy.vertices):,} vertices"
                 if state is None else "direct light read back from the store")
        light = direct.light(scene, mesh, settings, ex, state)                    # 2
        seconds["direct"], t = time.perf_counter() - t, time.perf_counter()
        mesh = light.mesh
        camera = render.camera(scene, settings)
        # the view's junction gather reads geometry alone: computed on idle cores meanwhile
        ahead = render.gather_ahead(scene, light, settings, camera, ex)
        taken = state is not None and light.irradiance is state.irradiance
        begin = store.begin(mesh.hierarchy, mesh.reflectance, solve.start(light),
                            None if taken else direct.state_of(light))
        began = True
        resumed_from = begin.iteration if resume else None    # the solve may update begin
        if resume and progress:         # before the bar, which draws its line at once
            output.note(f"resuming from shot {begin.iteration:,}" if begin.iteration else
                        "resuming: the store holds no shot yet, so the solve starts afresh")
        bar = Bar(settings.tolerance, enabled=progress, heartbeat=beat)
        watch = Watch(store, ex, settings, mesh.hierarchy, str(scene.path),
                      Preview(mesh, camera), then=bar)
        sol = solve.radiosity(light, settings, ex, begin, on_batch=watch)         # 3
        watch.finish(sol)
        bar.close()
        seconds["solve"], t = time.perf_counter() - t, time.perf_counter()
        beat.say(f"rendering {camera.width} x {camera.height}")
        image = render.image(scene, light, sol, settings, ex, camera, ahead)      # 4
        store.finish(image)
        seconds["render"], t = time.perf_counter() - t, time.perf_counter()
        memory = ex.memory()
    except BaseException as err:
        if bar is not None:             # its last line ends before the error's line
            bar.close()
        # a stopped run keeps its checkpoint; a copy of the finished store that holds
        # nothing new yet (a resume refused, or stopped before it began) goes
        if not (resume or interrupted(err) is not None) or (copied and not began):
            outputs.discard(Path(store.path))
        raise
    finally:
        ex.close()
    late = [w for w in (output.unlit_warning(scene, light, sol),
                        output.not_converged(sol, settings)) if w]
    for w in late:
        output.warn(w)
    warnings = [*scene.warnings, *late]     # the loader's were printed as it read
    seconds["total"] = time.perf_counter() - start
    report = output.report(scene, outputs, settings, light, sol, image, workers=ex.workers,
                           seconds=seconds, warnings=warnings, memory=memory,
                           resumed_from=resumed_from)
    beat.status = "writing the image and the report"
    outputs.publish(Path(store.path))
    output.write(outputs, image, report, settings.exposure)                       # 5
    beat.ended(f"done: {sol.iteration:,} shots, "
               + ("converged" if sol.converged else "not converged"))
    if replaced and not resume:
        output.note(output.replaced_note(replaced))
    return report


class Solved(NamedTuple):
    """Steps 1–3 on a loaded scene (:func:`solve_scene`)."""

    hierarchy: Hierarchy          # after adaptive subdivision
    reflectance: np.ndarray       # (E, 3) float64, ρ per element
    solution: solve.Solution
    light: direct.DirectLight     # step 2's result, with the refined mesh


def solve_scene(scene, settings: Settings, executor=None, on_batch=None) -> Solved:
    """Steps 1–3 in this process (or on ``executor``), no store and no output files."""
    from daskrad.distributed.executor import InProcess

    settings.validate()
    ex = executor or InProcess()
    light = direct.light(scene, preprocess(scene, settings), settings, ex)
    sol = solve.radiosity(light, settings, ex, on_batch=on_batch)
    return Solved(light.mesh.hierarchy, light.mesh.reflectance, sol, light)


def _announce(executor, settings: Settings) -> None:
    """Print the dashboard's address when there is one (and whether others can reach it)."""
    link = executor.dashboard_link
    if link:
        # a busy port: Dask serves the dashboard on another (its own warning is filtered,
        # daskrad.distributed.dask_executor.quiet_dask), and this line says so
        asked, got = getattr(executor, "dashboard_ports", (0, 0))
        moved = f"; port {asked} was in use" if asked and got != asked else ""
        print(f"daskrad: dashboard {link} (progress: {link.rsplit('/', 1)[0]}/daskrad{moved})",
              file=sys.stderr)
        host = settings.dashboard.rpartition(":")[0].strip("[]")
        if host not in ("127.0.0.1", "localhost", "::1") and not host.startswith("127."):
            output.warn(f"the dashboard listens on {host or 'every interface'} "
                        f"({settings.dashboard}), not only on this machine")
