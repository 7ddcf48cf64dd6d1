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
    ``settings.workers`` processes. ``store`` (a :class:`Store`) is where task contexts go."""
    from daskrad.distributed.dask_executor import connect_scheduler, start_local

    if settings.scheduler:
        return connect_scheduler(settings, store)
    return start_local(settings, store)


#: Without --workers, a scene of fewer elements (estimated) runs in-process: starting a
#: LocalCluster costs 2–3 s, more than 2 workers save on the default Cornell box (~6 s).
AUTO_CLUSTER_ELEMENTS = 20_000


def auto_workers(scene, settings) -> int:
    """``--workers`` not given: 2 local workers, or 0 for a small scene (docs/design.md §4)."""
    from daskrad.preprocess import estimated_elements

    return 0 if estimated_elements(scene, settings) < AUTO_CLUSTER_ELEMENTS else 2


def executor_for(settings, store=None):
    """Where the tasks of a run with ``settings`` run: this process (``workers`` 0 and no
    scheduler) or a Dask cluster (:func:`connect`)."""
    from daskrad.distributed.executor import InProcess

    if settings.workers == 0 and settings.scheduler is None:
        return InProcess()
    return connect(settings, store)
