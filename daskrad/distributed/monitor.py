"""The client's ``on_batch`` hook: checkpoints into the store and progress for the dashboard.

Checkpoints happen after every ``checkpoint_every``-th applied batch, counted by the solution's
own history, and at most once per ``CHECKPOINT_SECONDS`` of wall time, the first that long after
the solve began (a short solve writes its final states only). Timing
may decide which states are checkpointed without touching the result: a resume from any
checkpoint applies exactly the batches the uninterrupted run applied (the state holds the
queued batches), so the bits are the same. The last state a run with a smaller tolerance or
more iterations could continue from (the one before the final batch) is kept in memory and
written at the finish, so a continued run redoes at most one batch. Progress and the preview
image are throttled by wall time too: they are only watched, never read back.
"""

from __future__ import annotations

import base64
import dataclasses
import functools
import io
import math
import time

from daskrad import render, solve
from daskrad.mesh import vertex_average

#: Least wall seconds between two checkpoints, and from the solve's start to the first (the
#: final one always): an interrupt loses at most about this much shooting, and a short run does
#: not spend its time in the store. Measured on the Cornell box (7,295 elements): a checkpoint
#: costs ~50 ms, and one every 8 batches took 1.25 s of a 2.8 s solve; the first after 8
#: batches was one of the three a 0.5 s solve wrote (32–45 ms each).
CHECKPOINT_SECONDS = 5.0
#: Seconds between progress messages and between preview images sent to the scheduler.
PUBLISH_SECONDS = 0.5
PREVIEW_SECONDS = 3.0
#: Preview width in pixels (one sample per pixel: a glance, not the image).
PREVIEW_WIDTH = 96
#: History points kept for the dashboard's curve.
CURVE_POINTS = 400


class Preview:
    """A small tone-mapped PNG of the current solution, rendered in the client."""

    def __init__(self, mesh, camera):
        self.h, self.reflectance = mesh.hierarchy, mesh.reflectance
        scale = min(1.0, PREVIEW_WIDTH / camera.width)
        cam = type(camera)(eye=camera.eye, look_at=camera.look_at, up=camera.up,
                           fov=camera.fov, width=max(1, round(camera.width * scale)),
                           height=max(1, round(camera.height * scale)))
        self.ctx = render.RenderContext(grid=mesh.grid, tri_verts=mesh.tri_verts,
                                        tri_element=mesh.tri_element,
                                        elem_normal=self.h.elem_normal, vertex_radiance=None,
                                        camera=cam, spp=1)

    def png_base64(self, radiosity, unshot) -> str:
        """The preview of the solution ``radiosity (E, 3)``, ``unshot (P, 3)`` (copies: the
        executor's publisher renders it on a thread of its own while the solve goes on)."""
        from dataclasses import replace

        from PIL import Image

        from daskrad.io import tonemap

        amb = solve.ambient(self.h, self.reflectance, unshot)
        shown = radiosity + self.reflectance * amb
        ctx = replace(self.ctx, vertex_radiance=vertex_average(self.h, shown) / math.pi)
        buf = io.BytesIO()
        Image.fromarray(tonemap(render.render(ctx)), mode="RGB").save(buf, format="PNG")
        return base64.b64encode(buf.getvalue()).decode("ascii")


class Watch:
    """``on_batch(sol)``: checkpoint every few batches, publish progress, then call ``then``."""

    def __init__(self, store, executor, settings, h, title: str = "",
                 preview: Preview | None = None, then=None):
        self.store = store
        self.executor = executor
        self.publish = getattr(executor, "publish", None) if executor.workers else None
        self.preview = preview if executor.dashboard_link else None
        self.every = max(1, settings.checkpoint_every)
        self.then = then
        self.info = {"run": title, "elements": h.n_elements,
                     "patches": h.n_patches, "tolerance": settings.tolerance}
        self._sent = self._shown = -math.inf
        # the first checkpoint too waits CHECKPOINT_SECONDS, from the solve's start: a solve
        # shorter than that writes only its final states (Watch.finish)
        self._saved = time.perf_counter()
        self._open: solve.Solution | None = None   # the last state with batches queued
        self.seconds = 0.0                   # client time spent here (benchmarks read it)

    def __call__(self, sol: solve.Solution) -> None:
        t = time.perf_counter()
        if (self.store is not None and len(sol.history) % self.every == 0
                and t - self._saved >= CHECKPOINT_SECONDS):
            self.store.checkpoint(sol)
            self._saved = time.perf_counter()
            if self.store.continuable(sol):
                self._open = None           # saved; a closed (final) state keeps the snapshot
        elif self.store is not None and self.store.continuable(sol):
            self._open = _snapshot(sol)
        self._publish(sol, t)
        self.seconds += time.perf_counter() - t
        if self.then is not None:
            self.then(sol)

    def finish(self, sol: solve.Solution) -> None:
        """The final checkpoint and progress message."""
        if self.store is not None:
            if self._open is not None and self._open.iteration < sol.iteration:
                self.store.checkpoint(self._open)
            self.store.checkpoint(sol)
        self._publish(sol, time.perf_counter(), force=True)

    def _publish(self, sol, now: float, force: bool = False) -> None:
        if self.publish is None or not (force or now - self._sent >= PUBLISH_SECONDS):
            return
        self._sent = now
        hist = sol.history
        it, rms, sec = hist[-1] if hist else (sol.iteration, 1.0, sol.seconds)
        phase = getattr(self.executor, "phase", None)
        if phase is not None:
            phase("shooting", _fraction(rms, self.info["tolerance"], sol.converged),
                  f"{int(it)} shots, relative unshot RMS {rms:.3g}", force=True)
        self.publish("progress", {**self.info, "workers": self.executor.workers,
                                  "iteration": int(it),
                                  "relative_unshot_rms": float(rms), "seconds": round(sec, 2),
                                  "converged": bool(sol.converged), "history": curve(hist)})
        if self.preview is not None and (force or now - self._shown >= PREVIEW_SECONDS):
            self._shown = now
            self.publish("preview", functools.partial(
                self.preview.png_base64, sol.radiosity.copy(), sol.unshot.copy()))



def curve(history: list) -> list[list]:
    """The dashboard's curve of a solve's ``history`` (``[iteration, relative unshot RMS,
    seconds]`` per applied batch): at most ``CURVE_POINTS + 1`` of its points, every k-th and
    the last, each once, in order (a one-batch history is one point, not its first twice)."""
    step = max(1, math.ceil(len(history) / CURVE_POINTS))
    picked = list(range(0, len(history), step))
    if history and picked[-1] != len(history) - 1:
        picked.append(len(history) - 1)
    return [list(history[i]) for i in picked]


def _snapshot(sol: solve.Solution) -> solve.Solution:
    """A copy of ``sol`` the solve will not change (its arrays are updated in place)."""
    return dataclasses.replace(sol, radiosity=sol.radiosity.copy(), direct=sol.direct.copy(),
                               unshot=sol.unshot.copy(), history=list(sol.history),
                               queued=list(sol.queued),
                               row_kind=None if sol.row_kind is None else sol.row_kind.copy())


def _fraction(rms: float, tolerance: float, converged: bool) -> float:
    """How far the solve is, for the page's bar: ``log rms / log tolerance`` in [0, 1] (the
    relative unshot RMS falls from 1 to the tolerance roughly exponentially in the shots)."""
    if converged or rms <= tolerance:
        return 1.0
    if rms >= 1.0 or not 0.0 < tolerance < 1.0:
        return 0.0
    return min(1.0, max(0.0, math.log(rms) / math.log(tolerance)))
