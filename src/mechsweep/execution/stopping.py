"""A run that stops before its end: the signals that stop it (SIGINT and SIGTERM alike, acted on once
the chunk being saved is saved), and what it says then: what is kept, why a write failed and what
the run still needs, how to go on."""
from __future__ import annotations

import errno
import os
import signal
import threading
from contextlib import contextmanager
from pathlib import Path

from ..errors import StoreError, WriteFailed, why_os_error
from ..scene import Scene
from ..store.journal import Journal, drop, partial_path
from .checks import bytes_per_point, existing_ancestor, file_size_limit, mib

def interrupted(final: Path, signum: int) -> str:
    return f"interrupted ({signal.Signals(signum).name}): {what_is_kept(final)}"


def failed(exc: Exception, final: Path) -> None:
    """A run that failed with ``exc`` after its checks passed (under the lock): a journal with no
    chunk saved is removed (the next run starts afresh, nothing was written); otherwise what is
    kept and how to go on is added to the exception's notes (shown with its traceback)."""
    part = partial_path(final)
    try:
        journal = Journal.read(part) if part.is_dir() else None
        empty = journal is None or journal.empty or not journal.done_chunks().any()
    except (StoreError, OSError):
        return
    if empty:
        drop(final)
    else:
        exc.add_note(f"mechsweep: the run failed after its checks passed; {what_is_kept(final)}, or with --restart to "
                     "discard it")


def what_is_kept(final: Path) -> str:
    """What an unfinished run of ``final`` keeps, and how to go on."""
    part = partial_path(final)
    try:
        journal = Journal.read(part) if part.is_dir() else None
    except StoreError:
        journal = None
    if journal is None or journal.empty:
        return "no chunk was saved; run again"
    done = journal.done_chunks()
    return (f"journal kept ({int(done.sum())} of {done.size} chunks saved in {part}); "
            "run again with --resume to complete it")


def out_of_space(exc: WriteFailed, scene: Scene, final: Path, n_chunks: int) -> str:
    """The message of a failed write, by its cause: for a lack of room (no space, no inode, a quota,
    the file-size limit) how much the run still needs; for another cause (a folder removed or made
    read-only during the run, an I/O error) what happened; and what is kept, and how to go on."""
    from ..errors import why_write_failed

    code = exc.errno
    failed = f"writing {exc.path} failed"
    folder = final.parent
    if code == errno.ENOENT:
        return _removed_during_run(final, failed)
    if code not in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EFBIG):
        kept = what_is_kept(final)
        where = Path(exc.path).parent
        advice = {
            errno.EACCES: f"permission to write in {where} was taken away during the run: give it back; ",
            errno.EPERM: f"writing in {where} is no longer permitted: allow it again; ",
            errno.EROFS: f"the file system of {where} became read-only during the run (a system remounts a disk "
                         "so after errors: check it), make it writable; ",
            errno.EIO: f"the disk of {where} reported an error: check it (e.g. dmesg) before going on; ",
            errno.EISDIR: f"{exc.path} became a directory during the run: move it away; ",
            errno.ENOTDIR: f"a folder on the way to {exc.path} was replaced by a file during the run: put it back; ",
        }.get(code, "")
        reason = why_write_failed(code, exc.strerror) if code == errno.EIO else why_os_error(code, exc.strerror)
        return f"{reason}: {failed}; {advice}{kept}"
    part = partial_path(final)
    data = bytes_per_point(scene) * scene.n_points
    done = _done_chunks(part)
    if done is None:
        need, files = 2 * data, n_chunks + 1
    else:
        need = int(data * (1 - done.sum() / max(1, done.size)) + data)  # the chunks to come and the dataset
        files = int(done.size - done.sum()) + 1
    kept = what_is_kept(final)
    reason = why_write_failed(code, exc.strerror)
    soft = file_size_limit()
    free, inodes, total_inodes = _room(folder)
    short_of_inodes = total_inodes and inodes is not None and inodes < files + 1
    if code == errno.EFBIG and soft is not None:
        need_text = f"the limit is {mib(soft)}, the dataset needs up to {mib(data)}"
    elif code == errno.ENOSPC and short_of_inodes and (free is None or free >= need):
        # a file system that ran out of inodes (file entries) says ENOSPC too, with space to spare
        return (f"out of inodes (file entries), not of space: the file system of {_resolved(folder)} has {inodes} of "
                f"{total_inodes} inodes free (and {mib(free) if free is not None else 'enough'} of space); the run "
                f"still needs about {files} more files (one per chunk to come, and the dataset): delete files there "
                f"or write elsewhere with -o; {failed}; {kept}")
    elif code == errno.ENOSPC and short_of_inodes:
        need_text = (f"{mib(need)} and about {files} more files needed on the disk of {_resolved(folder)} (it is out "
                     f"of space and of inodes: {inodes} of {total_inodes} free)")
    elif code == getattr(errno, "EDQUOT", None):  # a quota counts blocks, and often files too
        need_text = f"{mib(need)} and about {files} more files needed within your quota on the disk of {_resolved(folder)}"
    else:
        need_text = f"{mib(need)} needed on the disk of {_resolved(folder)}"
    return f"{reason}: {need_text}; {failed}; {kept}"


