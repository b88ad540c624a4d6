"""Crash-safe progress of a run: a lock against a second writer, and a journal of finished chunks.

A run of output ``PATH`` keeps its finished chunks in the folder ``PATH.partial/``:

- ``run.json``: the scene (canonical form and text), the number of chunks and the provenance,
  written before any chunk, with a random run id and a SHA-256 checksum of everything else in it
  (``checksum``): a run.json edited or damaged after it was written is refused;
- ``chunks/NNNNNNN-SIZE-CRC.npz``: one file per finished chunk (its outputs, status, step counts
  and wall time), written to a temporary name, synced and renamed into place. Its name carries the
  file's size and a CRC-32 of the run id, the chunk's index and the file's bytes: a chunk file that
  does not match them (truncated, damaged, edited, renamed, from another run) is not counted; a
  resumed run removes it and computes that chunk again. (Older formats: ``NNNNNNN.npz`` without a
  checksum counts when numpy reads it; format 2 has no run id, and its run.json no checksum.)

Only what a run writes is ever deleted (``drop``, in whatever state it is); an entry a run does not
write is never removed (``foreign_entries``; the runner refuses to resume or restart over it).

A rename is atomic, so after a kill or a power cut every chunk file is complete or absent, and a
resumed run computes exactly the chunks that have no file. The HDF5 dataset is assembled only when
every chunk is in, into a temporary file that replaces ``PATH`` by one rename: a kill in the middle
of an HDF5 write can leave a file the library cannot open again, a chunk file cannot.

The lock is ``.PATH.lock`` beside the output, held with ``flock`` for the whole run (released by
the kernel however the process dies), so a second run on the same output is refused at once.

Every write here (lock, run.json, chunk files, folder syncs) turns a system error (disk full, file
size limit, quota, I/O error) into ``WriteFailed`` and leaves the journal as it was before it.
"""
from __future__ import annotations

import errno
import hashlib
import io
import json
import os
import re
import secrets
import shutil
import stat
import zlib
from pathlib import Path

import numpy as np

from ..chunks import MAX_CHUNKS
from ..errors import StoreError, WriteFailed

# 2: chunk files named with their size and CRC-32. A journal of format 1 (names without them) is
# still read; an older mechsweep refuses format 2 instead of not seeing its chunk files.
# 3: run.json carries a run id and its own checksum, and a chunk's CRC-32 covers the run id and its
# index before its bytes (a version that reads format 2 would take every chunk file for damaged).
FORMAT = 3
READABLE_FORMATS = (1, 2, 3)
_CHUNK_NAME = re.compile(r"^(\d{7,})(?:-(\d+)-([0-9a-f]{8}))?\.npz$")
_CHUNK_TMP = re.compile(r"^\d{7,}\.npz\.tmp$")  # a chunk file being written (write_chunk)
# What a run writes into its journal folder besides chunks/ (ASSEMBLY: the runner's dataset being assembled).
OWN_FILES = ("run.json", "run.json.tmp", "assembly.h5")


def partial_path(path: str | os.PathLike) -> Path:
    return Path(str(path) + ".partial")


def lock_path(path: str | os.PathLike) -> Path:
    p = Path(path)
    return p.with_name("." + p.name + ".lock")


def discard_path(path: str | os.PathLike) -> Path:
    """Where a journal goes to be deleted (a kill during the deletion leaves it there)."""
    return Path(str(path) + ".partial.discard")


# ----------------------------------------------------------------------------- lock
def _fcntl():
    """The POSIX module whose file locks guard a run (imported here, not with this module: reading
    a dataset needs no lock, and Windows, where it does not exist, can read datasets)."""
    try:
        import fcntl
    except ImportError:
        raise StoreError("running a sweep needs file locks (fcntl), which this system does not have: sweeps run "
                         "on Linux and macOS; here datasets can be read and plotted") from None
    return fcntl


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
        fcntl = _fcntl()
        while True:
            try:
                fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW, 0o644)  # (never through a link)
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
        fcntl = _fcntl()
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
            if _same_file(self.fd, self.path):  # (a file put in its place meanwhile is not ours to remove)
                self.path.unlink(missing_ok=True)  # before closing: nobody can lock the old inode in between
            os.close(self.fd)
            self.fd = None

    def __enter__(self) -> "RunLock":
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


def _same_file(fd: int, path: Path) -> bool:
    try:
        mine, there = os.fstat(fd), os.lstat(path)
    except OSError:
        return False
    return (mine.st_dev, mine.st_ino) == (there.st_dev, there.st_ino)


