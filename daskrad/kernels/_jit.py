"""The numba decorators every kernel uses.

``nogil`` lets Dask worker threads run kernels concurrently; ``cache`` keeps the compiled code
on disk so a fresh worker process loads it in tens of milliseconds instead of compiling again
(docs/stack.md: 0.8–1.8 s per raster kernel on first compile).

**Leaves.** numba counts references to every array a compiled function binds: each argument
(each array of a tuple argument such as :class:`daskrad.kernels.grid.Grid`) is incremented on
entry and decremented on every exit, with an atomic instruction each time, and its pruning
pass leaves most of those pairs in place in functions with several exits. A shadow ray went
through four such frames (``_unblocked``, ``any_hit_cached``, ``_walk``, ``_intersect``) with
two six-array tuples: perf put 35 % of the classroom's per-pixel pass in ``NRT_incref`` and
``NRT_decref`` alone. A kernel that allocates nothing and returns no array needs none of it,
so it is compiled with ``_nrt=False`` (:data:`jit_leaf`), where numba emits no reference
counts at all. The contract, held by ``tests/test_jit.py`` and checked by
:func:`daskrad.warmup.warmup` on every kernel it compiles (:func:`array_returns`):

- a leaf allocates nothing (numba refuses to compile one that does: "NRT required");
- a leaf returns no array, nor a tuple holding one: the caller would count a reference it was
  never given, and free the array under its owner (seen as heap corruption);
- a leaf calls only leaves (and numba's own functions): an array a counted kernel returned to
  it would never be freed.

Its arrays are borrowed from a counted caller that holds them for the whole call, so nothing
a leaf reads is freed under it. ``DASKRAD_LEAF_REFCOUNTS=1`` compiles the leaves as counted
kernels, for ``benchmarks/bench_leaves.py`` to compare the two; it takes effect only in a
numba cache of its own (``NUMBA_CACHE_DIR``), as the cache's index does not tell them apart.
"""

import os

from numba import njit
from numba.core import types

jit = njit(nogil=True, cache=True)
"""Decorator for kernels: ``@jit``."""

jit_parallel = njit(nogil=True, cache=True, parallel=True)
"""Decorator for kernels that use ``numba.prange``; only for in-process hot loops."""

#: Whether the leaves are compiled with numba's reference counts (``DASKRAD_LEAF_REFCOUNTS=1``,
#: for the benchmark that compares the two).
LEAF_REFCOUNTS = os.environ.get("DASKRAD_LEAF_REFCOUNTS", "") == "1"

_leaf_compile = jit if LEAF_REFCOUNTS else njit(nogil=True, cache=True, _nrt=False)


def jit_leaf(fn):
    """Decorator for kernels that allocate nothing, return no array and call only leaves:
    ``@jit_leaf`` (compiled without reference counts; see the module's notes)."""
    dispatcher = _leaf_compile(fn)
    dispatcher._daskrad_leaf = True
    return dispatcher


def is_leaf(dispatcher) -> bool:
    """Whether ``dispatcher`` was made by :data:`jit_leaf` (in either of its compilations)."""
    return getattr(dispatcher, "_daskrad_leaf", False)


def _holds_array(t) -> bool:
    if isinstance(t, types.Array):
        return True
    if isinstance(t, types.BaseTuple):
        return any(_holds_array(x) for x in t.types)
    return False


def array_returns(dispatcher) -> list[str]:
    """The compiled signatures of ``dispatcher`` whose result is or holds an array (a leaf
    must have none): ``["(args) -> result", ...]``."""
    return [f"{sig} -> {cres.signature.return_type}"
            for sig, cres in dispatcher.overloads.items()
            if _holds_array(cres.signature.return_type)]

