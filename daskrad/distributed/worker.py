"""What runs on a Dask worker: the task functions and the per-process context cache.

A task names what it needs — the store's path, the mesh generation, the context's token and a
few ids or a pixel range — and finds the geometry in this module's cache, filled once per
(store path, generation, token) from the store (docs/design.md §4). The cache lives in the
package, not in ``__main__``, so it persists between tasks in a worker process (docs/stack.md: a
task that reopens zarr costs 50–85 ms, a cache hit ~2 ms). The voxel grid of the render context is
read from the store, so it is built once (by the client) and loaded once per worker.

Workers that are threads of the client's own process (a LocalCluster's default,
``processes=False``) skip the store: the client hands each context over in memory
(:func:`share`), and the form-factor rows are one cache for all of them.
"""

from __future__ import annotations

import os
import threading
import time
import uuid
from collections import OrderedDict

import numpy as np

from daskrad import render
from daskrad.distributed.memory import peak_mib, physical_memory
from daskrad.distributed.store import load_context
from daskrad.formfactor import shooting

#: Contexts kept per process: the current shoot and render contexts, plus one generation back
#: while a refinement switches over.
CACHE_SIZE = 4

_cache: OrderedDict = OrderedDict()
_rows: OrderedDict = OrderedDict()  # (path, generation, token) → shooting.RowCache
_lock = threading.Lock()          # a worker with several threads loads a context once
loads = 0                         # contexts read from a store by this process (tests look)
#: (store path, kind) → ((generation, token), context): contexts the client of this process
#: handed over in memory (:func:`share`), the latest of each kind, never evicted by ``_cache``
_shared: dict = {}
#: Names this process: a worker answering the client's own value runs in the client's process.
PROCESS = uuid.uuid4().hex


def process() -> str:
    """:data:`PROCESS` (``client.run(process)`` tells which workers share the client's)."""
    return PROCESS


def share(path: str, kind: str, generation: int, token: str, ctx) -> None:
    """Hand the ``kind`` context over to this process's workers without the store (their
    tasks name it by ``path``, ``generation`` and ``token`` as usual); it replaces the one of
    that kind shared before."""
    with _lock:
        _shared[(path, kind)] = ((generation, token), ctx)


def shared_kinds(path: str) -> list[str]:
    """The kinds of context shared in memory for the store at ``path``."""
    with _lock:
        return sorted(kind for p, kind in _shared if p == path)


def unshare(path: str) -> None:
    """Forget the contexts and rows of the store at ``path`` (the executor closes)."""
    with _lock:
        for key in [k for k in _shared if k[0] == path]:
            del _shared[key]
        for key in [k for k in _rows if k[0] == path]:
            del _rows[key]


def context(path: str, kind: str, generation: int, token: str):
    """The ``kind`` context of the store at ``path`` for ``generation``, cached."""
    global loads
    key = (path, kind, generation, token)
    with _lock:
        shared = _shared.get((path, kind))
        if shared is not None and shared[0] == (generation, token):
            return shared[1]
        ctx = _cache.get(key)
        if ctx is None:
            ctx = load_context(path, kind, token)
            loads += 1
            _cache[key] = ctx
            while len(_cache) > CACHE_SIZE:
                _cache.popitem(last=False)
        else:
            _cache.move_to_end(key)
    return ctx


def shoot_task(path: str, generation: int, token: str, patch_ids: np.ndarray
               ) -> tuple[str | None, list, float]:
    """``(this worker's address, rows, seconds)``: the form-factor rows of the shooters
    ``patch_ids`` (:func:`daskrad.formfactor.shooting.shoot_rows`), with the rows this process
    already computed for that geometry (the client sends a re-shot back where its row is
    kept), and the seconds they took (the client sizes its tasks by them)."""
    start = time.perf_counter()
    ctx = context(path, "shoot", generation, token)
    out = shooting.shoot_rows(ctx, patch_ids, row_cache(path, generation, token, ctx))
    return address(), out, time.perf_counter() - start


def row_cache(path: str, generation: int, token: str, ctx: shooting.ShootContext,
              budget: int | None = None) -> shooting.RowCache:
    """This process's form-factor rows of the shoot context ``ctx`` (named by ``path``,
    ``generation``, ``token``), made on first use with ``budget`` bytes (default: sized from
    this worker's memory). Only the current geometry's rows are kept. A client whose workers
    are threads of its process takes this very cache for its own (one cache, one budget for
    the whole process: :meth:`daskrad.distributed.dask_executor.DaskExecutor.set_geometry`)."""
    key = (path, generation, token)
    with _lock:
        rows = _rows.get(key)
        if rows is None:
            if budget is None:
                budget = shooting.row_cache_bytes(ctx, memory())
            rows = _rows[key] = shooting.RowCache(budget)
            while len(_rows) > 1:           # only the current geometry shoots
                _rows.popitem(last=False)
        return rows


def address() -> str | None:
    """This worker's address (None outside a Dask worker)."""
    try:
        from distributed import get_worker

        return get_worker().address
    except (ImportError, ValueError):
        return None


def memory() -> int:
    """Bytes this worker may use: its Dask memory limit, else the machine's memory."""
    try:
        from distributed import get_worker

        limit = get_worker().memory_manager.memory_limit
    except (ImportError, ValueError, AttributeError):
        limit = None
    return int(limit) if limit else physical_memory()


def forget_rows() -> None:
    """Drop this process's cached form-factor rows (a benchmark timing the form-factor work of
    repeated runs of one geometry calls it on every worker with ``client.run``)."""
    with _lock:
        _rows.clear()


def tile_task(path: str, generation: int, token: str, r0: int, r1: int, c0: int, c1: int
              ) -> tuple[np.ndarray, dict]:
    """Radiance of the pixels ``[r0, r1) × [c0, c1)`` and what the tile did
    (:func:`daskrad.render.render_tile_stats`)."""
    ctx = context(path, "render", generation, token)
    return render.render_tile_stats(ctx, slice(r0, r1), slice(c0, c1))


def direct_task(path: str, generation: int, token: str, start: int, stop: int) -> tuple:
    """Direct light at vertices ``[start, stop)`` (:func:`daskrad.direct.vertex_light`)."""
    from daskrad import direct

    return direct.vertex_light(context(path, "direct", generation, token), start, stop)


def gather_task(path: str, generation: int, token: str, start: int, stop: int
                ) -> render.GatherOperator:
    """The junction gather's operator rows of its vertices ``[start, stop)``
    (:func:`daskrad.render.gather_vertices`)."""
    return render.gather_vertices(context(path, "gather", generation, token), start, stop)


def probe(path: str, kind: str, token: str) -> str | None:
    """Run on every worker before the first task: None if the store is readable here,
    else why not (the client turns it into one clear error)."""
    try:
        load_context(path, kind, token)
    except Exception as err:  # noqa: BLE001 - any failure means "not usable from here"
        return f"{type(err).__name__}: {err}"
    return None


def state() -> dict:
    """This process's pid and cache statistics (tests and benchmarks call it via client.run)."""
    rows = next(iter(_rows.values()), None)
    usage = rows.usage() if rows else {"row_cache_mib": 0.0, "row_cache_limit_mib": 0.0}
    return {"pid": os.getpid(), "loads": loads, "cached": len(_cache),
            "row_hits": rows.hits if rows else 0, "row_misses": rows.misses if rows else 0,
            **usage, "peak_mib": peak_mib()}