def _removed_during_run(final: Path, failed: str) -> str:
    """The message of a write that found a file or folder of the run gone (ENOENT): which one
    was removed, and what that means for the chunks computed so far."""
    part = partial_path(final)
    gone = next((p for p in (final.parent, part, part / "chunks") if not os.path.isdir(p)), None)
    if gone == final.parent:
        what = (f"the output folder {final.parent} was removed during the run, and the run's journal with it "
                "(create the folder again before the next run)")
    elif gone is not None:
        what = f"the journal folder {gone} was removed during the run"
    else:
        return (f"a file of the run was removed while it was being written (ENOENT): {failed}; {what_is_kept(final)}")
    return f"{what} (ENOENT): {failed}; the chunks computed so far are lost: run again, from the start"


def _done_chunks(part: Path):
    """The done-chunk mask of the journal ``part``, or None (no journal, or one that cannot be read)."""
    try:
        journal = Journal.read(part) if part.is_dir() else None
        return None if journal is None or journal.empty else journal.done_chunks()
    except (StoreError, OSError):
        return None


def _room(folder: Path) -> tuple[int | None, int | None, int | None]:
    """(free bytes, free inodes, total inodes) of the file system of ``folder`` (or its nearest
    existing ancestor); None where it cannot be told (total inodes 0: a file system without a fixed
    number of them, e.g. btrfs)."""
    try:
        v = os.statvfs(existing_ancestor(folder))
    except OSError:
        return None, None, None
    return v.f_bavail * v.f_frsize, v.f_favail, v.f_files


def _resolved(folder: Path) -> Path:
    try:
        return folder.resolve()
    except OSError:
        return folder


class Signals:
    """SIGINT and SIGTERM stop a run the same way (KeyboardInterrupt, the journal kept; the
    signal is in ``signum``). Inside ``deferred()`` a signal is only noted (``pending()`` says
    so), and raised when the block ends, so files being written are closed first. SIGXFSZ is
    ignored, so that a write over the file-size limit fails with EFBIG instead of killing the
    process. Handlers are only installed from the main thread (Python allows no other), and never
    over a signal the process was started ignoring: a script's background job (``mechsweep run ... &``,
    which a non-interactive shell starts with SIGINT ignored) is not stopped by a Ctrl-C meant for the
    job in the foreground, as Python itself keeps such a SIGINT ignored."""

    def __init__(self):
        self.signum: int | None = None
        self._defer = 0
        self._previous = {}

    def __enter__(self) -> "Signals":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                if signal.getsignal(sig) is not signal.SIG_IGN:
                    self._previous[sig] = signal.signal(sig, self._handle)
            if hasattr(signal, "SIGXFSZ"):
                self._previous[signal.SIGXFSZ] = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler if handler is not None else signal.SIG_DFL)

    def _handle(self, signum, frame) -> None:
        self.signum = self.signum or signum
        if not self._defer:
            raise KeyboardInterrupt

    def pending(self) -> bool:
        return self.signum is not None

    @contextmanager
    def deferred(self):
        self._defer += 1
        try:
            yield
        finally:
            self._defer -= 1
        if self.signum is not None and not self._defer:
            raise KeyboardInterrupt
