"""Reading datasets: ``open_dataset`` (a finished dataset, or an unfinished run's journal assembled
in memory), and the checks of files mechsweep did not write or that another process holds: a
dataset file (``check_dataset_file``), a journal folder (``check_journal_files``), an HDF5 lock.
Reading needs neither numba nor the models' kernels."""
from __future__ import annotations

import errno
import os
import stat
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import h5py

from ..errors import SYSTEM_ERRNOS, FileBusy, InputError, StoreError, file_kind, os_error_text, why_os_error
from ..chunks import plan_chunks
from .assemble import assemble
from .journal import Journal, partial_path
from .write import layout

if TYPE_CHECKING:
    import xarray as xr


# Datasets up to this size are loaded into memory by open_dataset(lazy=None); larger ones are
# opened lazily, so that the memory a run or a plot needs stays bounded by a chunk, not the grid.
LOAD_LIMIT_BYTES = 256 * 2**20


HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


RUN_ATTRS = ("scene_canonical", "model", "outputs")  # every dataset `mechsweep run` writes has them


def open_dataset(path: str | Path, *, allow_partial: bool = False, lazy: bool | None = False) -> xr.Dataset:
    """Open a dataset mechsweep wrote (``mechsweep run``, :func:`mechsweep.run`).

    Reading needs neither numba nor the models' kernels: it works wherever xarray and h5netcdf do.
    ``xarray.open_dataset(path, engine="h5netcdf")`` reads the same file; this function also
    checks that it is a mechsweep dataset and can open an unfinished run.

    Parameters
    ----------
    path : str or pathlib.Path
        The dataset's file.
    allow_partial : bool, optional
        Open an unfinished run (its missing chunks NaN, status ``pending``) when the finished file
        does not exist yet; that view is always loaded.
    lazy : bool or None, optional
        False (default): load it into memory (the file is closed again). True: read values only
        when they are used (as dask arrays, one per storage chunk, when dask is installed). None:
        load datasets up to ``LOAD_LIMIT_BYTES`` and open larger ones lazily.

    Returns
    -------
    xarray.Dataset
        The grid's dimensions and coordinates, the outputs, ``status`` (and ``n_steps``,
        ``n_rhs``), and the attributes the run wrote (the scene, solver settings, provenance).

    Raises
    ------
    FileNotFoundError
        No file at ``path`` (the message says when an unfinished run is there instead).
    StoreError
        The file is not a dataset mechsweep wrote (a folder, a device, an empty, text or damaged
        file, an HDF5 or netCDF file from elsewhere): the message says what it is not.
    """
    if "\0" in str(path):
        raise StoreError(f"dataset path {str(path)!r} contains a NUL character")
    path = Path(path)
    if not os.path.lexists(path):
        part = partial_path(path)
        if allow_partial and part.exists():
            return _open_partial(part)
        if part.exists():
            raise FileNotFoundError(
                f"{path} does not exist, but an unfinished run left {part}; complete it with "
                "`mechsweep run SCENE --resume`, or open it with allow_partial=True"
            )
        raise FileNotFoundError(f"{path} does not exist")
    check_dataset_file(path)
    if lazy is None:
        lazy = path.stat().st_size > LOAD_LIMIT_BYTES
    import xarray as xr  # here, not at the top: the command `mechsweep run` never needs it (0.3 s of CPU)

    try:
        if lazy:
            return current_names(xr.open_dataset(path, engine="h5netcdf", chunks={} if _have_dask() else None))
        with xr.open_dataset(path, engine="h5netcdf") as ds:
            return current_names(ds.load())
    except (OSError, ValueError, KeyError, TypeError, RuntimeError) as exc:
        raise StoreError(f"{path} is not a readable mechsweep dataset: {_first_line(exc)}") from None


