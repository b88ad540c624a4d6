"""Run a scene: one route for every run.

    scene -> plan (plan.py: what to compute and how, once) -> chunks -> compute (execute.py here, or
    cluster.py on a dask cluster: the same evaluate_chunk) -> a sink

The sink of a run with an output file (the CLI, ``compute``, ``run(output=path)``) is the journal of
finished chunks (journal.py: crash-safe, resumable), then the dataset assembled from it (store.py) and
moved into place by one rename. ``run(output=None)`` is the same route into a sink in memory
(store.MemorySink), and so is the dataset ``run(output=path)`` returns: its chunks are computed into
the dataset's arrays, saved to the journal, and written into the file while the next chunk computes
(store.Early), so that it is neither copied nor read back. The rest of this module checks a run's
output place, its existing files and its room before anything is written, and says what is kept
when a run stops."""
from __future__ import annotations

import contextlib
import datetime as _dt
import errno
import functools
import os
import platform
import shutil
import signal
import stat
import sys
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from importlib.metadata import version as _version
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numba
import numpy as np

from . import __version__
from . import _jit
from . import cf
from . import execute
from . import status as st
from .execute import check_threads, shows_progress
from .errors import (ClusterLost, FileBusy, InputError, OutOfSpace, RunError, RunInterrupted,  # noqa: F401  (API: runner.X)
                     WriteFailed, why_os_error)
from .grid import Chunk, chunk_target, plan_chunks
from .journal import (RESTART, BadChunk, Journal, RunLock, clear_discard, discard_path, drop, lock_path,
                      own_files_problem, partial_path)
from .plan import Plan, extra_shape, make_plan
from .scene import Scene, check_scheduler, check_worker_timeout, load_scene, load_scene_text
from .store import (COMPILE_KEY, LOAD_LIMIT_BYTES, Early, MemorySink, StoreError, assemble, check_journal_files,
                    file_kind, layout, open_dataset, status_counts)

if TYPE_CHECKING:
    import xarray as xr  # annotations only: `mechsweep run` does not import xarray


# A chunk file found damaged at assembly is computed again; if chunks keep going bad after this
# many rounds the disk is not to be trusted and the run stops.
REPAIR_ROUNDS = 3


@dataclass(frozen=True)
class RunSummary:
    """What a finished run wrote, known without opening its dataset (:func:`compute` returns it).

    Attributes
    ----------
    path : pathlib.Path
        The dataset written.
    sizes : dict
        Dimension -> size: the grid's axes, then the outputs' extra dimensions.
    status : dict
        Status code -> number of points, counted chunk by chunk (:meth:`status_names` by name).
    wall_time_s : float
        ``compile_time_s + compute_time_s``.
    compile_time_s : float
        JIT compilation (or loading the JIT cache) before the chunks.
    compute_time_s : float
        The chunks: kernels and the writes of the journal.
    """

    path: Path
    sizes: dict  # dimension -> size: the grid's axes, then the outputs' extra dimensions
    status: dict  # status code -> number of points, counted chunk by chunk
    wall_time_s: float  # compile_time_s + compute_time_s
    compile_time_s: float = 0.0  # JIT compilation (or loading the JIT cache) before the chunks
    compute_time_s: float = 0.0  # the chunks: kernels and the writes of the journal

    def status_names(self) -> dict[str, int]:
        """Counts by status name ("ok", "max_steps", ...)."""
        return {st.MEANINGS.get(code, str(code)): n for code, n in self.status.items()}


class _ScenePath:
    """The default of ``run(output=...)``: the scene's ``[storage] path``."""

    def __repr__(self) -> str:
        return "<the scene's [storage] path>"


SCENE_PATH = _ScenePath()


def run(
    scene_or_path: str | os.PathLike | Mapping | Scene,
    *,
    output: str | os.PathLike | None | _ScenePath = SCENE_PATH,
    resume: bool = False,
    restart: bool = False,
    threads: int | None = None,
    progress: bool | None = None,
    scheduler: str | None = None,
    load: bool | None = None,
    worker_timeout: float | None = None,
    overwrite: bool = False,
    models: Mapping | None = None,
) -> xr.Dataset:
    """Compute a scene's grid and return its dataset.

    Every grid point is computed by the model's compiled kernels, on all cores (or on a dask
    cluster), and stored chunk by chunk as it finishes, so an interrupted run can be resumed.

    Parameters
    ----------
    scene_or_path : str, os.PathLike, Mapping or Scene
        The scene: a TOML file's path, a dict with the same structure, or a :class:`Scene` from
        :func:`load_scene`.
    output : str, os.PathLike or None, optional
        Where the dataset goes. Default: the scene's ``[storage] path`` (relative to the working
        directory; its folder is created when missing). ``None``: the in-memory route, nothing
        written (no file, journal or lock; the values are bitwise those the file route stores;
        ``resume``, ``restart``, ``overwrite``, ``load`` and a scheduler do not apply to it and are
        refused).
    resume : bool, optional
        Complete an unfinished run of the same scene (``<path>.partial``), computing only its
        missing chunks.
    restart : bool, optional
        Discard an unfinished run of the scene and start over.
    threads : int, optional
        numba's thread count (default: all cores; on a dask cluster: per worker, at most its
        cores).
    progress : bool, optional
        Show a progress bar (default: only when stderr is a terminal).
    scheduler : str, optional
        A dask.distributed scheduler's address (or the scene's ``[execution] scheduler``): run the
        chunks on that cluster instead of here.
    load : bool, optional
        True: the returned dataset is in memory; False: opened lazily; None (default): loaded when
        it is at most ``store.LOAD_LIMIT_BYTES``.
    worker_timeout : float, optional
        On a cluster (or ``[execution] worker_timeout``): seconds to wait for a lost scheduler or
        with no worker before the run stops with its journal kept.
    overwrite : bool, optional
        Replace an existing ``output`` that holds another scene's dataset or a file mechsweep did
        not write (by default only a re-run of the same scene replaces its dataset).
    models : Mapping, optional
        Model name -> :class:`~mechsweep.model.OdeModel` (or a ``ModelSpec``) defined in Python, for
        a scene whose ``model`` is that name. Such a model lives only in this process: it runs
        locally (a dask cluster is refused; name the model as ``"file.py:NAME"`` or
        ``"package.module:NAME"`` in the scene for that).

    Returns
    -------
    xarray.Dataset
        One dimension per axis, the requested outputs with their units and long names, ``status``
        per point (and ``n_steps``, ``n_rhs`` for integrated outputs), the scene, solver settings
        and provenance in the attributes. ``compile_time_s`` (compiling the kernels, or loading them
        from the JIT cache, before the first chunk; 0 when this process compiled them already; on a
        dask cluster the workers compile inside their first chunk, counted as compute),
        ``compute_time_s`` (the chunks) and ``wall_time_s`` (their sum) say how long it took.

    Raises
    ------
    SceneError
        The scene is not valid (nothing is run or written).
    StoreError
        The output path cannot be written, or holds what the run may not replace.
    OutOfSpace
        A write failed (disk full, file-size limit): the journal is kept; resume with ``resume=True``.
    RunInterrupted
        SIGINT or SIGTERM (when run in the main thread): the finished chunks are kept.
    ClusterLost
        The dask scheduler was lost, or had no worker for ``worker_timeout`` seconds.

    See Also
    --------
    compute : the same without opening the result (status counts and sizes only).
    open_dataset : read a stored dataset.

    Examples
    --------
    >>> import mechsweep
    >>> ds = mechsweep.run("sweeps/quickstart.toml", output=None)      # doctest: +SKIP
    >>> float(ds.period.sel(A=1.0, mu=1.0, method="nearest"))          # doctest: +SKIP
    4.768022029112...
    """
    if output is None:
        return _run_in_memory(scene_or_path, resume=resume, restart=restart, threads=threads, progress=progress,
                              scheduler=scheduler, load=load, worker_timeout=worker_timeout, overwrite=overwrite,
                              models=models)
    if isinstance(output, _ScenePath):
        output = None
    lazy = None if load is None else not load
    summary, memory = _compute_file(scene_or_path, output=output, resume=resume, restart=restart, threads=threads,
                                    progress=progress, scheduler=scheduler, worker_timeout=worker_timeout,
                                    overwrite=overwrite, models=models, keep=load)
    if memory is not None and (load or summary.path.stat().st_size <= LOAD_LIMIT_BYTES):
        # the dataset the file holds, computed into memory as it was written: not read back (store.MemorySink)
        return memory.dataset()
    return open_dataset(summary.path, lazy=lazy)


