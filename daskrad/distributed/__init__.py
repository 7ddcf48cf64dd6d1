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
