"""User errors: the ones a user can cause and fix (docs/design.md §7).

The CLI turns a :class:`DaskradError` into one line on stderr and exit code 2, never a traceback.
"""

from __future__ import annotations

from pathlib import Path


class DaskradError(Exception):
    """An error caused by the user's input: names the file (if any) and the problem."""

    def __init__(self, message: str, path: str | Path | None = None):
        self.path = None if path is None else str(path)
        self.message = message
        super().__init__(self.line())

    def line(self) -> str:
        """The one line printed on stderr."""
        return f"{self.path}: {self.message}" if self.path else self.message


class SceneError(DaskradError):
    """The scene file (mesh, MTL or TOML) is missing, malformed or physically impossible."""


class OptionError(DaskradError):
    """A command-line option has a bad value."""


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, with the line the CLI prints about what is left to resume from."""

    def __init__(self, message: str):
        self.message = message
        super().__init__(message)


class DaskradWarning(UserWarning):
    """Something daskrad changed in the user's input or could not do as asked; the run goes on.

    The CLI prints each as one line, ``daskrad: warning: <message>``, without Python's source
    line; a :class:`daskrad.scene.Scene` keeps the warnings of its loading in ``warnings``.
    """


class StoreError(OptionError):
    """The solution store given (``--resume``, ``daskrad render``, ``daskrad export``) is
    missing, damaged, unfinished or was written from other inputs or settings."""
