"""The Dask executor: the same calls as :class:`~daskrad.distributed.executor.InProcess`,
run as named futures on a cluster (docs/design.md §4).

Futures carry ids and ranges only; the geometry goes once into the store
(:meth:`Store.put_context`) and each worker caches it (:mod:`daskrad.distributed.worker`).
Keys are ``formfactor-<generation>-<batch>-<part>-<run>``,
``direct-<generation>-<n>-<start>-<run>``, ``gather-<generation>-<n>-<start>-<token>-<run>``
and ``tile-<generation>-<n>-<run>``: the dashboard groups them by their first word; the 8-hex
run token keeps two runs on one cluster (or two runs of one test session) from sharing a key,
since a key still held by the scheduler returns
its old result (docs/stack.md).
"""

from __future__ import annotations

import logging
import shutil
import tempfile
import time
import uuid
from pathlib import Path

import numpy as np

from daskrad import render
from daskrad.distributed import worker
from daskrad.distributed.memory import peak_mib
from daskrad.distributed.store import Store
from daskrad.errors import OptionError
from daskrad.formfactor import shooting

#: Seconds between two counts of the cluster's workers.
COUNT_SECONDS = 2.0
#: Seconds between two phase messages of one phase for the dashboard page.
PHASE_SECONDS = 0.5

#: Custom dashboard page module (``/daskrad``), added to the scheduler's HTTP routes.
ROUTES_MODULE = "daskrad.distributed.dashboard"


class _Batch:
    """A batch's futures (one per worker); ``result()`` gives the rows in shooter order.

    ``order[k]`` is the position in the batch of the ``k``-th row the futures return, in
    future order (a future computes the shooters one worker holds)."""

    def __init__(self, futures: list, stats: dict, order: list[int]):
        self.futures = futures
        self.stats = stats
        self.order = order

    def result(self) -> list:
        t = time.perf_counter()
        rows = []
        for future in self.futures:
            rows.extend(future.result())
        self.stats["wait"] += time.perf_counter() - t
        self.futures = []                  # release: the scheduler forgets the keys
        out = [None] * len(rows)
        for k, row in zip(self.order, rows, strict=True):
            out[k] = row
        return out


