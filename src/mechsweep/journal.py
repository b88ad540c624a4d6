"""Crash-safe progress of a run: a lock against a second writer, and a journal of finished chunks.

A run of output ``PATH`` keeps its finished chunks in the folder ``PATH.partial/``:

- ``run.json``: the scene (canonical form and text), the number of chunks and the provenance,
  written before any chunk;
- ``chunks/NNNNNNN-SIZE-CRC.npz``: one file per finished chunk (its outputs, status, step counts
  and the wall time it took), written to a temporary name, synced and renamed into place. Its name
  carries the file's size in bytes and the CRC-32 of its bytes (8 hex digits): a chunk file that
  does not match them (truncated, zeroed, damaged by the disk) is not counted as finished; a
  resumed run removes it and computes that chunk again, keeping the others. (Files named
  ``NNNNNNN.npz``, from an older version, carry no checksum: they count when numpy can read them.)

A rename is atomic, so at any moment (a SIGKILL, a power cut after the sync) every chunk file is
either complete or absent, and a resumed run computes exactly the chunks that have no file. The
HDF5 dataset is assembled from the journal only when every chunk is in, into a temporary file in
the journal folder that replaces ``PATH`` by one rename; the journal is then dropped. An HDF5 file
is never written in place while a run is under way: a kill in the middle of an HDF5 write can leave
a file the library cannot open again, a chunk file cannot.

The lock is ``.PATH.lock`` beside the output, held with ``flock`` for the whole run (the kernel
releases it when the process dies, however it dies), so a second run on the same output is refused
at once instead of interleaving its writes.

Every write here (lock, run.json, chunk files, folder syncs) turns a system error (disk full, file
size limit, quota, I/O error) into ``WriteFailed`` and leaves the journal as it was before it.
"""
from __future__ import annotations

import errno
import fcntl
import io
import json
import os
import re
import shutil
import zlib
from pathlib import Path

import numpy as np

from .errors import StoreError, WriteFailed