def compute(
    scene_or_path: str | os.PathLike | Mapping | Scene,
    *,
    output: str | os.PathLike | None = None,
    resume: bool = False,
    restart: bool = False,
    threads: int | None = None,
    progress: bool | None = None,
    scheduler: str | None = None,
    worker_timeout: float | None = None,
    overwrite: bool = False,
    models: Mapping | None = None,
) -> RunSummary:
    """Compute a scene into its file without opening the result.

    The same as :func:`run` (same parameters, except ``load``; the output must be a file), for grids
    too large to hold: memory stays bounded by the chunk, whatever the grid, and the status counts
    are added up as the chunks are assembled.

    Parameters
    ----------
    scene_or_path : str, os.PathLike, Mapping or Scene
        The scene, as for :func:`run`.
    output : str or os.PathLike, optional
        The dataset's path (default: the scene's ``[storage] path``).
    resume, restart, overwrite : bool, optional
        As for :func:`run`.
    threads : int, optional
        numba's thread count (default: all cores).
    progress : bool, optional
        Show a progress bar (default: only when stderr is a terminal).
    scheduler : str, optional
        A dask.distributed scheduler's address, as for :func:`run`.
    worker_timeout : float, optional
        On a cluster: seconds to wait for a lost scheduler or with no worker.
    models : Mapping, optional
        Model name -> a model defined in Python, as for :func:`run`.

    Returns
    -------
    RunSummary
        The path written, the dimensions' sizes, the number of points of each status and the
        run's times.
    """
    return _compute_file(scene_or_path, output=output, resume=resume, restart=restart, threads=threads,
                         progress=progress, scheduler=scheduler, worker_timeout=worker_timeout, overwrite=overwrite,
                         models=models, keep=False)[0]


def _compute_file(scene_or_path, *, output, resume, restart, threads, progress, scheduler, worker_timeout, overwrite,
                  models, keep: bool | None) -> tuple[RunSummary, MemorySink | None]:
    """``compute``, and with ``keep`` (True, or None for a dataset of at most store.LOAD_LIMIT_BYTES)
    the dataset in memory, filled as the file is written (store.MemorySink; None when the run computed
    nothing: a resume that found it finished)."""
    if resume and restart:
        raise InputError("resume and restart (--resume --restart) together are refused: --resume keeps the "
                         "finished chunks of an unfinished run, --restart discards them; choose one")
    if models is not None and not isinstance(models, Mapping):
        raise InputError(f"models must be a mapping of model name -> OdeModel, got {type(models).__name__}")
    scene = scene_or_path if isinstance(scene_or_path, Scene) else load_scene(scene_or_path, models=models)
    _warn_settings(scene)
    if output is not None and str(output).endswith(("/", os.sep)):
        raise StoreError(f"output path {output} ends with a path separator; give a file path such as "
                         f"{Path(output) / 'run.h5'}")
    final = Path(output if output is not None else scene.storage.path)
    # the scene's default folder (data/runs/ relative to the working directory) is created when
    # missing; a folder given with output= must exist (a typo there is refused, not created)
    make_folder = output is None and not os.path.lexists(final.parent)
    check_target(final, create_folder=make_folder)
    check_output_place(final)
    if scheduler is not None and (why := check_scheduler(scheduler)) is not None:
        raise InputError(f"scheduler {why}")
    scheduler = scheduler if scheduler is not None else scene.execution.scheduler
    if scheduler and models and _from_python(scene, models):
        raise InputError(f"model {scene.model.name!r} was given from Python (models=...); a dask worker cannot "
                         "import it: name it in the scene as 'file.py:NAME' or 'package.module:NAME' to run it "
                         f"on the cluster {scheduler}, or run without a scheduler")
    check_threads(threads, here=scheduler is None)  # before any file is created
    if worker_timeout is not None and (why := check_worker_timeout(worker_timeout)) is not None:
        raise InputError(f"worker timeout {why}")
    worker_timeout = worker_timeout if worker_timeout is not None else scene.execution.worker_timeout
    # Without a progress bar the grid is not cut into at least 20 chunks (grid.default_chunk_target:
    # small chunks cost the lane kernel CPU); an unfinished run is resumed with its own cut.
    target = _journal_target(scene, final) if resume else None
    target = target or chunk_target(scene, many=shows_progress(progress))
    check_size(scene, final, min(target, scene.n_points), saved_bytes(final) if not restart else 0)
    check_file_limit(scene, final)
    # Conflicts are refused before the lock (taking it touches the folder), and checked again
    # under it: another run may have changed the files meanwhile.
    RunLock(final).refuse_if_held()
    plan = make_plan(scene, target)  # what to compute and how, decided once for every chunk
    chunks = plan.chunks
    finished = _check_existing(scene, final, resume, restart, target, len(chunks), overwrite)
    # A cluster that does not answer is refused here, before the lock and the journal exist.
    client = _connect(scheduler) if scheduler and not finished else None
    if make_folder:  # every check passed: only now is anything created
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            if client is not None:
                _disconnect(client)
            raise StoreError(f"cannot create the folder {final.parent} for output {final}: "
                             f"{why_os_error(exc.errno, exc.strerror)}") from None
    try:
        with _Signals() as signals:
            try:
                with RunLock(final):  # from here to the end, no other run touches final or its journal
                    clear_discard(final)  # what a killed clean-up left
                    before = _output_state(final)  # what the checks accept is what the dataset may replace
                    if not _check_existing(scene, final, resume, restart, target, len(chunks), overwrite):
                        keep = keep or keep is None and bytes_per_point(scene) * scene.n_points <= LOAD_LIMIT_BYTES
                        try:
                            counts, memory = _compute(plan, final, restart, threads, progress, scheduler, signals,
                                                      worker_timeout, client, keep, before)
                        except Exception as exc:  # a failure after the checks: keep no journal without a chunk
                            if not isinstance(exc, (WriteFailed, ClusterLost)):
                                _failed(exc, final)
                            raise
                    else:  # True: a resume found the run finished
                        counts, memory = status_counts(final), None
                    # the times the file was given: from the dataset in memory when there is one
                    # (the same floats; store._assemble), else read back from the file
                    times = _times(final) if memory is None else _memory_times(memory)
            except WriteFailed as exc:
                raise OutOfSpace(_out_of_space(exc, scene, final, len(chunks))) from None
            except ClusterLost as exc:
                raise ClusterLost(f"{exc}; {_kept(final)}") from None
            except KeyboardInterrupt:
                raise RunInterrupted(_interrupted(final, signals.signum or signal.SIGINT),
                                     signals.signum or signal.SIGINT) from None
    finally:
        if client is not None:
            _disconnect(client)
    return RunSummary(final, _sizes(scene), counts, *times), memory


