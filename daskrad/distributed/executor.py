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
- ``ahead(kind, plan, context_of, ranges_of)`` → :class:`Ahead` or None: ``kind`` tasks that
  read geometry alone, started on the cores the solve leaves idle (with Dask, the client's
  machine's; ``"gather"``: the junction gather's operator rows,
  :func:`daskrad.render.gather_ahead`);
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

import logging
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
        self._started: list[Ahead] = []         # work started ahead (ahead), stopped by close

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
        return self.run_ranges(render.render_tile_stats)(ctx, tiles)

    def direct(self, ctx, ranges: list[tuple[int, int]]) -> list[tuple]:
        """Direct light at the vertex ranges (:func:`daskrad.direct.vertex_light`)."""
        return self.run_ranges(direct.vertex_light)(ctx, ranges)

    def gather(self, ctx: render.GatherContext, ranges: list[tuple[int, int]]
               ) -> list[render.GatherOperator]:
        """The junction gather's operator rows over ranges of its vertices
        (:func:`daskrad.render.gather_vertices`)."""
        return self.run_ranges(render.gather_vertices)(ctx, ranges)

    def ahead(self, kind: str, plan, context_of, ranges_of) -> Ahead | None:
        """Start the ``kind`` tasks (:func:`ahead_task`) ``task(context_of(p), a, b)`` over
        ``ranges_of(p)`` of ``p = plan()`` on a thread that runs only where a core is idle
        (:class:`Ahead`); ``result()`` runs what it has not done on this executor's threads.
        None with one thread: it was asked to take one core."""
        task = ahead_task(kind)
        if self.threads == 1:
            return None
        self._started.append(Ahead(plan, context_of, ranges_of, task, self.run_ranges(task)))
        return self._started[-1]

    def run_ranges(self, task):
        """``run(ctx, ranges)``: ``[task(ctx, a, b) for a, b in ranges]`` on this executor's
        threads, in order: how :meth:`tiles`, :meth:`direct` and :meth:`gather` run, and what
        :class:`Ahead` runs the ranges it has not finished with."""
        return lambda ctx, ranges: self.map(lambda r: task(ctx, *r), ranges)

    def memory(self) -> dict:
        """Peak memory of this process (MiB) and the row cache's use and budget (no
        workers: this process is the one that computes)."""
        return {"client_peak_mib": peak_mib(), "workers": [], **self.rows.usage()}

    def publish(self, key: str, value) -> None:
        """No dashboard in-process: progress shows in the terminal only."""

    def close(self) -> None:
        for work in self._started:
            work.close()
        self._started = []
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

    def map(self, fn, items: list) -> list:
        """``[fn(item) for item in items]`` on this executor's threads, in order."""
        if self.threads == 1 or len(items) < 2:
            return [fn(item) for item in items]
        return [f.result() for f in [self._submit(fn, item) for item in items]]


def idle_priority() -> bool:
    """Let the calling thread run only where a core would otherwise be idle (Linux's
    ``SCHED_IDLE``, which any process may ask for itself; elsewhere the lowest ``nice`` a
    thread can take is not per thread, and nothing changes). Whether it was done."""
    policy = getattr(os, "SCHED_IDLE", None)
    if policy is None:
        return False
    try:
        os.sched_setscheduler(0, policy, os.sched_param(0))    # 0: this thread
    except OSError:
        return False
    return True


#: Seconds :meth:`Ahead.close` waits for the plan to finish.
CLOSE_SECONDS = 30.0

_log = logging.getLogger(__name__)


def ahead_task(kind: str):
    """The task of the ``kind`` of work :meth:`InProcess.ahead` (and the Dask executor's)
    may start: ``"gather"``, :func:`daskrad.render.gather_vertices`."""
    return {"gather": render.gather_vertices}[kind]


