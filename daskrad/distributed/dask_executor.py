"""The Dask executor: the same calls as :class:`~daskrad.distributed.executor.InProcess`,
run as named futures on a cluster (docs/design.md §4).

Futures carry ids and ranges only; the geometry goes once into the store
(:meth:`Store.put_context`) and each worker caches it (:mod:`daskrad.distributed.worker`),
or, when the workers are threads of this very process (``--workers N``'s LocalCluster), it is
handed to them in memory (:func:`daskrad.distributed.worker.share`): no copy, no store.
Keys are ``formfactor-<generation>-<batch>-<part>-<run>``,
``direct-<generation>-<n>-<start>-<run>``, ``gather-<generation>-<n>-<start>-<token>-<run>``
and ``tile-<generation>-<n>-<run>``: the dashboard groups them by their first word; the 8-hex
run token keeps two runs on one cluster (or two runs of one test session) from sharing a key,
since a key still held by the scheduler returns
its old result (docs/stack.md).
"""

from __future__ import annotations

import contextlib
import logging
import math
import shutil
import signal
import tempfile
import threading
import time
import urllib.parse
import uuid
import warnings
from pathlib import Path

import numpy as np

from daskrad import render
from daskrad.distributed import worker
from daskrad.distributed.executor import Ahead, ahead_task
from daskrad.distributed.memory import peak_mib, physical_memory
from daskrad.distributed.store import Store
from daskrad.errors import OptionError
from daskrad.formfactor import shooting

#: Seconds between two counts of the cluster's workers.
COUNT_SECONDS = 2.0
#: Seconds between two phase messages of one phase for the dashboard page.
PHASE_SECONDS = 0.5

#: Seconds of form-factor work a task of new rows aims at: a task costs the scheduler and the
#: client ~1.6 ms of a 2-core machine's wall time (RenderPark's cube, 1,606 patches, 30,063
#: elements, rows of ~5 ms: the solve took 7.2 s on 2 thread workers at a row a task, 6.3 s
#: grouped, against 4.4–4.6 s in-process), so cheap rows are sent several to a task
#: (:meth:`DaskExecutor.shots`).
TASK_SECONDS = 0.05

#: Tasks of rows computed ahead (:meth:`DaskExecutor.prefetch`) each worker may have
#: unfinished: one left it idle while the client heard that the task was done and offered
#: the next (the gaps between a worker's tasks, 3–7 ms a median, summed to 2.2 of 10.8
#: worker-seconds in the cube's solve); with two, the next is already there (with
#: :data:`daskrad.solve.PREFETCH`, figures there). A batch then waits behind at most two
#: such tasks a worker; giving its tasks a higher Dask priority measured the same.
AHEAD_TASKS = 2

#: Whether :meth:`DaskExecutor.publish` hands its messages to a :class:`Publisher` thread;
#: False sends them (and renders a preview) in the caller's thread, as before:
#: ``benchmarks/bench_client.py``'s reference arm (a benchmark's switch, read when the
#: executor is made).
PUBLISH_THREAD = True

#: Custom dashboard page module (``/daskrad``), added to the scheduler's HTTP routes.
ROUTES_MODULE = "daskrad.distributed.dashboard"


