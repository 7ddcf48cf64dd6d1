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


#: Seconds :func:`check_scheduler` waits for a TCP connection before leaving the question to
#: Dask's own connect (which waits ``connect_timeout``).
PROBE_SECONDS = 5.0


def check_scheduler(settings) -> None:
    """Refuse a ``--scheduler`` nothing listens on, at once and before any work: a refused
    connection or an unknown host raises :class:`~daskrad.errors.OptionError` (Dask's connect
    would retry it for ``connect_timeout`` seconds, after the scene was loaded and meshed).
    A host that does not answer within :data:`PROBE_SECONDS` is left to Dask. Only ``tcp://``
    addresses are probed; a plain socket, no dask import."""
    address = settings.scheduler
    if not address or not address.startswith("tcp://"):
        return
    import socket

    from daskrad.errors import OptionError

    host, _, port = address[len("tcp://"):].rpartition(":")
    try:
        with socket.create_connection((host.strip("[]"), int(port)),
                                      timeout=min(PROBE_SECONDS, settings.connect_timeout)):
            return
    except TimeoutError:
        return
    except OSError as err:
        reason = err.strerror or type(err).__name__
        raise OptionError(f"cannot reach the Dask scheduler {address}: {reason.lower()}") \
            from None


def auto_workers(scene, settings) -> int:
    """``--workers`` not given: 0, in-process on a thread per core (docs/design.md §4).

    On one machine a cluster only adds its scheduler: the kernels release the GIL, so the
    in-process threads do what a LocalCluster's workers would (``bench_speed``'s workers
    table). A cluster is for more than one machine (``--scheduler``) or for watching the
    dashboard (``--workers N``). ``scene`` and ``settings`` are kept for a rule that depends
    on them."""
    return 0


class Early:
    """A LocalCluster of threads started on a thread of its own (:func:`start_early`), so that
    its start (~0.5 s: the scheduler, the workers, their event loop) overlaps the loading and
    meshing of the scene, which use one core. :meth:`get` waits for it; :meth:`close` closes
    it when the run ends before taking it (a bad scene, Ctrl-C)."""

    def __init__(self, settings):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(1, thread_name_prefix="daskrad-cluster")
        self._future = self._pool.submit(connect, settings, None)
        self._pool.shutdown(wait=False)     # the one task runs on; the thread ends with it

    def get(self):
        """The executor (:func:`connect`'s); its errors are raised here."""
        return self._future.result()

    def close(self) -> None:
        """Close the cluster once it has started. The run is ending on an error of its own,
        the one to report: a cluster that failed to start, or fails to close, adds none (a
        Ctrl-C while waiting for it still interrupts)."""
        try:
            ex = self._future.result()
        except Exception:  # noqa: BLE001 - it did not start: nothing to close
            return
        try:
            ex.close()
        except Exception:  # noqa: BLE001, S110 - see above
            pass


def start_early(settings) -> Early | None:
    """Start ``--workers N``'s LocalCluster of threads now, in the background (:class:`Early`),
    or None: in-process runs need none, ``--scheduler`` is connected to once the scene is
    known good, and worker processes start from the main thread (they must inherit its
    ignored SIGINT, :func:`daskrad.distributed.dask_executor.start_local`)."""
    if settings.workers and settings.scheduler is None and not settings.processes:
        from daskrad.distributed.dask_executor import quiet_dask

        quiet_dask()            # from this thread, before the cluster's thread starts
        return Early(settings)
    return None


def executor_for(settings, store=None):
    """Where the tasks of a run with ``settings`` run: this process (``workers`` 0 and no
    scheduler) or a Dask cluster (:func:`connect`)."""
    from daskrad.distributed.executor import InProcess

    if settings.workers == 0 and settings.scheduler is None:
        return InProcess()
    return connect(settings, store)