class Ahead:
    """Geometry-only work computed on an idle core while the solve runs
    (:meth:`InProcess.ahead`, and the Dask executor's on the client's machine; the junction
    gather's operator, whose tasks read the mesh and never a radiance).

    A thread computes ``p = plan()`` at once (at the normal priority: the render waits for
    the plan, :meth:`plan`), then takes the ranges ``ranges_of(p)`` one at a time in order
    and runs ``task(context_of(p), a, b)`` on each. The first range runs at the normal
    priority too: its call loads (or compiles) the task's kernel under numba's compiler
    lock, which a starved thread must not hold while the render's threads wait on it; the
    others at idle priority (:func:`idle_priority`), taking a core only when the solve, the
    store's writes and every other thread of the machine leave one free. Where a thread
    cannot be given that priority (not Linux, or refused), it stops after the first range.

    :meth:`result` stops it and runs the ranges it has not finished through
    ``run(context_of(p), ranges)`` (the executor's threads at the normal priority, or its
    tasks on a cluster), one still running included: every task is a pure function of its
    range, so computing one twice gives the same bits, and the render never waits on the idle
    thread. The results are those of running every range through ``run``. What the idle
    thread may still hold while it is starved is the GIL for the microseconds between two
    kernel calls: a thread that wants it then waits until the scheduler runs the idle thread
    again, at the latest when a core falls idle.
    """

    def __init__(self, plan, context_of, ranges_of, task, run):
        self._fns = (context_of, task, run)
        self._lock = threading.Lock()
        self._planned = threading.Event()
        self._plan = None
        self._error: BaseException | None = None
        self._ranges: list = []
        self._next = 0                      # the next range no thread has taken
        self._done: dict[int, object] = {}  # range index -> its task's result
        self._stopped = False
        self._thread = threading.Thread(target=self._work, args=(plan, ranges_of),
                                        name="daskrad-ahead", daemon=True)
        self._thread.start()

    def _work(self, plan, ranges_of) -> None:
        try:
            p = plan()
            ranges = list(ranges_of(p)) if p is not None else []
            context_of, task, _ = self._fns
            ctx = context_of(p) if ranges else None
        except BaseException as err:  # noqa: BLE001 - raised again where the plan is read
            self._error = err
            self._planned.set()
            return
        self._plan, self._ranges = p, ranges
        self._planned.set()
        first = True
        while True:
            with self._lock:
                if self._stopped or self._next >= len(ranges):
                    return
                i = self._next
                self._next += 1
            try:
                value = task(ctx, *ranges[i])
            except BaseException:  # noqa: BLE001 - result() runs the range again and
                # meets the error in the caller's thread (or not: one only this thread met)
                _log.debug("work ahead stopped at range %d", i, exc_info=True)
                return
            with self._lock:
                self._done[i] = value
            if first:
                first = False
                if not idle_priority():     # no idle priority: the render does the rest
                    return

    def plan(self):
        """``plan()``'s value (waiting for it; its error raised here)."""
        self._planned.wait()
        if self._error is not None:
            raise self._error
        return self._plan

    def result(self) -> list:
        """Every range's result, in order: those the idle thread finished, the others run
        now through ``run`` (the executor's threads, or tasks on a cluster)."""
        p = self.plan()
        self.stop()
        with self._lock:
            done = dict(self._done)
        missing = [i for i in range(len(self._ranges)) if i not in done]
        if missing:
            context_of, _, run = self._fns
            values = run(context_of(p), [self._ranges[i] for i in missing])
            for i, value in zip(missing, values, strict=True):
                done[i] = value
        return [done[i] for i in range(len(self._ranges))]

    def stop(self) -> None:
        """Take no more ranges (one running finishes on its own)."""
        with self._lock:
            self._stopped = True

    def close(self, timeout: float = CLOSE_SECONDS) -> None:
        """Take no more ranges, and wait (up to ``timeout`` s) for the plan: it casts rays on
        numba's threads, which must not overlap what the process does next (a next run's
        grid; numba's workqueue layer takes one caller at a time). Not for the range the
        thread may be in: that runs serial kernels, at an idle priority that a busy machine
        may starve for long."""
        self.stop()
        self._planned.wait(timeout)

    def progress(self) -> tuple[int, int]:
        """``(ranges finished by the idle thread, ranges)`` (0 of 0 before the plan)."""
        with self._lock:
            return len(self._done), len(self._ranges)

    def join(self, timeout: float | None = None) -> bool:
        """Wait until the idle thread ends (every range done, or stopped); whether it has."""
        self._thread.join(timeout)
        return not self._thread.is_alive()