class _Batch:
    """A batch's futures; ``result()`` gives the rows in shooter order.

    ``rows`` holds the rows the client already has (position → row); ``groups[k]`` is
    ``(patch ids, positions)``: the patches whose rows future ``k`` computes, in its order, and
    each one's position in the batch (−1 for a row computed ahead for a later batch). Each
    future answers ``(worker address, rows, seconds)``: ``owner`` (patch id → address) learns
    where each row is kept, the client's ``cache`` keeps every row for the patch's next shot,
    and ``timed(rows, seconds)`` hears what the rows of a future in ``fresh`` (one computing
    new rows, counted once) cost."""

    def __init__(self, futures: list, stats: dict, groups: list[list[int]], ids: np.ndarray,
                 owner: dict, rows: dict, cache: shooting.RowCache, timed=None,
                 fresh: set | None = None):
        self.futures = futures
        self.stats = stats
        self.groups = groups
        self.ids = ids
        self.owner = owner
        self.rows = rows
        self.cache = cache
        self.timed = timed
        self.fresh = fresh or set()

    def result(self) -> list:
        t = time.perf_counter()
        out = [self.rows.get(k) for k in range(len(self.ids))]
        for n, (future, group) in enumerate(zip(self.futures, self.groups, strict=True)):
            where, rows, seconds = future.result()
            if self.timed is not None and n in self.fresh:
                self.timed(len(rows), seconds)
            pids, slots = group
            for p, k, row in zip(pids, slots, rows, strict=True):
                if k >= 0:
                    out[k] = row
                self.cache.put(p, row)
                if where is not None:
                    self.owner[p] = where
        self.stats["wait"] += time.perf_counter() - t
        self.futures = []                  # release: the scheduler forgets the keys
        return out


