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
    """This process's peak resident memory so far, MiB.

    ``VmHWM`` of ``/proc/self/status`` where there is one (Linux), else ``getrusage``'s
    ``ru_maxrss``. Not ``ru_maxrss`` first: Linux keeps it across ``execve``, so a worker
    started by spawn (fork, then exec) would report its parent's peak when that is higher —
    a ``--processes`` run's workers all showed the client's 827 MiB.
    """
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 2**10  # kB
    except (OSError, ValueError, IndexError):
        pass
    import resource
    import sys

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (2**20 if sys.platform == "darwin" else 2**10)