def _read_pid(fd: int) -> str:
    try:
        return os.pread(fd, 32, 0).decode(errors="replace").strip()
    except OSError:
        return ""


def _shown(value) -> str:
    text = json.dumps(value)
    return text if len(text) <= 60 else text[:57] + "..."


def scene_differences(stored: str, current: str, most: int = 3, then: str = "when the run began") -> str:
    """What differs between two canonical scene forms (``Scene.canonical``), key by key, as a user
    reads it: ``fixed.Y: 0.01 when the run began, 0.02 now`` (``then`` says where the stored form
    is from); at most ``most`` keys, then how many more. "" when either is not such a form."""
    try:
        old, new = json.loads(stored), json.loads(current)
    except (TypeError, ValueError):
        return ""
    found: list[str] = []

    def walk(a, b, key):
        if key == "axes" and isinstance(a, list) and isinstance(b, list):  # [[name, spec], ...] in order
            try:
                a_names, b_names = [x[0] for x in a], [x[0] for x in b]
                a, b = dict(a), dict(b)
            except (TypeError, ValueError, IndexError, KeyError):
                pass
            else:
                if sorted(a_names) == sorted(b_names) and a_names != b_names:
                    found.append(f"axes: in the order {', '.join(a_names)} {then}, "
                                 f"{', '.join(b_names)} now")
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b), key=str):
                name = f"{key}.{k}" if key else str(k)
                if k not in a:
                    found.append(f"{name}: not given {then}, {_shown(b[k])} now")
                elif k not in b:
                    found.append(f"{name}: {_shown(a[k])} {then}, not given now")
                else:
                    walk(a[k], b[k], name)
        elif a != b:
            found.append("the model's source files changed" if key == "model_source_sha256"
                         else f"{key}: {_shown(a)} {then}, {_shown(b)} now")

    walk(old, new, "")
    more = f"; and {len(found) - most} more" if len(found) > most else ""
    return "; ".join(found[:most]) + more


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
        # the run id a chunk's CRC-32 covers (None: a journal of format 1 or 2, CRC of the bytes only)
        self.run_id = meta.get("run_id") if isinstance(meta, dict) else None

    # -- creation and reopening ----------------------------------------------------
    @classmethod
    def create(cls, folder: Path, *, canonical: str, text: str, chunk_target: int, n_chunks: int,
               attrs: dict) -> "Journal":
        meta = {"format": FORMAT, "scene_canonical": canonical, "scene": text, "chunk_target": chunk_target,
                "n_chunks": n_chunks, "attrs": attrs}
        meta = seal(meta)
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
            meta = json.loads((folder / "run.json").read_bytes())
        except FileNotFoundError:
            meta = None  # killed between creating the folder and writing run.json: nothing saved
        except (OSError, ValueError) as exc:
            raise StoreError(f"{folder / 'run.json'} is unreadable ({exc}); {RESTART}") from None
        if meta is not None and (why := meta_problem(meta)) is not None:
            raise StoreError(f"{folder / 'run.json'} {why}; {RESTART}")
        return cls(folder, meta)

    def matches(self, canonical: str, chunk_target: int, n_chunks: int) -> str | None:
        """Why this journal cannot be resumed by a run of ``canonical`` cut into chunks of
        ``chunk_target`` points (``n_chunks`` of them), or None."""
        if self.meta["scene_canonical"] != canonical:
            what = scene_differences(self.meta["scene_canonical"], canonical)
            return (f"{self.folder} was started from a different scene ("
                    + (what or "model, outputs, axes, fixed values or solver settings differ")
                    + "); resume it with the scene it was started with, or start over with --restart")
        if (self.meta["chunk_target"], self.meta["n_chunks"]) != (chunk_target, n_chunks):
            return (f"{self.folder} was cut into {self.meta['n_chunks']} chunks of up to "
                    f"{self.meta['chunk_target']} points, this run into {n_chunks} of up to {chunk_target}; "
                    "use the same storage.chunk_size, or --restart")
        return None

    @property
    def empty(self) -> bool:
        return self.meta is None

    # -- chunks ----------------------------------------------------------------------
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
            size, crc = len(data), chunk_crc(data, self.run_id, index)
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
            if (crc := chunk_crc(data, self.run_id, index)) != int(m.group(3), 16):
                raise BadChunk(index, path, f"checksum {crc:08x}, its name says {m.group(3)} (damaged, edited, "
                               "or not this run's chunk of this index)")
        try:
            with np.load(io.BytesIO(data)) as z:
                arrays = {k: z[k] for k in z.files if k != "__wall_time_s"}
                return arrays, float(z["__wall_time_s"])
        except Exception as exc:  # a damaged file of an older version (no checksum in its name)
            raise BadChunk(index, path, f"unreadable ({type(exc).__name__}: {exc})") from None