class DaskExecutor:
    """Form factors and tiles as futures of ``client``.

    ``dashboard_ports``: ``(asked, got)``, the dashboard port a LocalCluster started here
    was asked for and the one it serves on (another when that one was busy); ``(0, 0)``
    when not known (a cluster not started here, or port 0 asked).

    Parameters
    ----------
    client : distributed.Client
    store : Store, optional
        Where task contexts go; a temporary store (usable by local workers only) if None.
    cluster : optional
        A cluster this executor started and closes in :meth:`close`.
    own_client : bool
        Close ``client`` in :meth:`close` (always when ``cluster`` is given); a client passed
        in by the caller (a test's session cluster) is left open.
    dashboard_host : str, optional
        The host the dashboard of a cluster started here listens on, for its link; None: the
        client's own link.
    """

    dashboard_ports: tuple[int, int] = (0, 0)

    def __init__(self, client, store: Store | None = None, cluster=None,
                 own_client: bool = False, dashboard_host: str | None = None):
        self.client = client
        self.cluster = cluster
        self.own_client = own_client or cluster is not None
        self._tmp = None
        if store is None:
            self._tmp = tempfile.mkdtemp(prefix="daskrad-")
            store = Store(Path(self._tmp) / "tasks.zarr")
        self.store = store
        self.run = uuid.uuid4().hex[:8]
        self.workers = 0
        self.addresses: list[str] = []     # the workers' addresses, sorted
        self.owner: dict[int, str] = {}
        self.rows = shooting.RowCache()    # rows the client received (set_geometry sizes it)
        # workers running in this process share the client's memory: contexts need no store
        self.shared = _shares_process(client)
        self._counted = -float("inf")
        self.row_seconds = None            # seconds a new row takes, as measured so far
        self._count_workers()
        self.dashboard_link = _dashboard(client, dashboard_host)
        self.stats = {"wait": 0.0, "tasks": 0, "ahead": 0}
        self._publisher = Publisher(
            lambda key, value: client.set_metadata(["daskrad", key], value),
            thread=PUBLISH_THREAD)
        # numbers every prefetched task's key: a patch dropped from the offer and offered again
        # while its first task is still alive must get a new task, not that one's future
        # (Client.submit hands back the live future of a key it already has)
        self._ahead_count = 0
        self.geometry = None               # (generation, token) of the current geometry
        self._forget_prefetched()
        self._probed = False
        self._started: list[Ahead] = []    # work started ahead (ahead), stopped by close
        self._phase = (None, -float("inf"))
        # the dashboard page shows a phase from the first second: the mesh is built next
        self.phase("preprocessing", force=True)

    # --- the executor interface -------------------------------------------------------------

    def use_store(self, store: Store) -> None:
        """Put the task contexts in ``store`` from now on (the run's own store: a new run's
        partial store, whatever store the executor was made with)."""
        if store is not self.store:
            if self.shared:
                worker.unshare(self.store.path)
            self.store = store
            self._probed = False

    def set_geometry(self, shoot_ctx: shooting.ShootContext, generation: int = 0) -> None:
        token = self._put_context("shoot", shoot_ctx, generation)
        self.geometry = (generation, token)
        self.owner = {}                    # patch id -> the worker holding its row
        budget = shooting.row_cache_bytes(shoot_ctx, physical_memory())
        # workers that are threads of this process fill the client's own cache: the rows are
        # the same objects, kept and counted once within one budget for the process
        self.rows = (worker.row_cache(self.store.path, generation, token, shoot_ctx, budget)
                     if self.shared else shooting.RowCache(budget))
        self._forget_prefetched()
        self.row_seconds = None
        self.phase("shooting", 0.0, force=True)

    def _forget_prefetched(self) -> None:
        """No rows computed ahead (a new executor, or a new geometry: the old rows are of
        another mesh)."""
        self._ahead: dict = {}             # patch id -> the future of its row, prefetched
        self._ahead_ids: dict = {}         # a prefetched future's key -> its patch ids
        self._counted_ahead: set = set()   # keys of prefetched futures a batch has timed

    def shots(self, batch_no: int, patch_ids: np.ndarray) -> _Batch:
        """Batch ``batch_no``: the rows the client keeps, tasks of new rows, and one per
        worker for the re-shots it holds.

        A patch shoots about five times in a converging solve. The client keeps every row it
        received (:class:`~daskrad.formfactor.shooting.RowCache`, sized like the workers'), so
        a re-shot costs no task and no transfer (the Cornell box at 73,000 elements: rows of
        ~0.5 MB, 1,275 re-shots). A row the client dropped but a worker kept goes back to that
        worker in one task per worker (a soft restriction: a lost or busy worker's may run
        elsewhere, and compute the row again).
        A row never computed is a task of its own, placed by the scheduler: rows differ in
        cost by up to 6× (penumbra sampling), and single tasks keep both workers busy where a
        fixed share of the batch per worker left one waiting; only rows cheaper than a task's
        own cost are grouped, enough of them to make :data:`TASK_SECONDS` by the mean time of
        the rows so far, and never fewer tasks than workers. Where a row was computed is
        learnt from the task's answer. The rows are the same bits wherever they are computed,
        in tasks of any size.
        """
        generation, token = self.geometry
        self._count_workers()
        ids = np.asarray(patch_ids, np.int64)
        alive = set(self.addresses)
        held: dict = {}
        new: list[int] = []
        have: dict = {}
        futures, groups, fresh = [], [], set()
        position = {p: k for k, p in enumerate(ids.tolist())}
        taken: set = set()                 # keys of the prefetched futures this batch takes
        for k, p in enumerate(ids.tolist()):
            row = self.rows.get(p)
            a = self.owner.get(p)
            if row is not None:
                have[k] = row
            elif p in self._ahead:
                future = self._ahead[p]
                if future.key not in taken:
                    taken.add(future.key)
                    if future.key not in self._counted_ahead:
                        self._counted_ahead.add(future.key)
                        fresh.add(len(futures))
                    futures.append(future)
                    pids = self._ahead_ids[future.key]
                    groups.append((pids, [position.get(q, -1) for q in pids]))
            elif a in alive:
                held.setdefault(a, []).append(k)
            else:
                new.append(k)
        for n, a in enumerate(sorted(held)):
            futures.append(self.client.submit(
                worker.shoot_task, self.store.path, generation, token, ids[held[a]],
                key=f"formfactor-{generation}-{batch_no}-held{n}-{self.run}", pure=False,
                workers=[a], allow_other_workers=True))
            groups.append((ids[held[a]].tolist(), held[a]))
        for part in row_tasks(new, self.row_seconds, self.workers):
            fresh.add(len(futures))
            futures.append(self.client.submit(
                worker.shoot_task, self.store.path, generation, token, ids[part],
                key=f"formfactor-{generation}-{batch_no}-new{part[0]}-{self.run}", pure=False))
            groups.append((ids[part].tolist(), part))
        self.stats["tasks"] += len(futures)
        return _Batch(futures, self.stats, groups, ids, self.owner, have, self.rows,
                      self._timed, fresh)

    def _timed(self, rows: int, seconds: float) -> None:
        """A task computed ``rows`` rows in ``seconds``: the running mean per row."""
        if rows:
            per = seconds / rows
            self.row_seconds = per if self.row_seconds is None else \
                0.9 * self.row_seconds + 0.1 * per

    def prefetch(self, patch_ids: np.ndarray) -> None:
        """Start the rows of ``patch_ids`` (in that order) that no one holds yet, while fewer
        prefetched tasks than :data:`AHEAD_TASKS` per worker are unfinished: a worker that
        would wait for the client's next batch computes rows the solve will mostly ask for
        within a few batches (:func:`daskrad.solve.solve`), and a batch submitted next waits
        behind at most that many such tasks per worker. A task takes as many rows as make
        :data:`TASK_SECONDS` (:func:`rows_per_task`; one until a row was timed): each task
        costs the scheduler and the client as much as a cheap row. A batch that shoots one of
        the patches takes the task's future and keeps all of its rows. Not while the client's
        row cache is half full (a dropped row costs twice). Patches no longer offered, or whose
        row came, are forgotten (a future nobody holds is released; the worker keeps a
        finished row in its own cache, where a later shot of the patch may find it)."""
        offered = set(np.asarray(patch_ids).tolist())
        for p in [p for p in self._ahead if p not in offered or self.rows.has(p)]:
            del self._ahead[p]
        live = {f.key for f in self._ahead.values()}
        self._ahead_ids = {k: v for k, v in self._ahead_ids.items() if k in live}
        if self.geometry is None or self.rows.nbytes > self.rows.max_bytes // 2:
            return
        generation, token = self.geometry
        room = AHEAD_TASKS * self.workers - len({f.key for f in self._ahead.values()
                                                 if not f.done()})
        if room <= 0:
            return
        wanted = [p for p in np.asarray(patch_ids).tolist()
                  if p not in self._ahead and p not in self.owner and not self.rows.has(p)]
        size = rows_per_task(self.row_seconds)
        for a in range(0, min(len(wanted), room * size), size):
            part = wanted[a:a + size]
            key = f"formfactor-{generation}-ahead{self._ahead_count}-{self.run}"
            self._ahead_count += 1
            future = self.client.submit(
                worker.shoot_task, self.store.path, generation, token,
                np.array(part, np.int64), key=key, pure=False)
            self._ahead_ids[key] = part
            for p in part:
                self._ahead[p] = future
            self.stats["tasks"] += 1
            self.stats["ahead"] += 1

    def tiles(self, ctx: render.RenderContext, tiles: list) -> list[tuple[np.ndarray, dict]]:
        """The image's tiles as ``tile-<generation>-<n>`` futures, in order: each its image
        and counts (:func:`daskrad.render.render_tile_stats`)."""
        generation = self.geometry[0] if self.geometry else 0
        return self._context_tasks(
            "render", ctx, generation, worker.tile_task,
            [(rows.start, rows.stop, cols.start, cols.stop) for rows, cols in tiles],
            lambda n, item, token: f"tile-{generation}-{n}", "rendering")

    def direct(self, ctx, ranges: list[tuple[int, int]]) -> list[tuple]:
        """Direct light at vertex ranges as ``direct-<generation>-<n>`` futures, in order."""
        generation = int(getattr(ctx, "generation", 0))
        return self._context_tasks(
            "direct", ctx, generation, worker.direct_task, ranges,
            lambda n, item, token: f"direct-{generation}-{n}-{item[0]}", "direct light")

    def gather(self, ctx: render.GatherContext, ranges: list[tuple[int, int]]
               ) -> list[render.GatherOperator]:
        """The junction gather's operator rows over ranges of its vertices as
        ``gather-<generation>-<n>`` futures, in order. The context's token is in the key: a
        re-render with another view gathers other vertices over the same ranges."""
        generation = self.geometry[0] if self.geometry else 0
        return self._context_tasks(
            "gather", ctx, generation, worker.gather_task, ranges,
            lambda n, item, token: f"gather-{generation}-{n}-{item[0]}-{token}", "rendering",
            "junction gather: ")

    def ahead(self, kind: str, plan, context_of, ranges_of) -> Ahead:
        """Start the ``kind`` tasks (:func:`daskrad.distributed.executor.ahead_task`) on a
        thread of this process, the client's, that runs only where one of its machine's cores
        is idle (:class:`~daskrad.distributed.executor.Ahead`): the client applies the shots
        in order and leaves its machine's cores mostly idle while the workers compute rows, or
        shares them with thread workers that wait on it between batches. ``result()`` sends
        what it has not done to the workers (:func:`daskrad.render.gather_merged`: tasks of
        :func:`daskrad.render.gather_batch` vertices, as the render sends). Not as Dask
        tasks ahead: sent at a priority below the rows', they took from the solve what they
        spared the render (the Cornell box at 73,063 elements, 2 thread workers, medians of
        2: solve 3.60 → 4.92 s, render 2.12 → 0.87 s, the run 6.83 → 6.93 s)."""
        runs = {"gather": lambda ctx, ranges: render.gather_merged(ctx, ranges, self)}
        work = Ahead(plan, context_of, ranges_of, ahead_task(kind), runs[kind])
        self._started.append(work)
        return work

    def _context_tasks(self, kind: str, ctx, generation: int, task, items: list, key,
                       phase: str, what: str = "") -> list:
        """``task(store path, generation, token, *item)`` for every item as futures, their
        results in order: ``ctx`` is written once into the store as the ``kind`` context
        (``token``), every worker is probed for it, and future ``n`` is keyed
        ``key(n, item, token)-<run>``; the phase ``phase`` (detail headed ``what``) follows
        them on the dashboard."""
        token = self._put_context(kind, ctx, generation)
        futures = [
            self.client.submit(task, self.store.path, generation, token, *item,
                               key=f"{key(n, item, token)}-{self.run}", pure=False)
            for n, item in enumerate(items)]
        self.stats["tasks"] += len(futures)
        return self._gather(phase, futures, what)

    def memory(self) -> dict:
        """Peak memory of the client and of each worker (MiB), and the row caches; with
        ``workers_in_client_process`` every worker's figures are the client process's."""
        # workers that are threads of this process report its peak, and one row cache; a task
        # still running (a prefetched row the solve no longer wanted) may add a row meanwhile,
        # so the figures are read until the cache stood still around the workers' reports
        for _ in range(10):
            usage = self.rows.usage()
            states = self.client.run(worker.state)
            if self.rows.usage() == usage:
                break
        return {"client_peak_mib": peak_mib(), **usage,
                "workers_in_client_process": self.shared,
                "workers": [{k: states[a][k] for k in ("peak_mib", "row_cache_mib",
                                                       "row_cache_limit_mib")}
                            for a in sorted(states)]}

    def publish(self, key: str, value) -> None:
        """Progress for the ``/daskrad`` page (scheduler metadata, small JSON values), sent
        by a thread of its own (:class:`Publisher`): the solve's client does not wait for the
        scheduler's answer, nor for a preview to render (``value`` may be a function of no
        arguments, called on that thread). :meth:`close` sends what is left."""
        self._publisher.put(key, value)

    def phase(self, name: str, fraction: float = 0.0, detail: str = "",
              force: bool = False) -> None:
        """The run's current phase and how far it is (``fraction`` in [0, 1]) for the page,
        at most every ``PHASE_SECONDS`` within one phase unless ``force``."""
        now = time.monotonic()
        if not force and self._phase[0] == name and now - self._phase[1] < PHASE_SECONDS:
            return
        self._phase = (name, now)
        self.publish("phase", {"phase": name, "fraction": round(float(fraction), 4),
                               "detail": detail})

    def _gather(self, name: str, futures: list, what: str = "") -> list:
        """The futures' results in order, publishing the phase ``name`` as they complete
        (``what`` heads the detail: a phase may run several kinds of task)."""
        from distributed import as_completed

        total = len(futures)
        self.phase(name, 0.0, f"{what}0 of {total} tasks", force=True)
        for n, _ in enumerate(as_completed(futures), 1):
            self.phase(name, n / total, f"{what}{n} of {total} tasks", force=n == total)
        return self.client.gather(futures)

    def close(self) -> None:
        for work in self._started:
            work.close()
        self._started = []
        try:        # the last progress reaches the page before the client goes
            self._publisher.close()
        finally:    # and the cluster is closed whatever the publisher or a Ctrl-C did
            if self.shared:
                worker.unshare(self.store.path)
            if self.own_client:
                self.client.close()
            if self.cluster is not None:
                self.cluster.close()
            if self._tmp is not None:
                shutil.rmtree(self._tmp, ignore_errors=True)

    # --- helpers ----------------------------------------------------------------------------

    def _count_workers(self) -> None:
        """Workers now in the cluster (they may join or leave mid-run), asked at most every
        ``COUNT_SECONDS``. Only how a batch is split depends on it, never the result."""
        now = time.monotonic()
        if now - self._counted >= COUNT_SECONDS:
            self.addresses = sorted(self.client.scheduler_info(n_workers=-1)["workers"])
            self.workers = len(self.addresses)
            self._counted = now

    def _put_context(self, kind: str, ctx, generation: int) -> str:
        """Make ``ctx`` the ``kind`` context the tasks of ``generation`` read; returns the
        token they name it by. Workers in other processes read it from the store (written
        once: the token is a digest of the content; every worker probed first); workers in
        this process get the object itself (:func:`worker.share`, a fresh token)."""
        if self.shared:
            token = uuid.uuid4().hex[:24]
            worker.share(self.store.path, kind, generation, token, ctx)
            return token
        token = self.store.put_context(kind, ctx)
        self._probe(kind, token)
        return token

    def _probe(self, kind: str, token: str) -> None:
        """Every worker must open the store: say clearly when a remote one cannot."""
        if self._probed:
            return
        answers = self.client.run(worker.probe, self.store.path, kind, token)
        bad = {w: why for w, why in answers.items() if why is not None}
        if bad:
            w, why = next(iter(bad.items()))
            raise OptionError(
                f"{len(bad)} of {len(answers)} workers cannot open the solution store "
                f"{self.store.path} (e.g. {w}: {why}); with --scheduler the output must be "
                "on a file system every worker shares", self.store.given)
        self._probed = True