def _warn_settings(scene: Scene) -> None:
    """A SettingsWarning for each of the scene's accepted but suspicious solver settings."""
    import warnings

    from .errors import SettingsWarning
    from .scene import solver_warnings

    for text in solver_warnings(scene):
        warnings.warn(text, SettingsWarning, stacklevel=4)


def _journal_target(scene: Scene, final: Path) -> int | None:
    """The chunk target of the unfinished run of ``final`` when the scene sets no chunk_size (the
    default cut depends on the progress bar and on the version), None otherwise: a resumed run
    computes exactly the chunks its journal is cut into."""
    part = partial_path(final)
    if scene.storage.chunk_size or not part.is_dir():
        return None
    try:
        check_journal_files(part)  # (a pipe for run.json would block the reading)
        meta = Journal.read(part).meta
    except (StoreError, OSError):
        return None  # _check_existing says what is wrong with it
    target = meta.get("chunk_target") if isinstance(meta, dict) else None
    if isinstance(target, bool) or not isinstance(target, int) or target < 1:
        return None
    from .grid import MAX_CHUNKS

    return target if len(plan_chunks(scene.shape, target)) <= MAX_CHUNKS else None


def _run_in_memory(scene_or_path, *, resume, restart, threads, progress, scheduler, load, worker_timeout,
                   overwrite, models) -> xr.Dataset:
    """``run(output=None)``: the route of every run into a sink in memory (store.MemorySink, described
    by the code that describes a file, store._define), computed here by the kernels the file route
    uses (a point's result does not depend on the chunk it is in: bitwise the values the file route
    stores). Nothing is written: no file, journal, lock or folder, and no signal handler is installed
    (Ctrl-C raises KeyboardInterrupt; nothing is kept)."""
    from .store import time_attrs

    given = [name for name, value in (("resume", resume), ("restart", restart), ("overwrite", overwrite))
             if value] + [name for name, value in (("load", load), ("scheduler", scheduler),
                                                    ("worker_timeout", worker_timeout)) if value is not None]
    if given:
        raise InputError(f"output=None (the in-memory route) computes here and writes nothing: {', '.join(given)} "
                         "does not apply to it; give an output path to use it")
    if models is not None and not isinstance(models, Mapping):
        raise InputError(f"models must be a mapping of model name -> OdeModel, got {type(models).__name__}")
    scene = scene_or_path if isinstance(scene_or_path, Scene) else load_scene(scene_or_path, models=models)
    _warn_settings(scene)
    if scene.execution.scheduler:
        raise InputError(f"output=None (the in-memory route) runs here; the scene's [execution] scheduler "
                         f"{scene.execution.scheduler} is not used by it: give an output path to run on the cluster")
    check_threads(threads)
    need = _memory_bytes(scene)
    available = _available_memory()
    if available is not None and need > available:
        raise StoreError(f"the dataset of {scene.n_points:,} points would need about {_size(need)} of memory, "
                         f"{_size(available)} is available; give an output path (the file route keeps memory "
                         "bounded by a chunk) or make the grid coarser")
    # Without a progress bar to feed, chunks only bound the scratch memory: as few as that allows
    # (each chunk is one parallel launch, costly on a busy machine). Results do not depend on the cut.
    target = chunk_target(scene)
    if not (shows_progress(progress) or scene.storage.chunk_size):
        target = max(target, min(scene.n_points, _values_bound(scene)))
    plan = make_plan(scene, target)
    memory = MemorySink(scene, layout(scene, len(plan.chunks)), provenance(plan))
    with execute.threads(threads):
        threads_used = _jit.num_threads()
        compile_s = _route(plan, list(plan.chunks), memory, progress=progress)
    compute_s = sum(seconds for seconds, _ in memory.times.values())
    memory.store.attrs.update({"execution": f"local, {threads_used} threads", "threads": threads_used})
    memory.store.attrs.update(time_attrs(compile_s, compute_s))
    return memory.dataset()