def current_names(ds: xr.Dataset) -> xr.Dataset:
    """A dataset written before one of its model's parameters was renamed, with the current name:
    a variable named by a former name the declaration keeps (``Param.aliases``, e.g. the
    slider-crank's ``lambda``, now ``lam``: a Python keyword cannot be used in ``ds.sel``). Only
    a file with a name that is no identifier, or a keyword, looks the model up."""
    import keyword

    odd = [n for n in ds.variables if isinstance(n, str) and (keyword.iskeyword(n) or not n.isidentifier())]
    model = ds.attrs.get("model")
    if not odd or not isinstance(model, str):
        return ds
    from ..models import MODELS  # (imports the built-in models: only for such an old file)

    spec = MODELS.get(model)
    renames = {a: n for a, n in (spec.aliases() if spec is not None else {}).items()
               if a in ds.variables and n not in ds.variables}
    if not renames:
        return ds
    ds = ds.rename(renames)
    for key in ("along", "continue_in"):  # a boundaries dataset names its axes
        if ds.attrs.get(key) in renames:
            ds.attrs[key] = renames[ds.attrs[key]]
    return ds


def check_dataset_file(path: str | Path) -> None:
    """Raise StoreError unless ``path`` is a regular HDF5 file that mechsweep wrote: a run's
    dataset (its scene, model and outputs attributes and a status variable) or a benchmark's
    (a ``mechsweep_kind`` attribute). Reads the file's header only, never blocks on a pipe."""
    path = Path(path)
    what = f"{path} is not a mechsweep dataset"
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise FileNotFoundError(f"{path} does not exist (a broken link)") from None
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    if not stat.S_ISREG(mode):
        raise StoreError(f"{what}: it is {file_kind(mode)}, not a file")
    try:  # O_NONBLOCK: a path that became a pipe since the stat above does not block the open
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise StoreError(f"{what}: it is {file_kind(info.st_mode)}, not a file")
        if held_for_writing(fd):
            raise FileBusy(path, lock_holder(info))
        head = os.read(fd, 8)
    except OSError as exc:
        raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
    finally:
        os.close(fd)
    if not head:
        raise StoreError(f"{what}: it is an empty file")
    if head != HDF5_SIGNATURE:
        kind = ("a netCDF-3 file" if head.startswith(b"CDF") else
                "a text file" if _looks_like_text(path) else "a file of another format")
        raise StoreError(f"{what}: it is {kind}, not HDF5 (it starts with {head[:8]!r})")
    try:
        with h5py.File(path, "r") as f:
            attrs = set(f.attrs)
            names = set(f.keys())
            outputs = _text(f.attrs.get("outputs", "")).split() if "outputs" in attrs else []
    except Exception as exc:  # h5py raises OSError, and others for damaged internals
        if is_lock_error(exc):  # another process took it for writing since the probe above
            raise FileBusy(path, lock_holder(path)) from None
        if isinstance(exc, OSError) and exc.errno in _SYSTEM_ERRORS:  # the system's refusal, not the file's bytes
            raise StoreError(f"{what}: it cannot be read ({why_os_error(exc.errno, exc.strerror)})") from None
        raise StoreError(f"{what}: it is an HDF5 file that cannot be read, damaged or truncated "
                         f"({_first_line(exc)})") from None
    if "mechsweep_kind" in attrs:
        return
    missing = [a for a in RUN_ATTRS if a not in attrs]
    if missing:
        raise StoreError(f"{what}: it is an HDF5/netCDF file without the attribute(s) {', '.join(missing)} "
                         "that `mechsweep run` writes")
    absent = [v for v in ["status", *outputs] if v not in names]
    if absent:
        raise StoreError(f"{what}: it lacks the variable(s) {', '.join(absent)} that a run writes")


# errnos with which the system refuses a read (the file's bytes are not at fault)
_SYSTEM_ERRORS = frozenset(getattr(errno, n) for n in ("EACCES", "EPERM", "ENOENT", "EMFILE", "ENFILE", "ENOMEM",
                                                        "EIO", "EISDIR", "ENOTDIR", "ELOOP") if hasattr(errno, n))


def is_lock_error(exc: BaseException) -> bool:
    """Whether ``exc`` (of h5py opening a file) says another process holds the file's HDF5 lock."""
    return isinstance(exc, BlockingIOError) or (isinstance(exc, OSError) and "unable to lock file" in str(exc))