class Publisher:
    """Sends ``(key, value)`` messages with ``send(key, value)`` on a thread of its own, so
    that the caller never waits for them: the solve's client published its progress and
    preview between two batches and waited for the scheduler's answer each time (the
    73,000-element Cornell box on 2 thread workers, ``benchmarks/bench_client.py``: the
    client's seconds in the monitor 0.40 → 0.24, the solve 0.96×). Only the latest value of
    a key not yet sent is sent (a page shows the latest); keys go in the order they were
    first put. A value that is a function of no arguments is called on the thread (a
    preview's render and PNG).

    Progress is a view, never read back: a message the scheduler does not take (it is gone)
    is dropped, and the run meets the lost scheduler at its next task. A value's function
    that fails is daskrad's own bug: the first such error is raised by :meth:`close`. The
    thread ends when nothing was put for :data:`IDLE_SECONDS` (an executor a test never
    closes leaves no thread behind) and starts again at the next message. ``thread`` False:
    each message is sent in the caller's thread as it is put (:data:`PUBLISH_THREAD`), and
    its errors raised there, as before."""

    #: Seconds without a message after which the thread ends.
    IDLE_SECONDS = 5.0
    #: Seconds :meth:`close` waits for the messages still pending (a scheduler that went
    #: away may hold each for its connect timeout; the run's own end or error comes first).
    CLOSE_SECONDS = 10.0

    def __init__(self, send, thread: bool = True):
        self._send = send
        self._pending: dict = {}
        self._cond = threading.Condition()
        self._closed = False
        self._threaded = thread
        self._thread: threading.Thread | None = None
        self.failure: BaseException | None = None

    def put(self, key: str, value) -> None:
        if not self._threaded:            # no thread: sent at once, in the caller's
            if not self._closed:
                self._send(key, value() if callable(value) else value)
            return
        with self._cond:
            if self._closed:
                return
            self._pending[key] = value
            if self._thread is None:
                self._thread = threading.Thread(target=self._loop, name="daskrad-publish",
                                                daemon=True)
                self._thread.start()
            self._cond.notify_all()

    def close(self) -> None:
        """Send what is pending (for :data:`CLOSE_SECONDS` at most), then stop; raise the
        first error of a value's function."""
        with self._cond:
            self._closed = True
            thread = self._thread
            self._cond.notify_all()
        if thread is not None and thread is not threading.current_thread():
            thread.join(self.CLOSE_SECONDS)
        if self.failure is not None:
            raise self.failure

    def _loop(self) -> None:
        while True:
            with self._cond:
                if not self._pending and not self._closed:
                    self._cond.wait(self.IDLE_SECONDS)
                if not self._pending:
                    self._thread = None     # closed and all sent, or idle: a put starts anew
                    return
                key = next(iter(self._pending))
                value = self._pending.pop(key)
            if callable(value):
                try:
                    value = value()
                except Exception as err:  # noqa: BLE001 - daskrad's own bug: close raises it
                    self.failure = self.failure or err
                    continue
            try:
                self._send(key, value)
            except Exception:  # noqa: BLE001, S110 - the scheduler is gone: see the docstring
                pass


