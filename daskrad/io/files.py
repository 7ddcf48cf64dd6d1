"""Checks on where output goes, made before anything is loaded or written."""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from daskrad.errors import OptionError


def check_directory(directory: str | Path, what: str = "output") -> None:
    """:class:`OptionError` naming ``directory`` unless a file can be made in it.

    ``os.access`` is not enough: it answers yes to root for ``/proc`` or a read-only mount,
    and the first write (the run's lock, a hidden ``.partial`` file) would then fail naming a
    file the user never gave. So a file is made and removed (a hidden name of
    ``tempfile``'s, made here, so removing it removes nothing of anyone else's)."""
    directory = Path(directory)
    if not directory.is_dir():
        why = "not a directory" if directory.exists() else "no such directory"
        raise OptionError(f"{why} for the {what}: {directory}")
    try:
        fd, probe = tempfile.mkstemp(prefix=".daskrad-", suffix=".probe", dir=directory)
    except OSError as err:
        raise OptionError(f"cannot write in this directory ({err.strerror or err})",
                          directory) from None
    # made and written: the directory takes files; the probe's own removal cannot fail it
    with contextlib.suppress(OSError):
        os.close(fd)
    with contextlib.suppress(OSError):
        os.unlink(probe)