def _values_bound(scene: Scene) -> int:
    """Points whose computed values fill grid.CHUNK_VALUES (the largest default chunk)."""
    from .grid import CHUNK_VALUES

    per_point = sum(int(np.prod(extra_shape(scene, name), dtype=np.int64)) for name in scene.computed_outputs)
    return max(1, CHUNK_VALUES // max(1, per_point))


def _memory_bytes(scene: Scene) -> int:
    """Memory of an in-memory dataset: its variables, and the chunk being computed."""
    return bytes_per_point(scene) * scene.n_points + CHUNK_MEMORY_FACTOR * bytes_per_point(scene) * min(
        chunk_target(scene), scene.n_points)


def _from_python(scene: Scene, models: Mapping) -> bool:
    """Whether the scene's model is one of ``models`` (given from Python, not importable elsewhere)."""
    from .model.user import from_object

    for name, obj in models.items():
        try:
            if scene.model is obj or scene.model is from_object(name, obj):
                return True
        except InputError:
            continue
    return False


def _sizes(scene: Scene) -> dict:
    lay = layout(scene, 0)
    sizes = dict(zip(lay.dims, lay.shape))
    for dims in lay.extra.values():
        for dim, values in dims:
            sizes.setdefault(dim.name, len(values))
    return sizes


def _memory_times(memory: MemorySink) -> tuple[float, float, float]:
    """(wall, compile, compute) seconds, as _times reads them from the file, from the dataset in
    memory (store._assemble gives it the file's attributes)."""
    attrs = memory.store.attrs
    return float(attrs["wall_time_s"]), float(attrs["compile_time_s"]), float(attrs["compute_time_s"])


def _times(final: Path) -> tuple[float, float, float]:
    """(wall, compile, compute) seconds stored with a dataset (compile 0 and compute = wall for a
    dataset written before they were stored apart)."""
    import h5py

    with h5py.File(final, "r") as f:
        wall = float(np.ravel(f.attrs["wall_time_s"])[0])
        compile_s = float(np.ravel(f.attrs.get("compile_time_s", 0.0))[0])
        compute_s = float(np.ravel(f.attrs.get("compute_time_s", wall))[0])
    return wall, compile_s, compute_s


def _interrupted(final: Path, signum: int) -> str:
    return f"interrupted ({signal.Signals(signum).name}): {_kept(final)}"


def _failed(exc: Exception, final: Path) -> None:
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
        exc.add_note(f"mechsweep: the run failed after its checks passed; {_kept(final)}, or with --restart to "
                     "discard it")


def _kept(final: Path) -> str:
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


def _out_of_space(exc: WriteFailed, scene: Scene, final: Path, n_chunks: int) -> str:
    """The message of a failed write, by its cause: for a lack of room (no space, no inode, a quota,
    the file-size limit) how much the run still needs; for another cause (a folder removed or made
    read-only during the run, an I/O error) what happened; and what is kept, and how to go on."""
    from .errors import why_write_failed

    code = exc.errno
    failed = f"writing {exc.path} failed"
    folder = final.parent
    if code == errno.ENOENT:
        return _removed_during_run(final, failed)
    if code not in (errno.ENOSPC, getattr(errno, "EDQUOT", None), errno.EFBIG):
        kept = _kept(final)
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
    kept = _kept(final)
    reason = why_write_failed(code, exc.strerror)
    soft = _file_size_limit()
    free, inodes, total_inodes = _room(folder)
    short_of_inodes = total_inodes and inodes is not None and inodes < files + 1
    if code == errno.EFBIG and soft is not None:
        need_text = f"the limit is {_mib(soft)}, the dataset needs up to {_mib(data)}"
    elif code == errno.ENOSPC and short_of_inodes and (free is None or free >= need):
        # a file system that ran out of inodes (file entries) says ENOSPC too, with space to spare
        return (f"out of inodes (file entries), not of space: the file system of {_resolved(folder)} has {inodes} of "
                f"{total_inodes} inodes free (and {_mib(free) if free is not None else 'enough'} of space); the run "
                f"still needs about {files} more files (one per chunk to come, and the dataset): delete files there "
                f"or write elsewhere with -o; {failed}; {kept}")
    elif code == errno.ENOSPC and short_of_inodes:
        need_text = (f"{_mib(need)} and about {files} more files needed on the disk of {_resolved(folder)} (it is out "
                     f"of space and of inodes: {inodes} of {total_inodes} free)")
    elif code == getattr(errno, "EDQUOT", None):  # a quota counts blocks, and often files too
        need_text = f"{_mib(need)} and about {files} more files needed within your quota on the disk of {_resolved(folder)}"
    else:
        need_text = f"{_mib(need)} needed on the disk of {_resolved(folder)}"
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
        return (f"a file of the run was removed while it was being written (ENOENT): {failed}; {_kept(final)}")
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
        v = os.statvfs(_existing_ancestor(folder))
    except OSError:
        return None, None, None
    return v.f_bavail * v.f_frsize, v.f_favail, v.f_files


def _resolved(folder: Path) -> Path:
    try:
        return folder.resolve()
    except OSError:
        return folder


def _mib(n: float) -> str:
    return f"{n / 2**20:.3g} MiB"


def _connect(scheduler: str):
    from .cluster import connect

    return connect(scheduler)


def _disconnect(client) -> None:
    from .cluster import disconnect

    disconnect(client)


def _check_existing(scene: Scene, final: Path, resume: bool, restart: bool, target: int, n_chunks: int,
                    overwrite: bool = False) -> bool:
    """Refuse what would mix runs or lose results: an unfinished run without --resume/--restart,
    a resume with another scene, an existing dataset of another scene (or a file mechsweep did
    not write) without ``overwrite``. True when ``resume`` finds the run already finished."""
    part = partial_path(final)
    if (why := own_files_problem(final)) is not None:  # a user's file in the journal: never removed
        raise StoreError(why)
    check_journal_files(part, contents=not restart)  # --restart discards what the folder holds
    if part.exists() and not (resume or restart):
        raise StoreError(f"an unfinished run of this output exists: {part}; continue it with --resume "
                         "or discard it with --restart")
    same = _holds_same_scene(final, scene, overwrite)  # None: no dataset there (or an empty file)
    if resume and not part.exists() and same:
        if (why := _dataset_sources_changed(final, scene)) is not None:
            raise StoreError(why)
        return True
    if part.exists() and not restart:
        journal = Journal.read(part)
        canonical = scene.canonical()
        if not journal.empty and same_scene({"scene_canonical": journal.meta["scene_canonical"],
                                             "scene": journal.meta.get("scene"),
                                             "scene_folder": journal.meta.get("attrs", {}).get("scene_folder")},
                                            scene):
            canonical = journal.meta["scene_canonical"]  # the same scene, perhaps in an older version's form
        if not journal.empty and (why := journal.matches(canonical, target, n_chunks)) is not None:
            raise StoreError(why)
        if not journal.empty and (why := _journal_attrs_problem(journal, scene)) is not None:
            raise StoreError(why)
        if not journal.empty and (why := _journal_sources_changed(journal, scene)) is not None:
            raise StoreError(why)  # the same scene, but its model's code changed since the run began
    return False


def _journal_attrs_problem(journal: Journal, scene: Scene) -> str | None:
    """Why the attributes an unfinished run's journal gives its dataset do not describe ``scene``
    (its run.json edited; a journal of format 2 has no checksum to tell), or None: the model, the
    outputs and the solver settings, which the scene determines."""
    import json

    attrs = journal.meta["attrs"]
    expected = {"model": scene.model.name, "outputs": " ".join(scene.outputs)}
    if scene.solver is not None:
        expected.update({f"solver_{k}": v for k, v in scene.solver.as_dict().items()})
    expected = json.loads(json.dumps(expected))  # as run.json holds them
    for key in sorted(set(expected) | {k for k in attrs if k.startswith("solver_")}):
        if key not in attrs or key not in expected or attrs[key] != expected[key]:
            stored = repr(attrs[key]) if key in attrs else "missing"
            wanted = repr(expected[key]) if key in expected else "none"
            return (f"{journal.folder / 'run.json'} gives the dataset the attribute {key} = {stored}, the scene "
                    f"{wanted}: the journal was edited; {RESTART}")
    return None


def _journal_sources_changed(journal: Journal, scene: Scene) -> str | None:
    """Why the unfinished run ``journal`` cannot be resumed with the model's current sources (the
    model file, the user modules it imports, the packages they use, mechsweep: model/sources.py), or
    None when they are those it began with. A journal that records none (written by a version before
    the record) is refused too: what its chunks were computed from cannot be checked."""
    from .model import sources

    attrs = journal.meta.get("attrs") if isinstance(journal.meta, dict) else None
    stored = attrs.get("dependencies") if isinstance(attrs, dict) else None
    if stored is None:
        version = attrs.get("mechsweep_version", "?") if isinstance(attrs, dict) else "?"
        return (f"{journal.folder} was started by mechsweep {version}, which did not record the sources its "
                "results depend on (the model file, the modules it imports, mechsweep's own): its chunks cannot "
                "be checked against the current ones; start over with --restart")
    changed = sources.differences(stored, sources.record(scene.model), scene.base or None)
    if not changed:
        return None
    return (f"cannot resume {journal.folder}: {'; '.join(changed)}; start over with --restart, or restore "
            f"{'them' if len(changed) > 1 else 'it'} and resume")


def _dataset_sources_changed(final: Path, scene: Scene) -> str | None:
    """Why ``--resume`` cannot take the finished dataset ``final`` as this run's result: it was
    computed from other sources than the model's current ones (None: the same, or a dataset of a
    version that recorded none, which is taken as it is: nothing is computed)."""
    import h5py

    from .model import sources

    try:
        with h5py.File(final, "r") as f:
            stored = _attr_text(f.attrs["dependencies"]) if "dependencies" in f.attrs else None
    except Exception:  # damaged internals were refused by _holds_same_scene's check already
        return None
    if stored is None:
        return None
    changed = sources.differences(stored, sources.record(scene.model), scene.base or None,
                                  since="this dataset was computed")
    if not changed:
        return None
    return (f"{final} is finished, but computed from other sources: {'; '.join(changed)}; compute it again "
            f"with `mechsweep run` without --resume (the dataset is replaced), or restore "
            f"{'them' if len(changed) > 1 else 'it'}")


def _holds_same_scene(final: Path, scene: Scene, overwrite: bool) -> bool | None:
    """Whether the dataset at ``final`` is a run of ``scene``; None when there is no dataset
    (absent or an empty file). A dataset of another scene, or a file that is not a mechsweep
    dataset, is refused unless ``overwrite`` (then False)."""
    if not final.exists() or final.stat().st_size == 0:
        return None
    try:
        same = _stored_same_scene(final, scene)
    except FileBusy as exc:  # never replaced, whatever the flags: that process's writes would be lost
        raise FileBusy(final, exc.holder, doing="a run would replace it and the writes of that process "
                       "would be lost: wait until it closes the file (or stop it), or write elsewhere with -o") from None
    except StoreError as exc:
        if overwrite:
            return False
        raise StoreError(f"{exc}; a run would replace it: use --overwrite to replace it anyway, "
                         "or choose another path with -o") from None
    if same is None and not overwrite:
        raise StoreError(f"{final} is a mechsweep benchmark dataset, not a run; use --overwrite to replace it, "
                         "or choose another path with -o")
    if same is False and not overwrite:
        raise StoreError(f"{final} holds a finished run of a different scene (model, outputs, axes, fixed "
                         "values or solver settings differ); use --overwrite to replace it, or choose "
                         "another path with -o")
    return bool(same)


def _stored_same_scene(final: Path, scene: Scene) -> bool | None:
    """Whether the dataset at ``final`` is a run of ``scene`` (None: a benchmark's dataset), from its
    attributes alone (read with h5py: a re-run does not pay for opening the dataset with xarray).
    StoreError when it is not a dataset mechsweep wrote."""
    import h5py

    from .store import RUN_ATTRS, check_dataset_file, is_lock_error, lock_holder

    check_dataset_file(final)  # a regular HDF5 file with a run's (or a benchmark's) attributes
    try:
        with h5py.File(final, "r") as f:
            keys = ("scene_canonical", "scene", "scene_folder") + RUN_ATTRS
            attrs = {k: _attr_text(f.attrs[k]) for k in keys if k in f.attrs}
            run = all(a in attrs for a in RUN_ATTRS) and "status" in f
    except Exception as exc:  # damaged internals: as check_dataset_file says it
        if is_lock_error(exc):  # another process opened it for writing since check_dataset_file
            raise FileBusy(final, lock_holder(final)) from None
        raise StoreError(f"{final} is not a mechsweep dataset: it is an HDF5 file that cannot be read "
                         f"({str(exc).splitlines()[0][:200] if str(exc) else type(exc).__name__})") from None
    return same_scene(attrs, scene) if run else None


def _attr_text(value):
    if isinstance(value, bytes):
        return value.decode(errors="replace")
    if isinstance(value, np.ndarray) and value.size == 1:
        return _attr_text(value.ravel()[0])
    return value


def same_scene(attrs: Mapping, scene: Scene) -> bool:
    """Whether a dataset's attributes describe a run of ``scene``: its stored canonical form equals
    the scene's, or its stored scene text, read by this version, has the same canonical form
    (the form may change between versions; the text stays the user's)."""
    if scene.same_as(attrs.get("scene_canonical")):
        return True
    text = attrs.get("scene")
    if not isinstance(text, str):
        return False
    try:
        return load_scene_text(text, label="stored scene", base=attrs.get("scene_folder") or None,
                               ).canonical() == scene.canonical()
    except InputError:
        return False


def _compute(plan: Plan, final: Path, restart: bool, threads, progress, scheduler, signals: "_Signals",
             worker_timeout: float, client=None, keep: bool = False, before: tuple | None = None
             ) -> tuple[dict[int, int], MemorySink | None]:
    """The route into the file sink: compute the missing chunks into the journal, then assemble the
    dataset; returns the points per status code, and with ``keep`` the dataset in memory, filled as
    the file was written (store.MemorySink). Chunk files that do not verify (found now, or while
    assembling) are removed and computed again. ``client``: a connected dask client when ``scheduler``
    is given. ``before``: what was at ``final`` when the checks passed (``_output_state``), the only
    file the dataset replaces besides a dataset of the same scene."""
    scene, chunks = plan.scene, plan.chunks
    part = partial_path(final)
    journal = Journal.read(part) if part.exists() and not restart else None
    resumed = journal is not None and not journal.empty
    if journal is None or journal.empty:  # none, discarded, or killed before its first word
        drop(final)
        journal = Journal.create(part, canonical=scene.canonical(), text=scene.text, chunk_target=plan.chunk_target,
                                 n_chunks=len(chunks), attrs=provenance(plan))
    lay = layout(scene, len(chunks))
    memory = MemorySink(scene, lay, journal.meta["attrs"]) if keep else None
    for _ in range(REPAIR_ROUNDS):
        done = journal.done_chunks(repair=True)
        _report_removed(journal)
        todo = [chunks[int(i)] for i in np.flatnonzero(~done)]  # at most grid.MAX_CHUNKS
        early = None
        try:
            with execute.threads(None if scheduler else threads):
                where = (f"dask scheduler {scheduler}, {threads or 'all'} numba threads per worker" if scheduler
                         else f"local, {_jit.num_threads()} threads")
                # the plan computing now (a resumed run's journal holds the plan it began with)
                attrs = {**journal.meta["attrs"], "plan": plan.text(), "execution": where}
                if not scheduler:
                    attrs["threads"] = _jit.num_threads()
                # A fresh run that returns its dataset (memory) writes its file while the chunks are
                # computed (store.Early: the writer thread, overlapping the kernels); a resumed
                # one (its history says when it was finished) is assembled at the end.
                if memory is not None and todo and not resumed and not done.any():
                    early = Early(journal.folder / ASSEMBLY, scene, lay, attrs)
                _route(plan, todo, _FileSink(journal, memory, early), progress=progress, scheduler=scheduler,
                       threads=threads, client=client, worker_timeout=worker_timeout, signals=signals)
                if resumed and todo:  # the history says that another run finished the dataset
                    now = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
                    attrs["history"] = (attrs.get("history", "") + "\n" + cf.history(
                        now, f"mechsweep.run(scene {scene.name!r}, resume=True): {len(todo)} chunk(s) computed",
                        __version__))
            bad, counts = _finish(journal, scene, chunks, final, attrs, signals, memory, early, before)
        except BaseException:
            if early is not None:  # interrupted or failed: no half-written file is left in the journal
                early.discard()
            raise
        if not bad:
            return counts, memory
        for exc in bad:
            journal.discard(exc.path, exc.why)
        _report_removed(journal)
    raise RunError(f"chunk files in {journal.chunks} were found damaged again after {REPAIR_ROUNDS} rounds of "
                     "computing them anew; the disk may be failing: check it, then run again with --resume")


class _FileSink:
    """The sink of a run with an output file: each chunk saved to the journal (crash-safe, resumable),
    and, for a run that returns its dataset, kept in memory (``memory``: the chunk was computed into its
    arrays) and written into the dataset's file at once (``early``, store.Early)."""

    background = True  # journal and HDF5 writes run in a writer thread, beside the next chunk's kernel

    def __init__(self, journal: Journal, memory: MemorySink | None = None, early: Early | None = None):
        self.journal, self.memory, self.early = journal, memory, early

    def views(self, chunk: Chunk) -> dict | None:
        return self.memory.views(chunk) if self.memory is not None else None

    def prepare(self, launches) -> None:
        """In the writer thread before the first chunk arrives: define the early file."""
        if self.early is not None:
            self.early.prepare(launches)

    def save(self, chunk: Chunk, arrays: dict, seconds: float) -> None:
        self.journal.write_chunk(chunk.index, arrays, seconds)
        if self.memory is not None:  # saved: kept for the dataset run() returns
            self.memory.save(chunk, arrays, seconds)
        if self.early is not None:  # and into the dataset's file, while the next chunk is computed
            self.early.write(chunk.index, chunk.region, arrays)


def _route(plan: Plan, todo: list[Chunk], sink, *, progress, scheduler: str | None = None, threads=None,
           client=None, worker_timeout: float | None = None, signals: "_Signals | None" = None) -> float:
    """Every run's route from its plan to its sink: the chunks ``todo`` computed here (execute.py: the
    kernels compiled or loaded first, timed apart) or on the dask cluster ``scheduler`` (cluster.py,
    the same evaluate_chunk), each saved to ``sink`` as it arrives. Returns the compile phase's seconds."""
    local = scheduler is None
    compile_s = execute.warm_up(plan, progress, todo[0]) if todo and local else 0.0
    launches = execute.Launches() if local else None
    if local:
        results = execute.local_results(plan, todo, launches, sink.views)
    else:
        from .cluster import dask_results

        results = dask_results(plan, todo, scheduler, threads, worker_timeout=worker_timeout, client=client)
    # a local run acts on Ctrl-C or SIGTERM once the chunk being computed is saved; a cluster's run at once
    # (closing its results cancels the tasks in flight)
    _save_chunks(plan, sink, results, plan.n_points - sum(c.size for c in todo), progress, compile_s, launches,
                 signals if local else None)
    return compile_s


def _report_removed(journal: Journal) -> None:
    for line in journal.removed:
        print(f"mechsweep: chunk file {line}: removed, it is computed again", file=sys.stderr)
    journal.removed = []


# The dataset is written here, in the journal folder, and renamed into place when complete.
ASSEMBLY = "assembly.h5"


def _finish(journal: Journal, scene: Scene, chunks, final: Path, attrs: dict,
            signals: "_Signals", memory: MemorySink | None = None, early: Early | None = None,
            before: tuple | None = None) -> tuple[list[BadChunk], dict[int, int]]:
    """Assemble the dataset next to the journal (or complete ``early``, the file written while the
    chunks were computed), move it into place by one rename, drop the journal. Signals wait until a
    chunk is written (the files are closed before the run stops). Returns the chunk files that did
    not verify (then nothing is moved into place) and the points per status. What is at ``final``
    is checked again right before the rename (``_placing_problem``): a file that appeared there
    while the run computed is not replaced (StoreError, the journal kept)."""
    tmp = journal.folder / ASSEMBLY
    if early is not None and early.usable(tmp, memory):  # most of the file is on the disk already
        check_free_space(scene, tmp, early.path.stat().st_size)
    else:
        check_free_space(scene, tmp)
    with signals.deferred():
        bad, counts = assemble(journal, scene, layout(scene, len(chunks)), chunks, tmp, attrs,
                               stop=signals.pending, memory=memory, early=early)
        if bad:
            os.unlink(tmp)
            return bad, counts
        if (why := _placing_problem(final, scene, before)) is not None:
            os.unlink(tmp)
            raise StoreError(why)
        try:
            os.replace(tmp, final)
        except OSError as exc:
            os.unlink(tmp)
            raise WriteFailed(final, exc) from None
        if left := drop(final):
            print(f"mechsweep: the dataset is in place; entries a run does not write were left as they are ("
                  f"{'; '.join(left[:5])}{' ...' if len(left) > 5 else ''}): move them away (a run of {final} "
                  "refuses to start until then)", file=sys.stderr)
    return [], counts


def _output_state(final: Path) -> tuple | None:
    """What is at ``final`` (the entry itself, a link not followed: device, inode, kind, size, times),
    None when nothing is."""
    try:
        s = os.lstat(final)
    except (FileNotFoundError, NotADirectoryError):
        return None
    return (s.st_dev, s.st_ino, s.st_mode, s.st_size, s.st_mtime_ns, s.st_ctime_ns)


def _placing_problem(final: Path, scene: Scene, before: tuple | None) -> str | None:
    """Why the finished dataset may not replace what is at ``final`` now, or None: nothing there,
    what the checks accepted when the run started (``before``), or a dataset of the same scene
    (the same values). Anything else came while the run computed (a file, a link, a folder, a
    dataset of another scene) and is not the run's to replace, whatever --overwrite said about the
    file of the start."""
    now = _output_state(final)
    if now is None or now == before:
        return None
    mode = now[2]
    if stat.S_ISREG(mode):
        try:
            same = _stored_same_scene(final, scene)
        except StoreError as exc:
            what = str(exc).replace(f"{final} is ", "", 1)
        else:
            if same:
                return None
            what = ("a mechsweep benchmark dataset" if same is None else
                    "a dataset of a different scene")
    else:
        what = "a symbolic link" if stat.S_ISLNK(mode) else file_kind(mode)
    part = partial_path(final)
    return (f"{final} {'appeared' if before is None else 'changed'} while the run computed ({what}); a run replaces "
            "only the file its checks accepted when it started, or a dataset of the same scene, so it was left as "
            f"it is. The finished chunks are kept in {part}: move {final} away, then run again with --resume (it "
            "only assembles the dataset)")


def check_output_place(final: Path) -> None:
    """Refuse an output inside a run's journal folder (``NAME.partial/``, or ``NAME.partial.discard/``
    being deleted), where the run of NAME would find a file it did not write, or named as the
    journal or lock of another output (``NAME.partial``, ``.NAME.lock``: that output's run would
    take it for its own). Links are followed: the folder the file would be in counts."""
    suffixes = (".partial", ".partial.discard")
    folder = Path(os.path.realpath(final.parent))
    for f in (folder, *folder.parents):
        if f.name.endswith(suffixes):
            owner = f.name[:-len(".partial")] if f.name.endswith(".partial") else f.name[:-len(".partial.discard")]
            raise StoreError(f"output path {final} is inside {f}, the journal folder of an unfinished run of "
                             f"{f.parent / owner} (a run keeps its finished chunks there and removes the folder "
                             "when it ends); choose another path with -o")
    name = final.name
    if name.endswith(suffixes) or (name.startswith(".") and name.endswith(".lock") and len(name) > len("..lock")):
        raise StoreError(f"output path {final}: a name ending in .partial or .partial.discard, or of the form "
                         ".NAME.lock, is the one mechsweep gives the journal or the lock of another output; "
                         "choose another name")


class _Signals:
    """SIGINT and SIGTERM stop a run the same way (KeyboardInterrupt, the journal kept; the
    signal is in ``signum``). Inside ``deferred()`` a signal is only noted (``pending()`` says
    so), and raised when the block ends, so files being written are closed first. SIGXFSZ is
    ignored, so that a write over the file-size limit fails with EFBIG instead of killing the
    process. Handlers are only installed from the main thread (Python allows no other)."""

    def __init__(self):
        self.signum: int | None = None
        self._defer = 0
        self._previous = {}

    def __enter__(self) -> "_Signals":
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
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


def _file_size_limit() -> int | None:
    """The process's file-size limit in bytes (``ulimit -f``); None when unlimited, or where the
    system has no such limit (no ``resource`` module: Windows)."""
    try:
        import resource
    except ImportError:
        return None
    soft = resource.getrlimit(resource.RLIMIT_FSIZE)[0]
    return None if soft == resource.RLIM_INFINITY else soft


def check_file_limit(scene: Scene, final: Path) -> None:
    """Refuse, before any file is made, a run whose dataset cannot fit under the process's file-size
    limit (``ulimit -f``). Counted are only the float outputs, which are stored uncompressed: the
    dataset is at least that large, so no run that would fit is refused."""
    soft = _file_size_limit()
    if soft is None:
        return
    least = _least_bytes(scene)
    if least > soft:
        raise StoreError(f"file size limit reached (ulimit -f): the dataset {final} needs at least {_mib(least)}, "
                         f"the limit is {_mib(soft)}; raise the limit (ulimit -f unlimited) or make the grid coarser")


def check_free_space(scene: Scene, tmp: Path, written: int = 0) -> None:
    """Before the assembly: refuse at once when the disk cannot hold even the dataset's float
    outputs (a lower bound of its size), less the ``written`` bytes of it already on the disk,
    instead of failing part way."""
    try:
        free = shutil.disk_usage(tmp.parent).free
    except OSError:
        return
    least = _least_bytes(scene) - written
    if least > free:
        raise WriteFailed(tmp, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))