# The advice of every message about a journal that cannot be resumed.
RESTART = "--restart discards the journal and starts over (its finished chunks are lost)"


def chunk_crc(data, run_id: str | None, index: int) -> int:
    """The CRC-32 a chunk file's name carries: of ``run_id/index`` followed by the file's bytes, so
    that a chunk file renamed to another index, or taken from another run, does not verify (format
    2, without a run id: of the bytes only). It detects damage and mix-ups, not a forgery: anyone
    can compute it."""
    if run_id is None:
        return zlib.crc32(data)
    return zlib.crc32(data, zlib.crc32(f"{run_id}/{index}".encode()))


def meta_checksum(meta: dict) -> str:
    """SHA-256 of a run.json's content: every entry but ``checksum`` and ``format`` (which says how
    to read the file), as sorted, compact JSON (the form does not depend on the file's layout)."""
    body = {k: v for k, v in meta.items() if k not in ("checksum", "format")}
    text = json.dumps(body, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


def seal(meta: dict) -> dict:
    """``meta`` as run.json stores it (as JSON reads it back), with a new run id and its checksum."""
    meta = json.loads(json.dumps({**meta, "run_id": secrets.token_hex(8)}))
    meta["checksum"] = meta_checksum(meta)
    return meta


# run.json's entries and their kinds (besides format, and run_id and checksum from format 3 on)
META_KINDS = {"scene_canonical": str, "scene": str, "chunk_target": int, "n_chunks": int, "attrs": dict}
# Attributes every run's dataset has (store.read.RUN_ATTRS), and those the runner reads as text.
_TEXT_ATTRS = ("scene_canonical", "model", "outputs")
_OPTIONAL_TEXT_ATTRS = ("scene", "title", "history", "scene_folder")


def meta_problem(meta) -> str | None:
    """Why a run.json's content (parsed JSON) is not what a run writes, for a message ("PATH
    {why}"), or None: of another version, an entry missing or of the wrong kind or range, or (from
    format 3 on) not matching its checksum."""
    if not isinstance(meta, dict):
        return f"is not a run's journal (a JSON {type(meta).__name__}, not an object)"
    fmt = meta.get("format")
    if not isinstance(fmt, int) or isinstance(fmt, bool):
        return f"is damaged (entry format missing or of the wrong kind: {fmt!r})"
    if fmt not in READABLE_FORMATS:
        return (f"was written by another mechsweep version (journal format {fmt}, this one reads "
                f"{', '.join(map(str, READABLE_FORMATS))})")
    bad = [k for k, kind in META_KINDS.items() if not isinstance(meta.get(k), kind) or isinstance(meta.get(k), bool)]
    if bad:
        return f"is damaged (entries {', '.join(bad)} missing or of the wrong kind)"
    if not 1 <= meta["n_chunks"] <= MAX_CHUNKS or meta["chunk_target"] < 1:
        return (f"is damaged (n_chunks = {meta['n_chunks']}, chunk_target = {meta['chunk_target']}: a run has "
                f"1 to {MAX_CHUNKS:,} chunks of at least one point)")
    if (why := seal_problem(meta)) is not None:
        return why
    attrs = meta["attrs"]
    bad = [k for k in _TEXT_ATTRS if not isinstance(attrs.get(k), str)]
    bad += [k for k in _OPTIONAL_TEXT_ATTRS if k in attrs and not isinstance(attrs[k], str)]
    bad += [k for k, v in attrs.items() if k not in bad and not _storable(v)]
    if bad:
        return f"is damaged (attributes {', '.join(bad)} missing or of the wrong kind)"
    if attrs["scene_canonical"] != meta["scene_canonical"]:
        return "is damaged (its attribute scene_canonical differs from its entry scene_canonical)"
    return None


def _storable(value) -> bool:
    """A value the dataset's attributes can hold as run.json gives it: text, a number, or a list of them."""
    if isinstance(value, (str, int, float)):
        return True
    return isinstance(value, list) and (all(isinstance(v, str) for v in value) or all(
        isinstance(v, (int, float)) and not isinstance(v, bool) for v in value))


def seal_problem(meta: dict) -> str | None:
    """Why a run.json's content does not verify (for a message: "PATH {why}"), or None. A journal of
    format 1 or 2 (written before the checksum) has none to verify."""
    checksum = meta.get("checksum")
    if checksum is None and meta.get("format") in (1, 2) and "run_id" not in meta:
        return None
    if not isinstance(checksum, str):
        return "has no checksum (entry checksum missing or of the wrong kind): it was edited or damaged"
    if not isinstance(meta.get("run_id"), str):
        return "has no run id (entry run_id missing or of the wrong kind): it was edited or damaged"
    if checksum != meta_checksum(meta):
        return "does not match its checksum: it was edited or damaged after the run wrote it"
    return None


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


def drop(output: Path) -> list[str]:
    """Remove the journal of ``output`` (and what a killed removal left): renamed away first, so
    a kill mid-removal never leaves a journal that looks like a run with chunks missing. Only what
    a run writes is removed: entries of the folder a run does not write (``foreign_entries``) stay,
    in the folder (its own entries removed in place); they are returned, for a message."""
    folder, trash = partial_path(output), discard_path(output)
    left = clear_discard(output)
    try:
        mode = os.lstat(folder).st_mode
    except FileNotFoundError:
        return left
    if stat.S_ISDIR(mode):
        if not left and not foreign_entries(folder):
            try:
                os.replace(folder, trash)
            except OSError:  # the rename failed (a full disk can refuse it): remove it in place
                pass
            else:
                return clear_discard(output)
        return left + _remove_own(folder)
    if stat.S_ISREG(mode):  # an older version's one-file partial
        folder.unlink()
    return left


def clear_discard(output: Path) -> list[str]:
    """Remove what a killed ``drop`` left of the journal of ``output`` (``discard_path``); returns
    the entries left there that a run does not write (never removed)."""
    trash = discard_path(output)
    try:
        mode = os.lstat(trash).st_mode
    except FileNotFoundError:
        return []
    if not stat.S_ISDIR(mode):
        return [f"{trash} ({_what(trash)}, not a folder)"]
    if not _entries(trash)[1]:
        shutil.rmtree(trash, ignore_errors=True)
        if not os.path.lexists(trash):
            return []
    return _remove_own(trash)


def foreign_entries(folder: Path) -> list[str]:
    """The entries of the journal folder ``folder`` that a run does not write (a user's files, a
    folder holding files where a run writes a file, what cannot be listed), which no run removes."""
    try:
        if not stat.S_ISDIR(os.lstat(folder).st_mode):
            return []
    except FileNotFoundError:
        return []
    return _entries(folder)[1]


def own_files_problem(output: Path) -> str | None:
    """Why a run of ``output`` may not take over its journal, the remains of one being deleted, or
    its lock file (a message), or None: an entry there that a run does not write (a run removes
    the journal when it ends, or with --restart, and never deletes what it did not write), a
    symbolic link in place of the folders or the lock, or a lock file holding something else than a
    lock's process id (taking the lock empties it)."""
    for folder in (partial_path(output), discard_path(output)):
        if os.path.islink(folder):
            return (f"{folder} is a symbolic link, not a folder mechsweep made; a run would take it for its journal: "
                    "move it away or choose another path with -o")
        left = foreign_entries(folder)
        if unlisted := [e for e in left if isinstance(e, _Unlisted)]:
            return (f"in {folder}, {_listing(unlisted)} cannot be listed: what it holds is not known, and a run "
                    "never deletes files it did not write; give it back its permissions (chmod u+rwx) or move it "
                    "away, then run again")
        if left:
            return (f"{folder} holds {_listing(left)}, which a run does not write: a run removes that folder "
                    f"(with --restart, or when it ends) and never deletes files it did not write; move "
                    f"{'it' if len(left) == 1 else 'them'} out of {folder}, then run again")
    part = partial_path(output)
    if os.path.isfile(part) and not os.path.islink(part):  # an older version's one-file journal (HDF5)
        try:
            with open(part, "rb") as f:
                head = f.read(8)
        except OSError as exc:
            head = str(exc).encode()
        if head and head != b"\x89HDF\r\n\x1a\n":
            return (f"{part} is a file that is not an unfinished run (an older mechsweep kept one in an HDF5 file "
                    "there); a run would take it for its journal: move it away or choose another path with -o")
    lock = lock_path(output)
    try:
        mode = os.lstat(lock).st_mode
    except FileNotFoundError:
        return None
    if stat.S_ISLNK(mode):
        return (f"{lock} (the run's lock) is a symbolic link, not a file mechsweep made; taking the lock would "
                "empty what it points to: move it away or choose another path with -o")
    if stat.S_ISREG(mode):
        try:
            with open(lock, "rb") as f:
                head = f.read(64)
        except OSError as exc:
            return (f"{lock} (the run's lock) cannot be read ({exc.strerror}); move it away or choose another "
                    "path with -o")
        if head.strip() and not head.strip().isdigit():
            return (f"{lock} (the run's lock) holds something else than a run's process id; taking the lock would "
                    "empty it: move it away or choose another path with -o")
    return None


def _entries(folder: Path) -> tuple[list[Path], list[str]]:
    """The entries of journal folder ``folder`` that a run writes (paths, deepest first, run.json
    last, in any state: a damaged file, a link, a pipe, an empty folder where a file belongs), and
    those it does not write (names in the folder, for a message)."""
    own, foreign = [], []
    try:
        listing = sorted(os.scandir(folder), key=lambda e: e.name == "run.json")
    except OSError as exc:
        return own, [_Unlisted(f"{os.path.basename(folder)} itself ({exc.strerror})")]
    for entry in listing:
        if entry.name == "chunks" and entry.is_dir(follow_symlinks=False):
            try:
                inner = list(os.scandir(entry.path))
            except OSError as exc:
                foreign.append(_Unlisted(f"chunks ({exc.strerror})"))
                continue
            for e in inner:
                if _CHUNK_NAME.match(e.name) or _CHUNK_TMP.match(e.name):
                    _own_entry(e, f"chunks/{e.name}", own, foreign)
                else:
                    foreign.append(f"chunks/{e.name}")
            own.append(Path(entry.path))
        elif entry.name in OWN_FILES or entry.name == "chunks":
            _own_entry(entry, entry.name, own, foreign)
        else:
            foreign.append(entry.name)
    return own, foreign


class _Unlisted(str):
    """An entry of a journal folder whose content cannot be listed (permission denied): what it holds
    is not known, so it is not removed."""


def _own_entry(entry: os.DirEntry, name: str, own: list, foreign: list) -> None:
    """An entry where a run writes a file: the run's in any state, except a folder that holds
    something (a run never makes a folder there; what is in it is not the run's)."""
    if entry.is_dir(follow_symlinks=False):
        try:
            inside = os.listdir(entry.path)
        except OSError as exc:
            foreign.append(_Unlisted(f"{name}/ ({exc.strerror})"))
            return
        if inside:
            foreign.append(f"{name}/ (a folder holding {_listing(sorted(inside))})")
            return
    own.append(Path(entry.path))


def _remove_own(folder: Path) -> list[str]:
    """Remove the entries of ``folder`` a run writes, then the folder if nothing else is in it;
    returns what is left (never removed: not the run's)."""
    own, foreign = _entries(folder)
    for path in own:
        try:
            if stat.S_ISDIR(os.lstat(path).st_mode):
                os.rmdir(path)  # chunks/ (empty unless it holds foreign entries), or an empty folder
            else:
                os.unlink(path)  # a link is removed, never what it points to
        except FileNotFoundError:
            pass
        except OSError as exc:
            if not foreign:
                foreign.append(f"{os.path.relpath(path, folder)} (it cannot be removed: {exc.strerror})")
    if not foreign:
        try:
            os.rmdir(folder)
        except FileNotFoundError:
            pass
        except OSError as exc:
            foreign.append(f"(the folder itself: it cannot be removed, {exc.strerror})")
    return [f"{folder}: {e}" for e in foreign]


def _listing(entries: list[str], most: int = 5) -> str:
    shown = ", ".join(str(e) for e in entries[:most])
    return shown + (f" and {len(entries) - most} more" if len(entries) > most else "")


def _what(path: Path) -> str:
    mode = os.lstat(path).st_mode
    for test, name in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISDIR, "a directory"), (stat.S_ISREG, "a file"),
                       (stat.S_ISFIFO, "a named pipe"), (stat.S_ISSOCK, "a socket"), (stat.S_ISCHR, "a device"),
                       (stat.S_ISBLK, "a device")):
        if test(mode):
            return name
    return "not a regular file"