def rows_per_task(row_seconds: float | None) -> int:
    """How many rows of ``row_seconds`` each make :data:`TASK_SECONDS` (1 until a row was
    timed, and for rows dearer than a task)."""
    if row_seconds is None or row_seconds <= 0:
        return 1
    return max(1, math.ceil(TASK_SECONDS / row_seconds))


def row_tasks(new: list[int], row_seconds: float | None, workers: int) -> list[list[int]]:
    """``new`` (positions of new rows in a batch) in order, cut into tasks of
    :func:`rows_per_task` rows, but into at least ``workers`` tasks (when there are as many
    rows)."""
    if not new:
        return []
    size = max(1, min(rows_per_task(row_seconds), math.ceil(len(new) / max(workers, 1))))
    return [new[a:a + size] for a in range(0, len(new), size)]


def _shares_process(client) -> bool:
    """Whether every worker of ``client`` runs in this process (a LocalCluster of threads):
    each answers its process's random name (:data:`worker.PROCESS`), so a worker elsewhere,
    even one with this pid on another machine, never matches."""
    answers = client.run(worker.process)
    return bool(answers) and all(name == worker.PROCESS for name in answers.values())


def _dashboard(client, host: str | None = None) -> str | None:
    """The dashboard's link, None without one. ``host``: where a LocalCluster started here
    listens; the link is built from it and the port, since a cluster of threads talks
    inproc:// and its ``client.dashboard_link`` would name the machine's address instead."""
    try:
        services = client.scheduler_info(n_workers=0).get("services", {})
    except Exception:  # noqa: BLE001 - no dashboard is not an error
        return None
    if "dashboard" not in services:
        return None
    if host is None:
        return client.dashboard_link
    return f"http://{host or '127.0.0.1'}:{services['dashboard']}/status"


