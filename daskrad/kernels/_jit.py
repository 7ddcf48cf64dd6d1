"""The one numba decorator every kernel uses.

``nogil`` lets Dask worker threads run kernels concurrently; ``cache`` keeps the compiled code
on disk so a fresh worker process loads it in tens of milliseconds instead of compiling again
(docs/stack.md: 0.8–1.8 s per raster kernel on first compile).
"""

from numba import njit

jit = njit(nogil=True, cache=True)
"""Decorator for kernels: ``@jit``."""

jit_parallel = njit(nogil=True, cache=True, parallel=True)
"""Decorator for kernels that use ``numba.prange``; only for in-process hot loops."""