# 2: chunk files named with their size and CRC-32. A journal of format 1 (names without them) is
# still read; an older mechsweep refuses format 2 instead of not seeing its chunk files.
FORMAT = 2
READABLE_FORMATS = (1, 2)
_CHUNK_NAME = re.compile(r"^(\d{7,})(?:-(\d+)-([0-9a-f]{8}))?\.npz$")


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
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:  # e.g. no inode left on a full disk
                raise WriteFailed(self.path, exc) from None
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
                self.fd = fd
                try:
                    os.ftruncate(fd, 0)
                    os.write(fd, str(os.getpid()).encode())
                except OSError as exc:
                    self.release()
                    raise WriteFailed(self.path, exc) from None
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
        self.files: dict[int, Path] = {}  # index -> its file, from the last done_chunks()
        self.removed: list[str] = []  # damaged chunk files done_chunks(repair=True) removed, with why

    # -- creation and reopening ----------------------------------------------------
    @classmethod
    def create(cls, folder: Path, *, canonical: str, text: str, chunk_target: int, n_chunks: int,
               attrs: dict) -> "Journal":
        meta = {"format": FORMAT, "scene_canonical": canonical, "scene": text, "chunk_target": chunk_target,
                "n_chunks": n_chunks, "attrs": attrs}
        try:
            folder.mkdir()
        except OSError as exc:
            raise WriteFailed(folder, exc) from None
        try:
            (folder / "chunks").mkdir()
            _write_atomic(folder / "run.json", json.dumps(meta, indent=1).encode())
        except OSError as exc:
            shutil.rmtree(folder, ignore_errors=True)
            raise WriteFailed(folder / "run.json", exc) from None
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
        if meta is not None and meta.get("format") not in READABLE_FORMATS:
            raise StoreError(f"{folder} was written by another mechsweep version (journal format "
                               f"{meta.get('format')}, this one reads {', '.join(map(str, READABLE_FORMATS))}); "
                               "start over with --restart")
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
    def chunk_file(self, index: int) -> Path | None:
        """The file of chunk ``index`` found by the last ``done_chunks``, or None."""
        return self.files.get(index)

    def done_chunks(self, repair: bool = False) -> np.ndarray:
        """Boolean per chunk: its file is in the journal and has the size its name says (the
        checksum is verified when it is read). With ``repair`` (only under the run's lock) leftover
        temporary files and chunk files that do not verify are removed (listed in ``removed``), so
        that those chunks are computed again; without it they are only not counted."""
        done = np.zeros(self.meta["n_chunks"], dtype=bool)
        self.files, self.removed = {}, []
        for entry in os.scandir(self.chunks):
            m = _CHUNK_NAME.match(entry.name)
            if m and int(m.group(1)) < done.size:
                index = int(m.group(1))
                why = _size_problem(entry, None if m.group(2) is None else int(m.group(2)))
                if why is None and index not in self.files:
                    done[index] = True
                    self.files[index] = Path(entry.path)
                    continue
                why = why or "a second file for the same chunk"
                if repair:
                    self.discard(Path(entry.path), why)
            elif entry.name.endswith(".tmp") and repair:
                _unlink(entry.path)  # a write that a kill interrupted
        return done

    def discard(self, path: Path, why: str) -> None:
        """Remove a chunk file that does not verify (under the run's lock), noting why."""
        _unlink(path)
        self.removed.append(f"{path.name}: {why}")

    def write_chunk(self, index: int, arrays: dict[str, np.ndarray], wall_time_s: float) -> None:
        """Save one finished chunk: complete, or (if killed or the write fails) not at all."""
        payload = dict(arrays)
        payload["__wall_time_s"] = np.float64(wall_time_s)
        tmp = self.chunks / f"{index:07d}.npz.tmp"
        try:
            # the file's bytes are made in memory, so that their size and CRC-32 are known without
            # reading the file back (the same bytes np.savez writes into a file)
            buffer = io.BytesIO()
            np.savez(buffer, **payload)
            data = buffer.getbuffer()
            size, crc = len(data), zlib.crc32(data)
            with open(tmp, "wb") as f:
                f.write(data)
                f.flush()
                os.fsync(f.fileno())
            del data
            target = self.chunks / f"{index:07d}-{size}-{crc:08x}.npz"
            os.replace(tmp, target)
            _sync_dir(self.chunks)
        except OSError as exc:
            _unlink(tmp)
            raise WriteFailed(tmp, exc) from None
        self.files[index] = target

    def read_chunk(self, index: int) -> tuple[dict[str, np.ndarray], float]:
        """The arrays and wall time of chunk ``index``, verified against its size and checksum;
        ``BadChunk`` if they do not match or the file cannot be read."""
        path = self.files.get(index)
        if path is None:
            raise BadChunk(index, self.chunks / f"{index:07d}.npz", "no file")
        m = _CHUNK_NAME.match(path.name)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise BadChunk(index, path, f"unreadable ({exc.strerror})") from None
        if m.group(2) is not None:
            if len(data) != int(m.group(2)):
                raise BadChunk(index, path, f"{len(data)} bytes, its name says {m.group(2)}")
            if (crc := zlib.crc32(data)) != int(m.group(3), 16):
                raise BadChunk(index, path, f"checksum {crc:08x}, its name says {m.group(3)}")
        try:
            with np.load(io.BytesIO(data)) as z:
                arrays = {k: z[k] for k in z.files if k != "__wall_time_s"}
                return arrays, float(z["__wall_time_s"])
        except Exception as exc:  # a damaged file of an older version (no checksum in its name)
            raise BadChunk(index, path, f"unreadable ({type(exc).__name__}: {exc})") from None


class BadChunk(StoreError):
    """A chunk file of the journal does not verify (size, checksum, or format)."""

    def __init__(self, index: int, path: Path, why: str):
        self.index, self.path, self.why = index, path, why
        super().__init__(f"chunk file {path} is damaged: {why}")


def _size_problem(entry: os.DirEntry, expected: int | None) -> str | None:
    try:
        size = entry.stat().st_size
    except OSError as exc:
        return f"unreadable ({exc.strerror})"
    if expected is None:
        return "empty file" if size == 0 else None
    return None if size == expected else f"{size} bytes, its name says {expected}"


def _unlink(path) -> None:
    try:
        os.unlink(path)
    except FileNotFoundError:
        pass


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
        try:
            os.replace(folder, trash)
        except OSError:  # the rename failed (a full disk can refuse it): remove it in place
            shutil.rmtree(folder, ignore_errors=True)
            return
        shutil.rmtree(trash, ignore_errors=True)
    elif folder.exists():  # an older version's one-file partial
        folder.unlink()
