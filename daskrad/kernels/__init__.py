"""Pure numba kernels over NumPy arrays.

Nothing here imports the rest of the project (an import-linter contract enforces it): each
kernel is a plain function over arrays, tested alone, and called by thin in-process and Dask
wrappers elsewhere so both paths share one implementation.
"""

from daskrad.kernels._jit import (
    LEAF_REFCOUNTS,
    REFERENCE_ARMS,
    is_leaf,
    jit,
    jit_leaf,
    leaf_faults,
)

__all__ = ["LEAF_REFCOUNTS", "REFERENCE_ARMS", "is_leaf", "leaf_faults", "jit", "jit_leaf"]
