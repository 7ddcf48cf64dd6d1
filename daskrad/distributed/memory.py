"""Memory of this process: what it may use and what it has used (the row cache is sized from
the first, the run report shows the second)."""

from __future__ import annotations

import os


def physical_memory() -> int:
    """The machine's physical memory in bytes (8 GiB where it cannot be read)."""
    try:
        return int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return 8 * 2**30


def peak_mib() -> float:
    """This process's peak resident memory so far, MiB (``getrusage``; Linux counts KiB)."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 2**10)
