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
so it is compiled with ``_nrt=False`` (:func:`jit_leaf`), where numba emits no reference
counts at all. The contract:

- a leaf allocates nothing (numba refuses to compile one that does: "NRT required");
- a leaf returns nothing that holds an array (an array, a tuple or an optional of one): the
  caller would count a reference it was never given, and free the array under its owner
  (seen as heap corruption);
- a leaf calls only leaves (and numba's own functions): an array a counted kernel returned to
  it would never be freed. Counted kernels say ``_nrt=True`` outright: numba otherwise takes
  a callee's setting from the caller that first compiles it, and a counted kernel compiled
  under a leaf would come out uncounted for every caller (the cache's key has no flags).

:func:`daskrad.warmup.leaf_violations` checks it: every leaf's calls, read from its Python
code, and for a leaf compiled in the process its result type and the absence of any call to a
reference count in its LLVM IR (:func:`leaf_faults`). ``daskrad warmup`` runs it after
compiling every kernel, which it does into an empty cache whenever the kernels changed since
the cache was filled (``make install`` in a fresh clone, CI's included). A leaf's arrays are
borrowed from a counted caller that holds them for the whole call, so nothing a leaf reads is
freed under it.

``DASKRAD_LEAF_REFCOUNTS=1`` compiles the leaves as counted kernels, for
``benchmarks/bench_leaves.py`` to compare the two; it needs a numba cache of its own
(``NUMBA_CACHE_DIR``, else it is refused), as the cache's index does not tell them apart
(:func:`reference_arm`).
"""

import os

from numba import njit

jit = njit(nogil=True, cache=True, _nrt=True)
"""Decorator for kernels: ``@jit``."""

jit_parallel = njit(nogil=True, cache=True, parallel=True, _nrt=True)
"""Decorator for kernels that use ``numba.prange``; only for in-process hot loops."""


def reference_arm(name: str) -> bool:
    """Whether the environment variable ``name`` is ``1``: the kernels are compiled as the
    reference arm of a benchmark (the code a change replaced). The setting is baked into the
    compiled code and numba's cache index does not tell the two apart, so the arm needs a
    cache of its own (``NUMBA_CACHE_DIR``, else it is refused); ``daskrad warmup`` records
    the arms its cache was compiled with (:data:`REFERENCE_ARMS`)."""
    on = os.environ.get(name, "") == "1"
    if on and not os.environ.get("NUMBA_CACHE_DIR"):
        raise RuntimeError(f"{name}=1 needs a numba cache of its own: set NUMBA_CACHE_DIR too")
    return on


#: Whether the leaves are compiled with numba's reference counts (``DASKRAD_LEAF_REFCOUNTS=1``,
#: for the benchmark that compares the two).
LEAF_REFCOUNTS = reference_arm("DASKRAD_LEAF_REFCOUNTS")

#: Whether the grid's walk remembers only the last four triangles a ray tested, in registers,
#: as before the fans' marks (``DASKRAD_WALK_REGISTERS=1``;
#: :data:`daskrad.kernels.grid.WALK_MARKS`).
WALK_REGISTERS = reference_arm("DASKRAD_WALK_REGISTERS")

#: The reference arms in force (their names as :func:`reference_arm` reads them).
REFERENCE_ARMS = {"leaf_refcounts": LEAF_REFCOUNTS, "walk_registers": WALK_REGISTERS}

_leaf_compile = jit if LEAF_REFCOUNTS else njit(nogil=True, cache=True, _nrt=False)


def jit_leaf(fn):
    """Decorator for kernels that allocate nothing, return no array and call only leaves:
    ``@jit_leaf`` (compiled without reference counts; see the module's notes)."""
    dispatcher = _leaf_compile(fn)
    dispatcher._daskrad_leaf = True
    return dispatcher


def is_leaf(dispatcher) -> bool:
    """Whether ``dispatcher`` was made by :func:`jit_leaf` (in either of its compilations)."""
    return getattr(dispatcher, "_daskrad_leaf", False)


def leaf_faults(dispatcher) -> list[str]:
    """What breaks a leaf's contract in the signatures of ``dispatcher`` known to this process:
    a result that holds an array, and, for a signature compiled here (the LLVM IR of one
    loaded from numba's cache cannot be read), a call to a reference count in its IR.
    ``["(args) -> result: what", ...]``."""
    out = []
    for sig, cres in dispatcher.overloads.items():
        rt = cres.signature.return_type
        where = f"{sig} -> {rt}"
        if cres.target_context.data_model_manager[rt].contains_nrt_meminfo():
            out.append(f"{where}: its result holds an array")
        # compiled here, not loaded from the cache; and the leaves compiled as leaves
        if not (LEAF_REFCOUNTS or getattr(cres.library, "_disable_inspection", True)):
            ir = cres.library.get_llvm_str()
            if "call void @NRT_incref" in ir or "call void @NRT_decref" in ir:
                out.append(f"{where}: counts references")
    return out