class CancelRace(logging.Filter):
    """Drops tornado's report of a race in ``distributed.utils.sync``: a Ctrl-C in the
    instant between a call's start and its future's creation makes the ``cancel`` callback
    read the unassigned ``future`` (``NameError: cannot access free variable``), and tornado
    logs that with a traceback on the event loop's thread, above daskrad's one line. The
    interrupt itself still reaches the main thread and is reported there; nothing else that
    tornado logs is dropped."""

    def filter(self, record: logging.LogRecord) -> bool:
        exc = record.exc_info[1] if record.exc_info else None
        if not isinstance(exc, NameError) or exc.__traceback__ is None:
            return True
        tb = exc.__traceback__
        while tb.tb_next is not None:
            tb = tb.tb_next
        code = tb.tb_frame.f_code
        return not (code.co_name == "cancel"
                    and Path(code.co_filename).parts[-2:] == ("distributed", "utils.py"))


CANCEL_RACE = CancelRace()


def hush_cancel_race() -> None:
    """Installs :class:`CancelRace` on tornado's callback logger, once per process."""
    logging.getLogger("tornado.application").addFilter(CANCEL_RACE)   # added once only


def quiet_dask() -> None:
    """What daskrad's clients filter out of Dask's output, for the rest of the process:
    tornado's report of the cancel race (:class:`CancelRace`), and the several-line warning
    of a busy dashboard port (Dask takes another; daskrad's dashboard line names the port
    it asked for, :attr:`DaskExecutor.dashboard_ports`). Called from the main thread before
    a cluster starts on a thread of its own (:func:`daskrad.distributed.start_early`): the
    warnings filters are one list, which the main thread's ``catch_warnings`` (the MGF
    reader's) copies on entry and puts back on exit, so a filter added from another thread
    meanwhile would be lost."""
    hush_cancel_race()
    warnings.filterwarnings("ignore", message=r"Port \d+ is already in use",
                            category=UserWarning)


