"""Pure numba kernels over NumPy arrays.

Nothing here imports the rest of the project (an import-linter contract enforces it): each
kernel is a plain function over arrays, tested alone, and called by thin in-process and Dask
wrappers elsewhere so both paths share one implementation.
"""