def _least_bytes(scene: Scene) -> int:
    return 8 * scene.n_points * sum(int(np.prod(extra_shape(scene, name), dtype=np.int64)) for name in scene.outputs)


def _existing_ancestor(path: Path) -> Path:
    """The nearest folder (or file) on the way up from ``path`` that exists."""
    path = Path(os.path.abspath(path))
    while not os.path.lexists(path) and path != path.parent:
        path = path.parent
    return path


def check_target(final: Path, create_folder: bool = False) -> None:
    """Refuse an output path that cannot work, before any computation. ``create_folder``: the
    folder of ``final`` is missing and will be created (then its nearest existing ancestor must
    be a writable folder)."""
    if "\0" in str(final):
        raise StoreError(f"output path {str(final)!r} contains a NUL character")
    try:
        name_max = os.pathconf(final.parent if final.parent.is_dir() else ".", "PC_NAME_MAX")
    except (AttributeError, OSError):
        name_max = 255
    longest = len(os.fsencode(discard_path(final).name))  # the longest name a run gives its files
    if longest > name_max:
        raise StoreError(f"file name {final.name[:40]}... is too long: {longest} bytes with the '.partial.discard' "
                         f"suffix a run uses, at most {name_max} allowed")
    try:
        final.stat()
    except (FileNotFoundError, NotADirectoryError):
        pass
    except OSError as exc:  # e.g. a path longer than the system allows, a folder on the way not searchable
        shown = str(final) if len(str(final)) <= 80 else str(final)[:80] + "..."
        raise StoreError(f"output path {shown}: {why_os_error(exc.errno, exc.strerror)}") from None
    if final.is_dir():
        raise StoreError(f"output path {final} is a directory; give a file path such as {final / 'run.h5'}")
    if os.path.lexists(final) and not final.is_file():
        raise StoreError(f"output path {final} is {_kind(final)}, not a regular file; a run writes only a "
                         "new file or replaces a dataset: choose another path with -o")
    for path, want, ok in ((lock_path(final), "a file", os.path.isfile),
                           (discard_path(final), "a folder", os.path.isdir)):
        if os.path.lexists(path) and not ok(path):
            raise StoreError(f"{path} (the run's {'lock' if want == 'a file' else 'journal being deleted'}) is "
                             f"{_kind(path)}, not {want} mechsweep made; move it away or choose another path with -o")
    parent = final.parent
    if create_folder and not os.path.lexists(parent):
        base = _existing_ancestor(parent)
        if not base.is_dir():
            raise StoreError(f"{base} (in output path {final}) is {_kind(base)}, not a folder; the folder {parent} "
                             "cannot be created there: choose another path with -o")
        if not _writable(base):
            raise StoreError(f"cannot create the folder {parent} for output {final}: {base} is not writable "
                             "(permission denied)")
        return
    if parent.exists() and not parent.is_dir():
        raise StoreError(f"{parent} (in output path {final}) is a file, not a folder; choose another path with -o")
    if not parent.is_dir():
        raise StoreError(f"the folder {parent} for output {final} does not exist; create it first "
                         f"(mkdir -p {parent}) or choose another path with -o")
    if not _writable(parent):
        raise StoreError(f"cannot write into {parent}: permission denied (read-only folder)")
    if final.exists() and not _writable(final):
        raise StoreError(f"{final} exists and is read-only")
    if final.is_file() and final.stat().st_size > 0:
        with open(final, "rb") as f:
            magic = f.read(8)
        if magic != b"\x89HDF\r\n\x1a\n":
            raise StoreError(f"{final} exists and is not an HDF5 dataset; it would be overwritten: "
                             "choose another path with -o")


