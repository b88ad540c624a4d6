"""mechsweep's exceptions, in one tree, so that a caller (and the command line) can tell bad input
from a run that failed::

    MechsweepError
    +-- InputError (also a ValueError)   the input is wrong; nothing was computed or written   exit 2
    |   +-- SceneError                   a scene that does not load (scene/)
    |   +-- StoreError                   an output path, dataset or journal that cannot be used as asked
    |       +-- FileBusy                 a file another process holds open for writing
    |       +-- BadChunk                 a damaged chunk file of a journal (store/journal.py)
    +-- RunError (also a RuntimeError)   a run that passed its checks failed; saved chunks are kept
        +-- WriteFailed                  a write failed (errno and path; the runner says it as OutOfSpace)
        +-- OutOfSpace                   a run's write failed (disk full, quota, ulimit -f, I/O error)  exit 2
        +-- ClusterLost                  the dask scheduler, or every worker, was lost                  exit 2
        +-- RunInterrupted               Ctrl-C or SIGTERM                                  exit 128 + signal

``mechsweep`` re-exports the public names (``mechsweep.InputError``, ``mechsweep.RunError``, ...). A
run failure is not an InputError: ``except ValueError`` (or ``InputError``, ``StoreError``) does
not catch a full disk or a lost cluster, ``except RunError`` does.
"""
from __future__ import annotations

import errno as _errno
import signal as _signal
import stat as _stat
from pathlib import Path


class MechsweepError(Exception):
    """Every error mechsweep raises on purpose: the message is for the user, no traceback needed."""


class InputError(MechsweepError, ValueError):
    """Invalid input: a message for the user, no traceback; nothing was computed or written."""


class RunError(MechsweepError, RuntimeError):
    """A run that passed its checks failed on the way (a write, the cluster, a signal); the chunks it
    saved are kept in its journal, and the message says how to go on (``--resume``)."""


class UserModelWarning(UserWarning):
    """A model's own code raised at some points (status user_error): where and why, from a replay
    in plain Python (``mechsweep.model.diagnose``)."""


class SettingsWarning(UserWarning):
    """A scene's solver settings are accepted but suspicious (scene.solver_warnings says why)."""


class StoreError(InputError):
    """A problem with the output file or an unfinished run (exists, locked, from another scene, unwritable)."""


class WriteFailed(RunError):
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
    return f"write failed ({why_os_error(code, strerror)})"


# errno -> what it means for a file a command reads or writes (the system's own text is terser)
_REASONS = {
    "ENOENT": "no such file or folder",
    "EACCES": "permission denied",
    "EPERM": "operation not permitted",
    "EROFS": "read-only file system",
    "EISDIR": "it is a directory",
    "ENOTDIR": "a part of the path is not a folder",
    "ELOOP": "a symbolic link loop",
    "EMFILE": "too many open files in this process",
    "ENFILE": "too many open files in the system",
    "EAGAIN": "held (locked) by another process",
    "ENXIO": "no such device or address (a socket or a device without a reader)",
    "EXDEV": "the paths are on different file systems",
    "ENOSPC": "no space left on the device",
    "EDQUOT": "disk quota exceeded",
    "EFBIG": "file too large (file size limit, ulimit -f)",
    "EIO": "I/O error (EIO)",
}


def file_kind(mode: int) -> str:
    """What a file system entry of this st_mode (of stat, or of lstat) is, for a message."""
    for test, name in ((_stat.S_ISLNK, "a symbolic link"), (_stat.S_ISDIR, "a directory"),
                       (_stat.S_ISCHR, "a character device"), (_stat.S_ISBLK, "a block device"),
                       (_stat.S_ISFIFO, "a named pipe (FIFO)"), (_stat.S_ISSOCK, "a socket"),
                       (_stat.S_ISREG, "a regular file")):
        if test(mode):
            return name
    return "not a regular file"