def held_for_writing(fd: int) -> bool:
    """Whether another process holds an exclusive lock on the open file ``fd``: HDF5 takes one
    (flock) on a file it opens for writing. Probed with a shared lock that is released at once;
    False where file locks are not available (no fcntl: Windows)."""
    try:
        import fcntl
    except ImportError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    except OSError:  # e.g. a file system without locks
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_UN)
    except OSError:
        pass
    return False


def lock_holder(file) -> int | None:
    """The process id holding a lock on ``file`` (a path or an os.stat_result), from /proc/locks
    (Linux); None when it cannot be told."""
    try:
        info = file if isinstance(file, os.stat_result) else os.stat(file)
        with open("/proc/locks") as f:
            lines = f.read(1 << 20).splitlines()
    except OSError:
        return None
    key = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    for line in lines:  # "1: FLOCK  ADVISORY  WRITE 19010 fe:00:1490980 0 EOF"
        parts = line.split()
        if key in parts and parts.index(key) >= 1:
            try:
                return int(parts[parts.index(key) - 1])
            except ValueError:
                return None
    return None


def is_run_dataset(ds: xr.Dataset) -> bool:
    """A dataset of `mechsweep run` (not a benchmark's)."""
    return all(a in ds.attrs for a in RUN_ATTRS) and "status" in ds


def _text(value) -> str:
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    return value if isinstance(value, str) else str(value)


def _looks_like_text(path: Path) -> bool:
    with open(path, "rb") as f:
        block = f.read(4096)
    try:
        block.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(block) - 4:  # not just a character cut at the block's end
            return False
    return b"\0" not in block


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return (text[0][:200] if text else type(exc).__name__)


def _open_partial(part: Path) -> xr.Dataset:
    """An unfinished run as a Dataset, assembled in memory from its journal."""
    check_journal_files(part)
    try:
        return _assemble_partial(part)
    except (StoreError, FileNotFoundError):
        raise
    except Exception as exc:  # a journal someone edited or damaged: say so, no traceback
        raise StoreError(f"{part} is not a readable unfinished run ({type(exc).__name__}: {_first_line(exc)}); "
                         "start it over with --restart") from None


def check_journal_files(part: Path, contents: bool = True) -> None:
    """Raise StoreError if the journal folder ``part`` (when it exists) or, with ``contents``, what
    it holds is not what a run makes: a folder, a verified run.json, a folder chunks of files (a
    pipe or a device there would block or be replaced). Without ``contents`` (--restart discards
    what the folder holds) only the folder itself is checked."""
    from .journal import RESTART

    if not os.path.lexists(part):
        return
    mode = os.lstat(part).st_mode
    if stat.S_ISREG(mode):  # an older version's one-file journal: Journal.read says so
        return
    if not stat.S_ISDIR(mode):
        raise StoreError(f"{part} (the journal of unfinished runs) is {file_kind(mode)}, not a folder mechsweep made; "
                         "move it away")
    if not contents:
        return
    try:
        _check_journal_kinds(part)
    except OSError as exc:  # e.g. a folder that cannot be listed (permission denied)
        raise StoreError(f"{exc.filename or part} cannot be read ({exc.strerror}); the journal {part} cannot be "
                         f"resumed: {RESTART}") from None
    _check_run_json(part / "run.json")