# Memory a chunk needs, in units of its output arrays: the chunk being computed (outputs and the
# model's scratch of the same size, e.g. a simulation's trajectory samples) and the previous
# chunk waiting to be written.
CHUNK_MEMORY_FACTOR = 3


def bytes_per_point(scene: Scene) -> int:
    """Bytes of one grid point before compression: every requested output (with its extra
    dimensions, float64), status (int8), and for integrated outputs n_steps and n_rhs (int64).
    Only the integer variables are compressed, so the file is at most this size per point."""
    values = sum(int(np.prod(extra_shape(scene, name), dtype=np.int64)) for name in scene.outputs)
    return 8 * values + 1 + (16 if scene.solver is not None else 0)


def check_size(scene: Scene, final: Path, chunk_points: int, saved: int) -> None:
    """Refuse, before any file is made, a run whose chunk does not fit the available memory or
    whose files do not fit the free disk space, with the sizes involved. Until the end a run needs
    twice the dataset's size, less the ``saved`` bytes an unfinished run already holds: the journal
    of finished chunks and the dataset assembled from it."""
    per_point = bytes_per_point(scene)
    chunk_need = CHUNK_MEMORY_FACTOR * per_point * chunk_points
    available = _available_memory()
    if available is not None and chunk_need > available:
        raise StoreError(f"a chunk of {chunk_points:,} points would need about {_size(chunk_need)} of memory, "
                         f"{_size(available)} is available; set a smaller [storage] chunk_size "
                         f"(at most {max(1, available // (CHUNK_MEMORY_FACTOR * per_point)):,} points)")
    data = per_point * scene.n_points
    need = max(0, 2 * data - saved)
    free = shutil.disk_usage(_existing_ancestor(final.parent)).free + (final.stat().st_size if final.exists() else 0)
    if need > free:
        raise StoreError(f"the dataset {final} would need {_size(data)} ({scene.n_points:,} points x "
                         f"{_size(per_point)}), and {_size(need)} free until the run ends (its journal of "
                         f"finished chunks and the dataset); its disk has {_size(free)} free; make the grid "
                         "coarser, ask for fewer outputs, or write elsewhere with -o")