def why_os_error(code: int | None, strerror: str = "") -> str:
    """What an OSError of errno ``code`` means, in a few words naming the cause."""
    name = _errno.errorcode.get(code or 0, "")
    if code is not None and code == getattr(_errno, "EWOULDBLOCK", None):
        name = "EAGAIN"
    reason = _REASONS.get(name) or strerror
    if reason and name:
        return f"{reason} ({name})"
    return reason or (f"errno {code}" if code is not None else "unknown error")


class FileBusy(StoreError):
    """A file another process holds open for writing (an HDF5 file lock): reading it now would
    fail or see it half written, and replacing it would lose that process's writes."""

    def __init__(self, path, holder: int | None = None, doing: str = ""):
        self.path = str(path)
        self.holder = holder
        who = f"process {holder}" if holder else "another process"
        super().__init__(f"{path} is held open for writing by {who} (its HDF5 file lock); "
                         + (doing or "wait until that process closes it (or stop it), then try again"))


class OutOfSpace(RunError):
    """A write of the run failed (disk full, file-size limit, quota, I/O error); the journal of
    finished chunks is kept, so the run can be completed with --resume once there is room."""


class ClusterLost(RunError):
    """A distributed run lost its dask scheduler, or all its workers for longer than the worker
    timeout (exit code 2); the chunks already saved stay in the journal, and ``resume=True``
    (``--resume``), on the cluster or locally, completes the run."""


class RunInterrupted(RunError):
    """The run stopped (Ctrl-C, SIGTERM) after saving every finished chunk (exit code 130).

    Resume it with ``mechsweep.run(..., resume=True)`` (``--resume``). ``signum`` is the signal that
    stopped it (SIGINT for Ctrl-C)."""

    def __init__(self, message: str, signum: int = _signal.SIGINT):
        super().__init__(message)
        self.signum = signum


# ----------------------------------------------------------------------------- an OSError in one line
# errnos with which the system refuses a read or write (not a fault in a file's bytes)
SYSTEM_ERRNOS = frozenset(getattr(_errno, n) for n in (
    "ENOENT", "EACCES", "EPERM", "EROFS", "EISDIR", "ENOTDIR", "ELOOP", "ENOSPC", "EDQUOT", "EFBIG", "EMFILE",
    "ENFILE", "ENAMETOOLONG", "EXDEV", "EAGAIN") if hasattr(_errno, n))


# what to do about a refused write, by errno ({folder}: the file's folder)
_WRITE_ADVICE = {
    "ENOENT": "the folder {folder} does not exist (or was removed); create it (mkdir -p {folder}) or give another "
              "path with -o",
    "EACCES": "give another path with -o, or make {folder} writable",
    "EPERM": "give another path with -o",
    "EROFS": "its file system is mounted read-only; give a path elsewhere with -o",
    "ENOSPC": "its disk is full (of space, or of inodes); free some or give a path elsewhere with -o",
    "EDQUOT": "your disk quota there is used up; free some or give a path elsewhere with -o",
    "EFBIG": "it would exceed the file size limit (ulimit -f); raise it or draw fewer or smaller figures",
    "EISDIR": "a directory has that name; give a figure file name with -o",
    "ENOTDIR": "a part of the path is a file, not a folder; give another path with -o",
    "ENAMETOOLONG": "give a shorter path with -o",
}


def _why(exc: OSError) -> str:
    return why_os_error(exc.errno, exc.strerror or str(exc))


def os_error_text(exc: OSError, path=None, writing: str = "") -> str:
    """One line for an OSError: the file it names (else ``path``), its cause by errno, and, for a
    write (``writing``: what was being written), what to do."""
    name = exc.filename if exc.filename is not None else path
    where = f"{name}: " if name is not None else ""
    if not writing:
        return f"{where}{_why(exc)}"
    code = _errno.errorcode.get(exc.errno or 0, "")
    folder = Path(str(name)).parent if name is not None else Path(".")
    advice = _WRITE_ADVICE.get(code, "give another path with -o").format(folder=folder)
    return f"cannot write {writing} {name}: {_why(exc)}; {advice}"