class DaskExecutor:
    """Form factors and tiles as futures of ``client``.

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
    """

    def __init__(self, client, store: Store | None = None, cluster=None,
                 own_client: bool = False):
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
        self._counted = -float("inf")
        self._count_workers()
        self.dashboard_link = _dashboard(client)
        self.stats = {"wait": 0.0, "tasks": 0}
        self.geometry = None               # (generation, token) of the current geometry
        self._probed = False
        self._phase = (None, -float("inf"))
        # the dashboard page shows a phase from the first second: the mesh is built next
        self.phase("preprocessing", force=True)

    # --- the executor interface -------------------------------------------------------------

    def use_store(self, store: Store) -> None:
        """Put the task contexts in ``store`` from now on (the run's own store: a new run's
        partial store, whatever store the executor was made with)."""
        if store is not self.store:
            self.store = store
            self._probed = False

    def set_geometry(self, shoot_ctx: shooting.ShootContext, generation: int = 0) -> None:
        token = self.store.put_context("shoot", shoot_ctx)
        self.geometry = (generation, token)
        self.owner = {}                    # patch id -> the worker holding its row
        self._probe("shoot", token)
        self.phase("shooting", 0.0, force=True)

    def shots(self, batch_no: int, patch_ids: np.ndarray) -> _Batch:
        """Batch ``batch_no``: one task per worker, each computing the shooters it holds.

        A patch shoots about five times in a converging solve, and its row, kept by the worker
        that computed it (:class:`~daskrad.formfactor.shooting.RowCache`), costs nothing the
        next time there. So a patch goes back to the worker that computed its row; a patch
        never shot (or whose worker left) goes to the worker with the fewest new rows in this
        batch. The rows are the same bits wherever they are computed: this decides only where
        the work runs (a soft restriction: a busy or lost worker's shots may run elsewhere).
        """
        generation, token = self.geometry
        self._count_workers()
        ids = np.asarray(patch_ids, np.int64)
        addresses = self.addresses or [None]
        new_rows = dict.fromkeys(addresses, 0)
        groups: dict = {a: [] for a in addresses}
        for k, p in enumerate(ids.tolist()):
            a = self.owner.get(p)
            if a not in new_rows:
                a = min(addresses, key=lambda w: new_rows[w])   # first of the least loaded
                new_rows[a] += 1
                self.owner[p] = a
            groups[a].append(k)
        futures, order = [], []
        for n, a in enumerate(addresses):
            if not groups[a]:
                continue
            futures.append(self.client.submit(
                worker.shoot_task, self.store.path, generation, token, ids[groups[a]],
                key=f"formfactor-{generation}-{batch_no}-{n}-{self.run}", pure=False,
                workers=None if a is None else [a], allow_other_workers=True))
            order.extend(groups[a])
        self.stats["tasks"] += len(futures)
        return _Batch(futures, self.stats, order)

    def tiles(self, ctx: render.RenderContext, tiles: list) -> list[np.ndarray]:
        generation = self.geometry[0] if self.geometry else 0
        token = self.store.put_context("render", ctx)
        self._probe("render", token)
        futures = [
            self.client.submit(worker.tile_task, self.store.path, generation, token,
                               rows.start, rows.stop, cols.start, cols.stop,
                               key=f"tile-{generation}-{n}-{self.run}", pure=False)
            for n, (rows, cols) in enumerate(tiles)]
        self.stats["tasks"] += len(futures)
        return self._gather("rendering", futures)

    def direct(self, ctx, ranges: list[tuple[int, int]]) -> list[np.ndarray]:
        """Direct light at vertex ranges as ``direct-<generation>-<n>`` futures, in order."""
        generation = int(getattr(ctx, "generation", 0))
        token = self.store.put_context("direct", ctx)
        self._probe("direct", token)
        futures = [
            self.client.submit(worker.direct_task, self.store.path, generation, token, a, b,
                               key=f"direct-{generation}-{n}-{a}-{self.run}", pure=False)
            for n, (a, b) in enumerate(ranges)]
        self.stats["tasks"] += len(futures)
        return self._gather("direct light", futures)

    def gather(self, ctx: render.GatherContext, ranges: list[tuple[int, int]]
               ) -> list[np.ndarray]:
        """The junction gather over ranges of its vertices as ``gather-<generation>-<n>``
        futures, in order. The context's token is in the key: a render gathers several times
        (the correction passes) over the same ranges."""
        generation = self.geometry[0] if self.geometry else 0
        token = self.store.put_context("gather", ctx)
        self._probe("gather", token)
        futures = [
            self.client.submit(worker.gather_task, self.store.path, generation, token, a, b,
                               key=f"gather-{generation}-{n}-{a}-{token}-{self.run}",
                               pure=False)
            for n, (a, b) in enumerate(ranges)]
        self.stats["tasks"] += len(futures)
        return self._gather("rendering", futures, "junction gather: ")

    def memory(self) -> dict:
        """Peak memory of the client and of each worker (MiB), and each worker's row cache."""
        states = self.client.run(worker.state)
        return {"client_peak_mib": peak_mib(),
                "workers": [{k: states[a][k] for k in ("peak_mib", "row_cache_mib",
                                                       "row_cache_limit_mib")}
                            for a in sorted(states)]}

    def publish(self, key: str, value) -> None:
        """Progress for the ``/daskrad`` page (scheduler metadata, small JSON values)."""
        self.client.set_metadata(["daskrad", key], value)

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


def _dashboard(client) -> str | None:
    try:
        services = client.scheduler_info(n_workers=0).get("services", {})
    except Exception:  # noqa: BLE001 - no dashboard is not an error
        return None
    return client.dashboard_link if "dashboard" in services else None


def start_local(settings, store: Store | None) -> DaskExecutor:
    """``--workers N``: a LocalCluster of N processes with one thread each, on loopback."""
    import dask
    from distributed import Client, LocalCluster

    routes = list(dask.config.get("distributed.scheduler.http.routes"))
    with dask.config.set({"distributed.scheduler.http.routes": routes + [ROUTES_MODULE]}):
        cluster = LocalCluster(
            n_workers=settings.workers, threads_per_worker=1, processes=True,
            host="127.0.0.1", dashboard_address=settings.dashboard,
            # numba's threads match the worker's one thread: N workers share N cores
            env={"NUMBA_NUM_THREADS": "1"}, silence_logs=logging.ERROR)
    return DaskExecutor(Client(cluster), store, cluster=cluster)


def connect_scheduler(settings, store: Store | None) -> DaskExecutor:
    """``--scheduler ADDR``: an existing cluster; the store must be on a shared path."""
    from distributed import Client

    if store is not None and not Path(store.given).is_absolute():
        raise OptionError(
            "with --scheduler every worker opens the solution store itself, so the output "
            f"must be an absolute path on a shared file system (got {store.given}; "
            "e.g. -o /shared/run/out.exr)", store.given)
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