def start_local(settings, store: Store | None) -> DaskExecutor:
    """``--workers N``: a LocalCluster of N workers with one thread each, its dashboard on
    ``settings.dashboard`` (loopback by default).

    The workers are threads of this process unless ``settings.processes``: the kernels
    release the GIL, so threads run side by side as processes would, while they share the
    client's memory: no task context goes through the store, and one row cache serves every
    worker (``bench_speed``'s workers table measures both kinds). Processes stand in for the
    machines of a real cluster (``--scheduler``): each reads the store and keeps its own
    caches, and numba's threads are set to the worker's one thread.
    """
    import dask
    from distributed import Client, LocalCluster

    quiet_dask()        # for the paths without start_early; again after it: harmless
    routes = list(dask.config.get("distributed.scheduler.http.routes"))
    kinds = ({"processes": True, "host": "127.0.0.1", "env": {"NUMBA_NUM_THREADS": "1"}}
             if settings.processes else {"processes": False})
    with dask.config.set({"distributed.scheduler.http.routes": routes + [ROUTES_MODULE]}), \
            _children_ignore_sigint():
        cluster = LocalCluster(
            n_workers=settings.workers, threads_per_worker=1, silence_logs=logging.ERROR,
            dashboard_address=settings.dashboard, **kinds)
    ex = DaskExecutor(Client(cluster), store, cluster=cluster,
                      dashboard_host=settings.dashboard.rsplit(":", 1)[0])
    got = urllib.parse.urlsplit(ex.dashboard_link).port if ex.dashboard_link else None
    ex.dashboard_ports = (int(settings.dashboard.rsplit(":", 1)[1]), got or 0)
    return ex