def saved_bytes(final: Path) -> int:
    """Bytes of finished chunks an unfinished run of ``final`` holds (0 if none)."""
    chunks = partial_path(final) / "chunks"
    try:
        return sum(e.stat().st_size for e in os.scandir(chunks))
    except OSError:  # no journal, or it went away meanwhile
        return 0


def _available_memory() -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (ValueError, OSError, AttributeError):
        return None


def _size(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000.0
    return f"{n:.1f} PB"


def _kind(path: Path) -> str:
    """What a file system entry is, for a message."""
    try:
        return file_kind(os.stat(path).st_mode)
    except OSError:
        return "a broken link"


def _writable(path: Path) -> bool:
    """Write permission, and not marked read-only (root passes os.access even then)."""
    return os.access(path, os.W_OK) and bool(path.stat().st_mode & 0o222)


# Seconds between two progress lines of a run that shows no bar (stderr no terminal: a log).
PROGRESS_LOG_EVERY = 30.0


def _progress(scene: Scene, progress: bool | None, initial: int = 0):
    """The run's progress: a tqdm bar where one is shown (``execute.shows_progress``), one line now
    and then on stderr when progress is None and nobody watches (a log: ``_LogProgress``), else nothing.
    Each has ``update(points)`` and ``close()``."""
    if shows_progress(progress):
        from tqdm.auto import tqdm

        return tqdm(total=scene.n_points, initial=initial, unit="pt", unit_scale=scene.n_points >= 100_000,
                    dynamic_ncols=True, desc=scene.name, smoothing=0.1)
    if progress is None:
        return _LogProgress(scene.name, scene.n_points, initial)
    return _NoProgress()


class _NoProgress:
    def update(self, n: int) -> None:
        pass

    def close(self) -> None:
        pass


class _LogProgress:
    """Progress for a log (stderr no terminal, e.g. a batch job): at most one line per
    PROGRESS_LOG_EVERY seconds, "mechsweep: NAME: 12,000 / 1,000,000 points, 1.2 %, ETA 3 min",
    and a last line with the run's time when any line was written (a short run writes none)."""

    def __init__(self, name: str, total: int, initial: int = 0):
        self.name, self.total, self.done, self.first = name, total, initial, initial
        self.t0 = self.last = time.monotonic()
        self.lines = 0

    def update(self, n: int) -> None:
        self.done += n
        now = time.monotonic()
        if now - self.last >= PROGRESS_LOG_EVERY and self.done < self.total:
            self.last = now
            rate = (self.done - self.first) / max(now - self.t0, 1e-9)
            eta = f", ETA {_duration((self.total - self.done) / rate)}" if rate > 0 else ""
            self._print(f"{self.done:,} / {self.total:,} points, {100.0 * self.done / self.total:.1f} %{eta}")

    def close(self) -> None:
        if self.lines and self.done >= self.total:
            self._print(f"{self.done:,} / {self.total:,} points, 100 %, in {_duration(time.monotonic() - self.t0)}")

    def _print(self, text: str) -> None:
        self.lines += 1
        print(f"mechsweep: {self.name}: {text}", file=sys.stderr, flush=True)


def _duration(seconds: float) -> str:
    """A rough duration for a progress line: 40 s, 3 min, 2.5 h."""
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _save_chunks(plan: Plan, sink, results, already: int, progress, compile_s: float = 0.0,
                 launches: "execute.Launches | None" = None, signals: "_Signals | None" = None) -> None:
    """Save each computed chunk to ``sink`` as it arrives, with its compute time (since the previous
    chunk; the first this call computes also ``compile_s``, the compile phase before it, kept apart:
    store.assemble sums both kinds into the dataset's attributes). A sink that writes
    (``sink.background``) does so in a writer thread: the write of one chunk overlaps the computation
    of the next (kernels release the GIL), and at most one chunk waits to be written, so memory stays
    bounded by the chunk size. ``signals`` (a local run to a file): Ctrl-C or SIGTERM while a chunk
    computes is acted on once that chunk is saved. A kernel launch cannot be stopped, so the chunk
    runs to its end either way; raising as soon as it returns would throw that work away (a slow
    one-chunk grid would end with "0 of 1 chunks saved")."""
    from concurrent.futures import ThreadPoolExecutor

    bar = _progress(plan.scene, progress, already)
    pending = None
    clock = {"last": execute.clock(), "compile": compile_s}
    solver = plan.solver is not None

    def write(chunk, result, seq):
        if launches is not None and sink.background:  # not while the run's thread prepares the next launch
            launches.wait_beyond(seq + 1)
        columns, status, n_steps, n_rhs = result
        arrays = {**columns, "status": status}
        if solver:
            arrays.update(n_steps=n_steps, n_rhs=n_rhs)
        if clock["compile"]:
            arrays[COMPILE_KEY] = np.float64(clock["compile"])
            clock["compile"] = 0.0
        now = execute.clock()  # the wall time up to this chunk is saved with it (survives a kill)
        sink.save(chunk, arrays, now - clock["last"])
        clock["last"] = now

    if not sink.background:  # nothing to write: each chunk is saved where it was computed
        try:
            for seq, (chunk, result) in enumerate(results):
                write(chunk, result, seq)
                bar.update(chunk.size)
        finally:
            close = getattr(results, "close", None)
            if close is not None:
                close()
            bar.close()
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="mechsweep-writer") as writer:
        writer.submit(sink.prepare, launches)  # (store.Early: the file is defined while the first chunk computes)
        try:
            with signals.deferred() if signals is not None else contextlib.nullcontext():
                for seq, (chunk, result) in enumerate(results):
                    if pending is not None:
                        pending.result()  # raises a write error here, in order
                        bar.update(pending_size)
                    pending, pending_size = writer.submit(write, chunk, result, seq), chunk.size
                    if signals is not None and signals.pending():
                        if launches is not None:
                            launches.end()  # no launch follows: the writer saves this chunk at once
                        break  # raised as KeyboardInterrupt when the deferral ends, after this chunk is saved
                if pending is not None:
                    pending.result()
                    bar.update(pending_size)
        finally:
            if pending is not None and not pending.done():
                pending.exception()  # let the last write finish before leaving
            if launches is not None:
                launches.end()  # (a run stopped before its first launch: the writer waits no longer)
            close = getattr(results, "close", None)
            if close is not None:
                close()  # a distributed run cancels what is still in flight
            bar.close()


