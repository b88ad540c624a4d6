"""Run a scene: scene -> plan (plan.py) -> chunks computed here (execute.py) or on a dask cluster
(cluster.py) -> a sink (about 700 lines: the route, its sinks and the run's end, read together).

A run with an output file saves each chunk to the journal (store/journal.py: crash-safe,
resumable), then assembles the dataset from it and moves it into place by one rename; the dataset
``run(output=path)`` returns is also kept in memory and written into the file while the next chunk
computes (store.assemble: MemorySink, Early). ``run(output=None)`` is the same route into a
MemorySink alone. The checks before anything is written are in checks.py; what a stopped run says
and keeps, in stopping.py."""
from __future__ import annotations

import contextlib
import datetime as _dt
import os
import signal
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Mapping

import numpy as np

from .. import __version__
from .. import _jit
from .. import cf
from .. import status as st
from ..errors import (ClusterLost, InputError, OutOfSpace, RunError, RunInterrupted, StoreError, WriteFailed,
                      why_os_error)
from ..chunks import Chunk, plan_chunks
from ..grid import chunk_target
from ..scene import Scene, check_scheduler, check_worker_timeout, load_scene
from ..store.assemble import COMPILE_KEY, Early, MemorySink, assemble, status_counts
from ..store.journal import BadChunk, Journal, RunLock, clear_discard, drop, partial_path
from ..store.read import LOAD_LIMIT_BYTES, check_journal_files, open_dataset
from ..store.write import layout
from . import execute
from .checks import (CHUNK_MEMORY_FACTOR, available_memory, bytes_per_point, check_existing, check_file_limit,
                     check_free_space, check_output_place, check_size, check_target, output_state, placing_problem,
                     saved_bytes, size_text)
from .execute import check_threads, shows_progress
from .plan import Plan, extra_shape, make_plan, tally
from .progress import make_progress
from .provenance import provenance
from .stopping import Signals, failed, interrupted, out_of_space, what_is_kept

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
        # the dataset the file holds, computed into memory as it was written: not read back (store.assemble.MemorySink)
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
    resume, restart, overwrite, threads, progress, scheduler, worker_timeout, models : optional
        As for :func:`run`.

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
    """``compute``, and with ``keep`` (True, or None up to store.LOAD_LIMIT_BYTES) the dataset in memory,
    filled as the file is written (None when a resume found the run finished)."""
    if resume and restart:
        raise InputError("resume and restart (--resume --restart) together are refused: --resume keeps the "
                         "finished chunks of an unfinished run, --restart discards them; choose one")
    scene = _scene(scene_or_path, models)
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
    finished = check_existing(scene, final, resume, restart, target, len(chunks), overwrite)
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
        with Signals() as signals:
            try:
                with RunLock(final):  # from here to the end, no other run touches final or its journal
                    clear_discard(final)  # what a killed clean-up left
                    before = output_state(final)  # what the checks accept is what the dataset may replace
                    if not check_existing(scene, final, resume, restart, target, len(chunks), overwrite):
                        keep = keep or keep is None and bytes_per_point(scene) * scene.n_points <= LOAD_LIMIT_BYTES
                        try:
                            counts, memory = _compute(plan, final, restart, threads, progress, scheduler, signals,
                                                      worker_timeout, client, keep, before)
                        except Exception as exc:  # a failure after the checks: keep no journal without a chunk
                            if not isinstance(exc, (WriteFailed, ClusterLost)):
                                failed(exc, final)
                            raise
                    else:  # True: a resume found the run finished
                        counts, memory = status_counts(final), None
                    # the times the file was given: from the dataset in memory when there is one
                    # (the same floats; store.assemble), else read back from the file
                    times = _times(final) if memory is None else _memory_times(memory)
            except WriteFailed as exc:
                raise OutOfSpace(out_of_space(exc, scene, final, len(chunks))) from None
            except ClusterLost as exc:
                raise ClusterLost(f"{exc}; {what_is_kept(final)}") from None
            except KeyboardInterrupt:
                raise RunInterrupted(interrupted(final, signals.signum or signal.SIGINT),
                                     signals.signum or signal.SIGINT) from None
    finally:
        if client is not None:
            _disconnect(client)
    return RunSummary(final, _sizes(scene), counts, *times), memory