def _check_journal_kinds(part: Path) -> None:
    from .journal import RESTART

    for name, want, test in (("run.json", "a file", stat.S_ISREG), ("chunks", "a folder", stat.S_ISDIR)):
        entry = part / name
        if os.path.lexists(entry) and not test(mode := os.lstat(entry).st_mode):
            raise StoreError(f"{entry} is {file_kind(mode)}, not {want} as a run writes it; {RESTART}")
    for e in os.scandir(part):  # e.g. assembly.h5: a pipe there would block the run's last step
        if e.name not in ("run.json", "chunks") and not e.is_file(follow_symlinks=False):
            raise StoreError(f"{e.path} is {_lkind(e.path)}, not a file a run writes; {RESTART}")
    chunks = part / "chunks"
    n_chunk_files = 0
    if chunks.is_dir():
        for e in os.scandir(chunks):
            if not e.is_file(follow_symlinks=False):
                raise StoreError(f"{e.path} is not a chunk file a run writes (it is {_lkind(e.path)}): remove that "
                                 f"entry (--resume then computes its chunk again), or {RESTART}")
            n_chunk_files += e.name.endswith(".npz")
    has_meta = os.path.lexists(part / "run.json")
    if n_chunk_files and not has_meta:  # a run writes run.json before any chunk
        raise StoreError(f"{part / 'run.json'} is missing, and {n_chunk_files} chunk file(s) are in {chunks}: the "
                         f"journal is damaged; {RESTART}")
    if has_meta and not os.path.lexists(chunks):  # a run makes chunks/ before run.json
        raise StoreError(f"{chunks} is missing, and {part / 'run.json'} is there: the journal is damaged; {RESTART}")


def _lkind(path) -> str:
    return file_kind(os.lstat(path).st_mode)


def _check_run_json(path: Path) -> None:
    """Refuse a journal's run.json that is not what a run writes (edited, damaged, foreign)."""
    import json

    from .journal import RESTART, meta_problem

    if not path.is_file():
        return
    try:
        meta = json.loads(path.read_bytes())
    except ValueError as exc:
        raise StoreError(f"{path} is unreadable ({_first_line(exc)}); {RESTART}") from None
    except OSError as exc:
        raise StoreError(f"{path} cannot be read ({exc.strerror}); {RESTART}") from None
    if (why := meta_problem(meta)) is not None:
        raise StoreError(f"{path} {why}; {RESTART}")


def _assemble_partial(part: Path) -> xr.Dataset:
    import io

    journal = Journal.read(part)
    if journal.empty:
        raise FileNotFoundError(f"{part} holds no finished chunk yet")
    attrs = journal.meta.get("attrs") if isinstance(journal.meta.get("attrs"), dict) else {}
    from ..scene import load_scene_text

    scene = load_scene_text(journal.meta["scene"], label=str(part / "run.json"),
                            base=attrs.get("scene_folder") or None)
    chunks = plan_chunks(scene.shape, journal.meta["chunk_target"])
    lay = layout(scene, len(chunks))
    buffer = io.BytesIO()
    bad_chunks, _ = assemble(journal, scene, lay, chunks, buffer, journal.meta["attrs"])
    for bad in bad_chunks:
        print(f"mechsweep: {bad}; shown as pending, a --resume computes it again", file=sys.stderr)
    buffer.seek(0)
    import xarray as xr

    with xr.open_dataset(buffer, engine="h5netcdf") as ds:
        return ds.load()


def _have_dask() -> bool:
    try:
        import dask.array  # noqa: F401
    except ImportError:
        return False
    return True


@contextmanager
def reading(path):
    """Reading a dataset opened by ``open_dataset`` (``mechsweep info`` and ``plot``): a file that passed
    the opener's checks (a run's attributes and variables) but whose
    contents are not laid out as a run writes them (edited, or made elsewhere to look alike):
    say so in one line, exit 2."""
    try:
        yield
    except InputError:
        raise
    except OSError as exc:
        if is_lock_error(exc):  # another process took the dataset for writing meanwhile
            raise FileBusy(path, lock_holder(path)) from None
        if exc.filename is not None or exc.errno in SYSTEM_ERRNOS:  # the system's refusal, not the file's bytes
            raise InputError(os_error_text(exc, path)) from None
        # a lazily opened dataset whose data turn out damaged when read (HDF5 says why, without an errno)
        raise InputError(f"{path} cannot be read, it is damaged ({str(exc).splitlines()[0][:200]})") from None
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        detail = str(exc).splitlines()[0][:200] if str(exc) else ""
        raise InputError(f"{path} is not laid out as a mechsweep dataset ({type(exc).__name__}: {detail}); "
                         "was it written by `mechsweep run`?") from None
