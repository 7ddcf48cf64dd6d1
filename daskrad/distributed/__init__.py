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
