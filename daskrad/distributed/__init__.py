"""Where the pipeline's tasks run; the only layer that imports dask, distributed and zarr.

- :class:`~daskrad.distributed.executor.InProcess` (``--workers 0``): tasks run in this process.
- :func:`connect` (``--workers N`` or ``--scheduler ADDR``): a
  :class:`~daskrad.distributed.dask_executor.DaskExecutor` on a LocalCluster or an existing
  cluster, with the same interface: ``set_geometry``, ``shots``, ``tiles``, ``direct``,
  ``publish``, ``close`` and the attributes ``workers`` and ``dashboard_link``.
- :class:`~daskrad.distributed.store.Store`: the solution store ``OUT.zarr``.

Importing this package is cheap: dask and distributed load only when a cluster is used.
"""

from __future__ import annotations

import threading


def connect(settings, store=None):
    """A Dask executor for ``settings``: ``--scheduler`` if given, else a LocalCluster of
    ``settings.workers`` workers (threads of this process, or processes with ``--processes``).
    ``store`` (a :class:`Store`) is where task contexts go when workers need them there."""
    from daskrad.distributed.dask_executor import connect_scheduler, start_local

    if settings.scheduler:
        return connect_scheduler(settings, store)
    return start_local(settings, store)


def auto_workers(scene, settings) -> int:
    """``--workers`` not given: 0, in-process on a thread per core (docs/design.md §4).

    On one machine a cluster only adds its scheduler: the kernels release the GIL, so the
    in-process threads do what a LocalCluster's workers would (``bench_speed``'s workers
    table). A cluster is for more than one machine (``--scheduler``) or for watching the
    dashboard (``--workers N``). ``scene`` and ``settings`` are kept for a rule that depends
    on them."""
    return 0


def executor_for(settings, store=None):
    """Where the tasks of a run with ``settings`` run: this process (``workers`` 0 and no
    scheduler) or a Dask cluster (:func:`connect`)."""
    from daskrad.distributed.executor import InProcess

    if settings.workers == 0 and settings.scheduler is None:
        return InProcess()
    return connect(settings, store)


class Starting:
    """An executor being made by :func:`executor_for` while the caller does other work.

    A LocalCluster of threads (``--workers N``, the default kind) is started at once on a
    thread of its own: importing distributed and starting the scheduler, its dashboard and the
    workers takes ~0.8 s of a 2-core machine, which then overlaps loading and meshing the
    scene instead of preceding the direct pass. Anything else (in-process, worker processes
    that must start from the main thread so that they ignore Ctrl-C, an existing scheduler
    that must see the run's store) is made when :meth:`result` asks for it, as before.
    """

    def __init__(self, settings):
        self.settings = settings
        self._made = None
        self._error: BaseException | None = None
        self._thread = None
        if settings.workers and not settings.processes and settings.scheduler is None:
            self._thread = threading.Thread(target=self._make, name="daskrad-cluster-start",
                                            daemon=True)
            self._thread.start()

    def _make(self) -> None:
        try:
            self._made = connect(self.settings, None)
        except BaseException as err:  # noqa: BLE001 - raised again by result()
            self._error = err

    def result(self, settings, store=None):
        """The executor for ``settings`` (the run's, with ``--workers`` settled), its task
        contexts going to ``store``; raises what starting it raised."""
        if self._thread is None:
            return executor_for(settings, store)
        self._thread.join()
        if self._error is not None:
            raise self._error
        if store is not None:
            self._made.use_store(store)
        return self._made

    def cancel(self) -> None:
        """The run stops before it took the executor: close the cluster started for it."""
        if self._thread is not None:
            self._thread.join()
            if self._made is not None:
                self._made.close()
