"""Crash-safe progress of a run: a lock against a second writer, and a journal of finished chunks.

A run of output ``PATH`` keeps its finished chunks in the folder ``PATH.partial/``:

- ``run.json``: the scene (canonical form and text), the number of chunks and the provenance,
  written before any chunk;
- ``chunks/NNNNNNN.npz``: one file per finished chunk (its outputs, status, step counts and the
  wall time it took), written to a temporary name, synced and renamed into place.

A rename is atomic, so at any moment (a SIGKILL, a power cut after the sync) every chunk file is
either complete or absent, and a resumed run computes exactly the chunks that have no file. The
HDF5 dataset is assembled from the journal only when every chunk is in, into a temporary file in
the journal folder that replaces ``PATH`` by one rename; the journal is then dropped. An HDF5 file
is never written in place while a run is under way: a kill in the middle of an HDF5 write can leave
a file the library cannot open again, a chunk file cannot.

The lock is ``.PATH.lock`` beside the output, held with ``flock`` for the whole run (the kernel
releases it when the process dies, however it dies), so a second run on the same output is refused
at once instead of interleaving its writes.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import shutil
from pathlib import Path

import numpy as np

from .errors import StoreError

FORMAT = 1
_CHUNK_NAME = re.compile(r"^(\d{7,})\.npz$")


def partial_path(path: str | os.PathLike) -> Path:
    return Path(str(path) + ".partial")


def lock_path(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_name("." + p.name + ".lock")


def discard_path(path: str | os.PathLike) -> Path:
    """Where a journal goes to be deleted (a kill during the deletion leaves it there)."""
    return Path(str(path) + ".partial.discard")


# ----------------------------------------------------------------------------- lock
class RunLock:
    """Exclusive right to write output ``path`` (and its journal), held until ``release``.

    The lock file is removed on release; a process that opened it just before and locks the
    removed file notices (the inode on disk differs) and tries again, so two runs never both
    believe they hold it.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = lock_path(path)
        self.output = Path(path)
        self.fd: int | None = None

    def acquire(self) -> "RunLock":
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError as exc:
                try:
                    if exc.errno in (errno.EWOULDBLOCK, errno.EACCES):
                        self._refuse(fd)
                    raise StoreError(f"cannot lock {self.path}: {exc.strerror}") from None
                finally:
                    os.close(fd)
            try:
                same = os.fstat(fd).st_ino == os.stat(self.path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                os.ftruncate(fd, 0)
                os.write(fd, str(os.getpid()).encode())
                self.fd = fd
                return self
            os.close(fd)  # the holder removed it while we waited: lock the new one

    def refuse_if_held(self) -> None:
        """Raise if another run holds the lock now; unlike ``acquire`` this creates no file."""
        try:
            fd = os.open(self.path, os.O_RDONLY)
        except FileNotFoundError:
            return
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            self._refuse(fd)
        finally:
            os.close(fd)

    def _refuse(self, fd: int):
        holder = _read_pid(fd)
        who = f" (process {holder})" if holder else ""
        raise StoreError(f"{self.output} is being written by another mechsweep run{who}; "
                         "wait for it to finish or stop it first") from None

    def release(self) -> None:
        if self.fd is not None:
            self.path.unlink(missing_ok=True)  # before closing: nobody can lock the old inode in between
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> "RunLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _read_pid(fd: int) -> str:
    try:
        return os.pread(fd, 32, 0).decode(errors="replace").strip()
    except OSError:
        return ""


# ----------------------------------------------------------------------------- journal
class Journal:
    """The ``PATH.partial/`` folder of one run. Open it with ``create`` or ``reopen`` while
    holding the run's ``RunLock``."""

    def __init__(self, folder: Path, meta: dict):
        self.folder = folder
        self.meta = meta
        self.chunks = folder / "chunks"

    # -- creation and reopening ----------------------------------------------------
    @classmethod
    def create(cls, folder: Path, *, canonical: str, text: str, chunk_target: int, n_chunks: int,
               attrs: dict) -> "Journal":
        meta = {"format": FORMAT, "scene_canonical": canonical, "scene": text, "chunk_target": chunk_target,
                "n_chunks": n_chunks, "attrs": attrs}
        folder.mkdir()
        try:
            (folder / "chunks").mkdir()
            _write_atomic(folder / "run.json", json.dumps(meta, indent=1).encode())
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        return cls(folder, meta)

    @classmethod
    def read(cls, folder: Path) -> "Journal":
        """Open an existing journal (no checks against a scene)."""
        if folder.is_file():
            raise StoreError(f"{folder} is an unfinished run of an older mechsweep version (one HDF5 file); "
                               "it cannot be resumed: start over with --restart")
        try:
            meta = json.loads((folder / "run.json").read_text())
        except FileNotFoundError:
            meta = None  # killed between creating the folder and writing run.json: nothing saved
        except (OSError, ValueError) as exc:
            raise StoreError(f"{folder / 'run.json'} is unreadable ({exc}); start over with --restart") from None
        if meta is not None and meta.get("format") != FORMAT:
            raise StoreError(f"{folder} was written by another mechsweep version (journal format "
                               f"{meta.get('format')}, this one reads {FORMAT}); start over with --restart")
        return cls(folder, meta)

    def matches(self, canonical: str, chunk_target: int, n_chunks: int) -> str | None:
        """Why this journal cannot be resumed by a run of ``canonical`` cut into chunks of
        ``chunk_target`` points (``n_chunks`` of them), or None."""
        if self.meta["scene_canonical"] != canonical:
            return (f"{self.folder} was started from a different scene (model, outputs, axes, fixed values or "
                    "solver settings differ); resume it with the scene it was started with, or start over "
                    "with --restart")
        if (self.meta["chunk_target"], self.meta["n_chunks"]) != (chunk_target, n_chunks):
            return (f"{self.folder} was cut into {self.meta['n_chunks']} chunks of up to "
                    f"{self.meta['chunk_target']} points, this run into {n_chunks} of up to {chunk_target}; "
                    "use the same storage.chunk_size, or --restart")
        return None

    @property
    def empty(self) -> bool:
        return self.meta is None

    # -- chunks ----------------------------------------------------------------------
    def chunk_file(self, index: int) -> Path:
        return self.chunks / f"{index:07d}.npz"

    def done_chunks(self) -> np.ndarray:
        """Boolean per chunk: its file is in the journal. Leftover temporary files are removed."""
        done = np.zeros(self.meta["n_chunks"], dtype=bool)
        for entry in os.scandir(self.chunks):
            m = _CHUNK_NAME.match(entry.name)
            if m and int(m.group(1)) < done.size:
                done[int(m.group(1))] = True
            elif entry.name.endswith(".tmp"):
                os.unlink(entry.path)  # a write that a kill interrupted
        return done

    def write_chunk(self, index: int, arrays: dict[str, np.ndarray], wall_time_s: float) -> None:
        """Save one finished chunk: complete, or (if killed) not at all."""
        payload = dict(arrays)
        payload["__wall_time_s"] = np.float64(wall_time_s)
        target = self.chunk_file(index)
        tmp = target.with_name(target.name + ".tmp")
        with open(tmp, "wb") as f:
            np.savez(f, **payload)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
        _sync_dir(self.chunks)

    def read_chunk(self, index: int) -> tuple[dict[str, np.ndarray], float]:
        with np.load(self.chunk_file(index)) as z:
            arrays = {k: z[k] for k in z.files if k != "__wall_time_s"}
            return arrays, float(z["__wall_time_s"])


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)
    _sync_dir(path.parent)


def _sync_dir(folder: Path) -> None:
    fd = os.open(folder, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def drop(output: Path) -> None:
    """Remove the journal of ``output`` (and what a killed removal left): renamed away first, so
    a kill mid-removal never leaves a journal that looks like a run with chunks missing."""
    folder, trash = partial_path(output), discard_path(output)
    shutil.rmtree(trash, ignore_errors=True)
    if folder.is_dir():
        os.replace(folder, trash)
        shutil.rmtree(trash, ignore_errors=True)
    elif folder.exists():  # an older version's one-file partial
        folder.unlink()
