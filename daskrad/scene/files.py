"""Reading a scene's text files safely (issue 13): only regular files, of bounded size."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from daskrad.errors import SceneError


def read_text(path: Path, what: str, max_bytes: int | None = None,
              name: str | Path | None = None) -> str:
    """The text of ``path``: only a regular file (never a FIFO, a device such as ``/dev/zero``
    or a directory: reading those hangs or never ends), of at most ``max_bytes`` when given,
    not binary. Errors are :class:`SceneError` saying ``what`` the file is and naming
    ``name`` (default ``path``)."""
    name = path if name is None else name
    try:
        # stat before opening: opening a FIFO for reading blocks until a writer comes
        st = os.stat(path)
        if stat.S_ISDIR(st.st_mode):
            raise SceneError(f"{what} is a directory, not a file", name)
        if not stat.S_ISREG(st.st_mode):
            raise SceneError(f"{what} is not a regular file (a device, FIFO or socket)", name)
        if max_bytes is not None and st.st_size > max_bytes:
            raise SceneError(f"{what} is too large ({st.st_size:,} bytes; at most "
                             f"{max_bytes:,})", name)
        with open(path, "rb") as f:
            data = f.read() if max_bytes is None else f.read(max_bytes + 1)
    except FileNotFoundError:
        raise SceneError(f"{what} not found", name) from None
    except IsADirectoryError:
        raise SceneError(f"{what} is a directory, not a file", name) from None
    except OSError as err:
        raise SceneError(f"cannot read {what}: {err.strerror or err}", name) from None
    if max_bytes is not None and len(data) > max_bytes:  # grew while being read
        raise SceneError(f"{what} is too large (more than {max_bytes:,} bytes)", name)
    if b"\x00" in data[:4096]:
        raise SceneError(f"not a text {what} (binary data)", name)
    # the formats declare no encoding; names are the only non-ASCII content
    return data.decode("utf-8", errors="replace")