@contextlib.contextmanager
def _children_ignore_sigint():
    """SIGINT ignored while the worker processes start, so that they keep ignoring it (an
    ignored signal stays ignored across exec, and Python then installs no handler): Ctrl-C
    in a terminal reaches every process of the group, and the client alone must answer it
    (one line, the checkpoint kept; it closes the cluster), not each worker with a
    traceback. Only from the main thread, where signal handlers can be set."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def connect_scheduler(settings, store: Store | None) -> DaskExecutor:
    """``--scheduler ADDR``: an existing cluster; the store must be on a shared path."""
    from distributed import Client

    if store is not None and not Path(store.given).is_absolute():
        raise OptionError(
            "with --scheduler every worker opens the solution store itself, so the output "
            f"must be an absolute path on a shared file system (got {store.given}; "
            "e.g. -o /shared/run/out.exr)", store.given)
    hush_cancel_race()
    try:
        client = Client(settings.scheduler, timeout=settings.connect_timeout)
    except (OSError, TimeoutError) as err:
        raise OptionError(f"cannot reach the Dask scheduler {settings.scheduler}: {err}") \
            from err
    try:
        client.wait_for_workers(1, timeout=settings.connect_timeout)
    except TimeoutError as err:
        client.close()
        raise OptionError(f"the Dask scheduler {settings.scheduler} has no workers") from err
    return DaskExecutor(client, store, own_client=True)