def _scene(scene_or_path, models: Mapping | None) -> Scene:
    """The scene of a run, with a SettingsWarning for each accepted but suspicious solver setting."""
    import warnings

    from ..errors import SettingsWarning
    from ..scene import solver_warnings

    if models is not None and not isinstance(models, Mapping):
        raise InputError(f"models must be a mapping of model name -> OdeModel, got {type(models).__name__}")
    scene = scene_or_path if isinstance(scene_or_path, Scene) else load_scene(scene_or_path, models=models)
    for text in solver_warnings(scene):
        warnings.warn(text, SettingsWarning, stacklevel=4)
    return scene


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
        return None  # check_existing says what is wrong with it
    target = meta.get("chunk_target") if isinstance(meta, dict) else None
    if isinstance(target, bool) or not isinstance(target, int) or target < 1:
        return None
    from ..chunks import MAX_CHUNKS

    return target if len(plan_chunks(scene.shape, target)) <= MAX_CHUNKS else None


def _run_in_memory(scene_or_path, *, resume, restart, threads, progress, scheduler, load, worker_timeout,
                   overwrite, models) -> xr.Dataset:
    """``run(output=None)``: the route of every run into a MemorySink, bitwise the values the file route
    stores. Nothing is written (no file, journal, lock or folder) and no signal handler is installed."""
    from ..store.assemble import time_attrs

    given = [name for name, value in (("resume", resume), ("restart", restart), ("overwrite", overwrite))
             if value] + [name for name, value in (("load", load), ("scheduler", scheduler),
                                                    ("worker_timeout", worker_timeout)) if value is not None]
    if given:
        raise InputError(f"output=None (the in-memory route) computes here and writes nothing: {', '.join(given)} "
                         "does not apply to it; give an output path to use it")
    scene = _scene(scene_or_path, models)
    if scene.execution.scheduler:
        raise InputError(f"output=None (the in-memory route) runs here; the scene's [execution] scheduler "
                         f"{scene.execution.scheduler} is not used by it: give an output path to run on the cluster")
    check_threads(threads)
    need = _memory_bytes(scene)
    available = available_memory()
    if available is not None and need > available:
        raise StoreError(f"the dataset of {scene.n_points:,} points would need about {size_text(need)} of memory, "
                         f"{size_text(available)} is available; give an output path (the file route keeps memory "
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
    from ..grid import CHUNK_VALUES

    per_point = sum(int(np.prod(extra_shape(scene, name), dtype=np.int64)) for name in scene.computed_outputs)
    return max(1, CHUNK_VALUES // max(1, per_point))


def _memory_bytes(scene: Scene) -> int:
    """Memory of an in-memory dataset: its variables, and the chunk being computed."""
    return bytes_per_point(scene) * scene.n_points + CHUNK_MEMORY_FACTOR * bytes_per_point(scene) * min(
        chunk_target(scene), scene.n_points)


def _from_python(scene: Scene, models: Mapping) -> bool:
    """Whether the scene's model is one of ``models`` (given from Python, not importable elsewhere)."""
    from ..model.user import from_object

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
    """(wall, compile, compute) seconds, as _times reads them from the file."""
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


def _connect(scheduler: str):
    from .cluster import connect  # dask is imported only for a run on a cluster

    return connect(scheduler)


def _disconnect(client) -> None:
    from .cluster import disconnect

    disconnect(client)


def _compute(plan: Plan, final: Path, restart: bool, threads, progress, scheduler, signals: "Signals",
             worker_timeout: float, client=None, keep: bool = False, before: tuple | None = None
             ) -> tuple[dict[int, int], MemorySink | None]:
    """The route into the file sink: the missing chunks into the journal, then the dataset assembled;
    returns the points per status code and, with ``keep``, the dataset in memory. Chunk files that do
    not verify are removed and computed again. ``before``: what was at ``final`` when the checks
    passed (``output_state``), the only file the dataset replaces besides one of the same scene."""
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
        todo = [chunks[int(i)] for i in np.flatnonzero(~done)]  # at most chunks.MAX_CHUNKS
        early = None
        try:
            with execute.threads(None if scheduler else threads):
                where = (f"dask scheduler {scheduler}, {threads or 'all'} numba threads per worker" if scheduler
                         else f"local, {_jit.num_threads()} threads")
                # the plan computing now (a resumed run's journal holds the plan it began with)
                attrs = {**journal.meta["attrs"], "plan": plan.text(), "execution": where}
                if not scheduler:
                    attrs["threads"] = _jit.num_threads()
                # a fresh run that returns its dataset writes its file while the chunks compute; a
                # resumed one (its history says when it was finished) is assembled at the end
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
    """The sink of a run with an output file: each chunk saved to the journal and, for a run that
    returns its dataset, kept in ``memory`` and written into the dataset's file at once (``early``)."""

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
           client=None, worker_timeout: float | None = None, signals: "Signals | None" = None) -> float:
    """Every run's route from its plan to its sink: the chunks ``todo`` computed here (the kernels
    compiled first, timed apart) or on the dask cluster ``scheduler``, each saved to ``sink`` as it
    arrives. Returns the compile phase's seconds."""
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
    computed = sum(c.size for c in todo)
    _save_chunks(plan, sink, results, plan.n_points - computed, progress, compile_s, launches,
                 signals if local else None)
    tally(plan, computed)  # what the one-point route has cost this model so far (a later plan reads it)
    return compile_s


def _report_removed(journal: Journal) -> None:
    for line in journal.removed:
        print(f"mechsweep: chunk file {line}: removed, it is computed again", file=sys.stderr)
    journal.removed = []


# The dataset is written here, in the journal folder, and renamed into place when complete.
ASSEMBLY = "assembly.h5"


def _finish(journal: Journal, scene: Scene, chunks, final: Path, attrs: dict,
            signals: "Signals", memory: MemorySink | None = None, early: Early | None = None,
            before: tuple | None = None) -> tuple[list[BadChunk], dict[int, int]]:
    """Assemble the dataset next to the journal (or complete ``early``), move it into place by one
    rename, drop the journal; signals wait until the files are closed. Returns the chunk files that
    did not verify (then nothing is moved) and the points per status. A file that appeared at
    ``final`` while the run computed is not replaced (StoreError, the journal kept)."""
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
        if (why := placing_problem(final, scene, before)) is not None:
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


def _save_chunks(plan: Plan, sink, results, already: int, progress, compile_s: float = 0.0,
                 launches: "execute.Launches | None" = None, signals: "Signals | None" = None) -> None:
    """Save each computed chunk to ``sink`` as it arrives, with its compute time since the previous
    chunk (the first also with ``compile_s``, kept apart). A sink that writes (``sink.background``)
    does so in a writer thread: one chunk's write overlaps the next one's kernels (they release the
    GIL), and at most one chunk waits, so memory stays bounded by the chunk size. ``signals``: Ctrl-C
    or SIGTERM while a chunk computes is acted on once that chunk is saved (a kernel launch cannot be
    stopped; raising as it returns would throw its work away)."""
    from concurrent.futures import ThreadPoolExecutor

    bar = make_progress(plan.scene, progress, already)
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
            _close(results, bar)
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="mechsweep-writer") as writer:
        writer.submit(sink.prepare, launches)  # (store.assemble.Early: the file is defined while the first chunk computes)
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
            _close(results, bar)


def _close(results, bar) -> None:
    close = getattr(results, "close", None)
    if close is not None:
        close()  # a distributed run cancels what is still in flight
    bar.close()
