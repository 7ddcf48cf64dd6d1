"""daskrad: progressive refinement radiosity with Doi's hemisphere-base form factors, on Dask.

The pipeline (docs/design.md §1) is load → mesh → direct → solve → render → write; see
:func:`daskrad.run.run` for the one-screen version.
"""

__version__ = "0.1.0"
