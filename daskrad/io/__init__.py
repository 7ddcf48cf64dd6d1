"""Step 5, output: the HDR image, its preview and the run report (docs/design.md §7).

The solution store (Zarr) is written by :mod:`daskrad.distributed.store`, the only layer that
imports zarr.
"""

from daskrad.io.image import read_exr, tonemap, write_exr, write_png
from daskrad.io.report import write_report

__all__ = ["read_exr", "tonemap", "write_exr", "write_png", "write_report"]
