"""Errors that mean "the user's input is wrong": the CLI prints them and exits with code 2."""
from __future__ import annotations

import errno as _errno


class InputError(ValueError):
    """Invalid input: a message for the user, no traceback."""


class UserModelWarning(UserWarning):
    """A model's own code raised at some points (status user_error): where and why, from a replay
    in plain Python (``mechsweep.model.diagnose``)."""


class StoreError(InputError):
    """A problem with the output file or an unfinished run (exists, locked, from another scene, unwritable)."""


class WriteFailed(StoreError):
    """Writing one of a run's files failed (disk full, file-size limit, quota, I/O error).

    ``path`` is the file, ``errno`` the system's error number; the runner turns it into a message
    that says how much space the run still needs and that the journal is kept."""

    def __init__(self, path, error: OSError):
        self.path = str(path)
        self.errno = error.errno
        self.strerror = error.strerror or str(error)
        super().__init__(f"{why_write_failed(error.errno, self.strerror)} while writing {self.path}")


def why_write_failed(code: int | None, strerror: str = "") -> str:
    """A short reason for a failed write, by errno."""
    if code == _errno.ENOSPC:
        return "disk full"
    if code == getattr(_errno, "EDQUOT", None):
        return "disk quota exceeded"
    if code == _errno.EFBIG:
        return "file size limit reached (ulimit -f)"
    if code == _errno.EIO:
        return "I/O error (EIO)"
    return f"write failed ({strerror or 'errno ' + str(code)})"


class ClusterLost(StoreError):
    """A distributed run lost its dask scheduler, or all its workers for longer than the worker
    timeout (exit code 2); the chunks already saved stay in the journal, and ``resume=True``
    (``--resume``), on the cluster or locally, completes the run."""
