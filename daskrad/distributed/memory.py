"""Memory of this process: what it may use and what it has used (the row cache is sized from
the first, the run report shows the second)."""

from __future__ import annotations

import os

#: Where a container's memory limit is (cgroup v2, then v1).
CGROUP_LIMITS = ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes")


def physical_memory() -> int:
    """Bytes this process's machine lets it use: the physical memory, or the container's
    limit when smaller (8 GiB where neither can be read)."""
    try:
        total = int(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        total = 8 * 2**30
    for path in CGROUP_LIMITS:
        try:
            with open(path) as f:
                text = f.read().strip()
        except OSError:
            continue
        if text.isdigit() and 0 < int(text) < total:
            total = int(text)
        break
    return total


def peak_mib() -> float:
    """This process's peak resident memory so far, MiB (``getrusage``; Linux counts KiB)."""
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 2**10)