@functools.lru_cache(maxsize=1)
def _xarray_version() -> str:
    """The installed xarray's version, looked up once per process: importlib.metadata reads the
    package's metadata files at every call (1-10 ms, before a run's first chunk)."""
    return _version("xarray")


def provenance(plan: Plan) -> dict:
    """The attributes a run's dataset (and its journal) starts with: the scene, its plan, versions."""
    scene = plan.scene
    created = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
    attrs = {
        "title": scene.name,
        "model": scene.model.name,
        "model_source": scene.model.source,
        "outputs": " ".join(scene.outputs),
        "scene": scene.text,
        "scene_canonical": scene.canonical(),
        **({"scene_folder": scene.base} if scene.base else {}),
        "created": created,
        "mechsweep_version": __version__,
        "numba_version": numba.__version__,
        "numpy_version": np.__version__,
        "xarray_version": _xarray_version(),  # xarray is not imported by the command `mechsweep run` (0.3 s of CPU)
        "python_version": platform.python_version(),
        "chunk_size": plan.chunks.max_size,
        "wall_time_s": 0.0,
        "Conventions": cf.CONVENTIONS,
        "source": cf.source(scene.model, __version__),
        "history": cf.history(created, f"mechsweep.run(scene {scene.name!r})", __version__),
        "references": cf.references(scene.model),
    }
    if scene.solver is not None:
        for k, v in scene.solver.as_dict().items():
            attrs[f"solver_{k}"] = v
    from .model import sources

    # what the results are computed from (model/sources.py): a resume checks it, a reader sees it
    attrs.update(sources.record(scene.model).attrs(scene.base or None))
    attrs["plan"] = plan.text()  # what is computed and how (plan.py)
    return attrs
