"""Executors: where the pipeline's tasks run.

Both executors expose the same calls, so the pipeline is written once:

- ``set_geometry(shoot_ctx, generation=0)``: the form-factor task's context;
- ``shots(batch_no, patch_ids)`` → handle with ``.result()`` = rows of
  :func:`daskrad.formfactor.shooting.shoot_rows`;
- ``tiles(render_ctx, tiles)`` → list of tile images of :func:`daskrad.render.render_tile`;
- ``publish(key, value)``: progress for the dashboard (a no-op here);
- ``close()``.

The Dask executor (:mod:`daskrad.distributed.dask_executor`) also has ``direct(ctx, ranges)``;
:func:`daskrad.direct.compute` runs the batches in-process when an executor lacks it.

:class:`InProcess` runs every task at once in this process (``--workers 0``; tiny scenes need no
cluster: starting one costs seconds).
"""

from __future__ import annotations

import numpy as np

from daskrad import render
from daskrad.formfactor import shooting


class _Done:
    """A finished handle, like a completed future."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class InProcess:
    """Runs tasks in the calling process with the same functions the workers run."""

    workers = 0
    dashboard_link = None

    def __init__(self, shoot_ctx: shooting.ShootContext | None = None):
        self.shoot_ctx = shoot_ctx
        self.rows = shooting.RowCache()

    def set_geometry(self, shoot_ctx: shooting.ShootContext, generation: int = 0) -> None:
        self.shoot_ctx = shoot_ctx
        self.rows = shooting.RowCache()

    def shots(self, batch_no: int, patch_ids: np.ndarray) -> _Done:
        return _Done(shooting.shoot_rows(self.shoot_ctx, patch_ids, self.rows))

    def tiles(self, ctx: render.RenderContext, tiles: list) -> list[np.ndarray]:
        return [render.render_tile(ctx, rows, cols) for rows, cols in tiles]

    def publish(self, key: str, value) -> None:
        """No dashboard in-process: progress shows in the terminal only."""

    def close(self) -> None:
        pass
