"""Executors: where the pipeline's tasks run.

Both executors expose the same calls, so the pipeline is written once:

- ``use_store(store)``: where task contexts go (the run's store);
- ``set_geometry(shoot_ctx, generation=0)``: the form-factor task's context;
- ``shots(batch_no, patch_ids)`` → handle with ``.result()`` = rows of
  :func:`daskrad.formfactor.shooting.shoot_rows`;
- ``prefetch(patch_ids)``: rows likely to be asked for soon, computed ahead on idle cores
  (or not at all: a hint);
- ``tiles(render_ctx, tiles)`` → list of ``(tile image, counts)`` of
  :func:`daskrad.render.render_tile_stats`;
- ``direct(ctx, ranges)`` → list of ``(H, classes)`` of
  :func:`daskrad.direct.vertex_light`, one per vertex range, in order;
- ``gather(gather_ctx, ranges)`` → list of the junction gather's operator rows
  (:func:`daskrad.render.gather_vertices`), one per range of junction vertices, in order;
- ``memory()`` → peak memory of the client and of every worker, and the row caches' use;
- ``publish(key, value)``: progress for the dashboard (a no-op here);
- ``close()``.

:class:`InProcess` runs the tasks in this process (``--workers 0``; tiny scenes need no
cluster: starting one costs seconds), on a pool of threads, one per core by default: the
kernels release the GIL (``nogil``), so a batch's shooters, the image's tiles and the
direct-light vertex ranges run side by side (issue 12, item 1). Every task is a pure function
of its context and its ids, and the results are handed back in submission order, so the bits do
not depend on the number of threads.
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

import numpy as np

from daskrad import direct, render
from daskrad.distributed.memory import peak_mib, physical_memory
from daskrad.formfactor import shooting


def default_threads() -> int:
    """The cores this process may run on (its CPU affinity, else the machine's count)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):            # not on Linux
        return max(1, os.cpu_count() or 1)


class _Done:
    """A finished handle, like a completed future."""

    __slots__ = ("value",)

    def __init__(self, value):
        self.value = value

    def result(self):
        return self.value


class _Rows:
    """A batch's rows as futures of the thread pool; ``result()`` joins them in shooter
    order (like :class:`daskrad.distributed.dask_executor._Batch`)."""

    __slots__ = ("futures",)

    def __init__(self, futures: list[Future]):
        self.futures = futures

    def result(self) -> list:
        return [f.result()[0] for f in self.futures]


class InProcess:
    """Runs tasks in the calling process with the same functions the workers run.

    ``threads``: how many tasks run at once (default :func:`default_threads`, every core this
    process may use); 1 runs each task in the caller's thread as it is submitted.
    """

    workers = 0
    dashboard_link = None

    def __init__(self, shoot_ctx: shooting.ShootContext | None = None,
                 threads: int | None = None):
        self.shoot_ctx = shoot_ctx
        self.rows = shooting.RowCache()
        self.threads = default_threads() if threads is None else max(1, int(threads))
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()
        self._ahead: dict[int, Future] = {}    # patch id -> its row computed ahead
        self._busy = 0                          # tasks submitted and not finished
        self.prefetched = 0                     # rows started ahead (prefetch)

    def use_store(self, store) -> None:
        """In-process tasks read their contexts from memory: no store needed."""

    def set_geometry(self, shoot_ctx: shooting.ShootContext, generation: int = 0) -> None:
        self.shoot_ctx = shoot_ctx
        self.rows = shooting.RowCache(shooting.row_cache_bytes(shoot_ctx,
                                                               physical_memory()))
        self._ahead = {}

    def shots(self, batch_no: int, patch_ids: np.ndarray) -> _Done | _Rows:
        if self.threads == 1:
            return _Done(shooting.shoot_rows(self.shoot_ctx, patch_ids, self.rows))
        # one task per shooter: a batch of 8 keeps every core busy, and the solve submits the
        # next batch before it waits for this one, so the pool never runs dry between batches
        ctx, rows = self.shoot_ctx, self.rows
        return _Rows([self._ahead.pop(int(p), None)
                      or self._submit(shooting.shoot_rows, ctx, [int(p)], rows)
                      for p in np.asarray(patch_ids)])

    def prefetch(self, patch_ids: np.ndarray) -> None:
        """Compute the rows of ``patch_ids`` (in that order) not kept yet on the threads the
        batches leave idle: at most one task waits or runs per idle thread, so a batch
        submitted next waits for no more than one prefetched row per thread (rows the solve
        will mostly ask for within a few batches). Only while the row cache has room for
        them: a prefetched row it dropped would be computed twice. Rows started for patches
        no longer offered are let go (a finished one is in the row cache anyway; one not
        started is cancelled)."""
        offered = set(np.asarray(patch_ids).tolist())
        for p in [p for p in self._ahead if p not in offered]:
            self._ahead.pop(p).cancel()
        if self.threads == 1 or self.rows.nbytes > self.rows.max_bytes // 2:
            return
        ctx, rows = self.shoot_ctx, self.rows
        for p in np.asarray(patch_ids).tolist():
            if self._busy >= self.threads:
                break
            if p in self._ahead or rows.has(p):
                continue
            self._ahead[p] = self._submit(shooting.shoot_rows, ctx, [p], rows)
            self.prefetched += 1

    def tiles(self, ctx: render.RenderContext, tiles: list) -> list[tuple[np.ndarray, dict]]:
        return self._map(lambda t: render.render_tile_stats(ctx, t[0], t[1]), tiles)

    def direct(self, ctx, ranges: list[tuple[int, int]]) -> list[tuple]:
        """Direct light at the vertex ranges (:func:`daskrad.direct.vertex_light`)."""
        return self._map(lambda r: direct.vertex_light(ctx, r[0], r[1]), ranges)

    def gather(self, ctx: render.GatherContext, ranges: list[tuple[int, int]]
               ) -> list[render.GatherOperator]:
        """The junction gather's operator rows over ranges of its vertices
        (:func:`daskrad.render.gather_vertices`)."""
        return self._map(lambda r: render.gather_vertices(ctx, r[0], r[1]), ranges)

    def memory(self) -> dict:
        """Peak memory of this process (MiB) and the row cache's use and budget (no
        workers: this process is the one that computes)."""
        return {"client_peak_mib": peak_mib(), "workers": [], **self.rows.usage()}

    def publish(self, key: str, value) -> None:
        """No dashboard in-process: progress shows in the terminal only."""

    def close(self) -> None:
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)

    # --- the pool -----------------------------------------------------------------------

    def _submit(self, fn, *args) -> Future:
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self.threads, thread_name_prefix="daskrad")
            self._busy += 1
            future = self._pool.submit(fn, *args)
        future.add_done_callback(self._finished)
        return future

    def _finished(self, future: Future) -> None:
        with self._lock:
            self._busy -= 1

    def _map(self, fn, items: list) -> list:
        if self.threads == 1 or len(items) < 2:
            return [fn(item) for item in items]
        return [f.result() for f in [self._submit(fn, item) for item in items]]
