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
    """Ctrl-C (or SIGTERM: ``terminated``), with the line the CLI prints about what is left
    to resume from."""

    def __init__(self, message: str, terminated: bool = False):
        self.message = message
        self.terminated = terminated
        super().__init__(message)


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, a batch system's stop, a container's shutdown) while a command runs:
    it stops the command as Ctrl-C does (the last checkpoint kept, the lock released, one
    line), and the CLI exits with 143 (128 + 15) where Ctrl-C exits with 130."""


class DaskradWarning(UserWarning):
    """Something daskrad changed in the user's input or could not do as asked; the run goes on.

    The CLI prints each as one line, ``daskrad: warning: <message>``, without Python's source
    line; a :class:`daskrad.scene.Scene` keeps the warnings of its loading in ``warnings``.
    """


class StoreError(OptionError):
    """The solution store given (``--resume``, ``daskrad render``, ``daskrad export``) is
    missing, damaged, unfinished or was written from other inputs or settings."""


def interrupted(err: BaseException | None) -> KeyboardInterrupt | None:
    """The Ctrl-C (or SIGTERM, :class:`daskrad.errors.Terminated`) ``err`` comes from, None if
    it comes from none (inside a numba kernel it surfaces as a SystemError chained to the
    KeyboardInterrupt)."""
    while err is not None and not isinstance(err, KeyboardInterrupt):
        err = err.__cause__ or err.__context__
    return err
