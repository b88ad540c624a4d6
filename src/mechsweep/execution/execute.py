"""Execute a plan: ``evaluate_chunk``, the one function a local run and a dask worker (cluster.py)
both call; the local loop over a run's chunks, and the compile phase before it. A chunk's values
may be computed straight into the arrays of the dataset a run keeps in memory (``out``)."""
from __future__ import annotations

import numbers
import sys
import threading
import time
from contextlib import contextmanager

import numba
import numpy as np

from .. import _jit
from .. import status as st
from ..errors import InputError
from ..chunks import Chunk
from ..grid import ParameterMatrix
from .plan import Plan, make_plan


def evaluate_rows(plan: Plan, P: np.ndarray, out: dict | None = None, launching=None):
    """Compute the plan's outputs on any parameter rows ``P`` (float64 [n, n_params]), exactly as a
    chunk of its grid is computed (same outputs asked, same kernels, same status rules). Returns
    (requested outputs by name, status, n_steps, n_rhs). ``plan`` may be a Scene (then its default
    plan is made for this call: plan.make_plan, with the route a run of its grid takes). ``out``:
    arrays of n rows to compute into (outputs by name, "status", "n_steps", "n_rhs"; any of them),
    returned as they are; the others are made here. ``launching()``: called right before the kernel
    is launched."""
    if not isinstance(plan, Plan):
        plan = make_plan(plan)
    scene = plan.scene
    n = P.shape[0]
    out = out or {}
    values = {}
    for name in plan.computed:
        given = out.get(name)
        if given is None:
            values[name] = np.full((n,) + plan.extra_shape(name), np.nan)
        else:
            given[...] = np.nan
            values[name] = given
    status, n_steps, n_rhs = (_zeros(out.get(name), n, dtype) for name, dtype in
                              (("status", st.DTYPE), ("n_steps", np.int64), ("n_rhs", np.int64)))
    route = {} if getattr(scene.model, "plan", None) is None else {"route": plan.routes}
    with np.errstate(all="ignore"):  # an overflow at an extreme point is its status
        if launching is not None:
            launching()
        scene.model.evaluate(P, plan.computed, scene.solver, values, status, n_steps, n_rhs, **route)
    for name, given in out.items():  # a model that replaced an array of ``values``: its values into ``out``
        if name in values and values[name] is not given:
            given[...] = values[name]
            values[name] = given
    # a code that is not a status (a user's classify returning 99 at a point its probe did not see)
    # is the model's error, not a result to store
    not_a_status = (status < st.OK) | (status > st.LAST)
    if not_a_status.any():
        status[not_a_status] = st.USER_ERROR
        for v in values.values():
            v[not_a_status] = np.nan
    requested = {name: values[name] for name in plan.outputs}
    # A point is ok only if everything asked of it is finite (never a NaN with status ok).
    # An overflow (inf) is never stored as a value: it becomes NaN, the point NONFINITE.
    finite = np.ones(n, dtype=bool)
    for v in requested.values():
        finite &= np.isfinite(v.reshape(n, -1)).all(axis=1)
        v[np.isinf(v)] = np.nan
    status[(status == st.OK) & ~finite] = st.NONFINITE
    return requested, status, n_steps, n_rhs


def _zeros(given, n: int, dtype) -> np.ndarray:
    if given is None:
        return np.zeros(n, dtype=dtype)
    given[...] = 0
    return given


def evaluate_chunk(plan: Plan, chunk: Chunk, params: ParameterMatrix | None = None, out: dict | None = None,
                   launching=None):
    """Compute one chunk of the plan's grid (``evaluate_rows`` of its parameter rows). Returns
    (requested outputs by name, status, n_steps, n_rhs). ``plan`` may be a Scene (its default plan)."""
    if not isinstance(plan, Plan):
        plan = make_plan(plan)
    return evaluate_rows(plan, (params or plan.params)(chunk.start, chunk.stop), out, launching)


# ----------------------------------------------------------------------------- the compile phase
# The compile phase is announced only when it lasts longer than this (seconds): a warm JIT cache
# loads in a fraction of it, and then nothing is printed.
COMPILE_NOTE_AFTER = 0.5
COMPILE_NOTE = "compiling kernels for model {model} (first run; cached afterwards)"

# The kernels warm_up has compiled or loaded in this process, by _kernel_key.
_WARM: set = set()


def _kernel_key(plan: Plan) -> tuple:
    """What selects a plan's kernels: the model (and the source of a user's model), the outputs
    computed, the method and the routes (the plan's, after the scene's ``[execution] lanes``). A user
    model file edited in the process changes ``model_key``."""
    scene = plan.scene
    return (scene.model.name, scene.model_key, scene.model.source, plan.computed,
            scene.solver.method if scene.solver is not None else None, plan.route)


def clock() -> float:
    """The run's clock (a seam: tests move it on to time the compile phase apart)."""
    return time.perf_counter()


def shows_progress(progress: bool | None) -> bool:
    """Whether a progress bar is shown: ``progress``, or by default where a user watches: when
    stderr is a terminal, or in a Jupyter notebook (tqdm.auto draws it as a widget there)."""
    if progress is not None:
        return bool(progress)
    try:
        if sys.stderr.isatty():
            return True
    except (AttributeError, ValueError):
        pass
    return _in_notebook()


def _in_notebook() -> bool:
    """Whether this process is a Jupyter kernel (IPython's ZMQ shell), where stderr is no terminal
    but a user watches the cell's output."""
    ipython = sys.modules.get("IPython")
    try:
        shell = ipython.get_ipython() if ipython is not None else None
    except Exception:  # an IPython too old or half imported: no notebook to show anything in
        return False
    return type(shell).__name__ == "ZMQInteractiveShell"


def warm_up(plan: Plan, progress: bool | None, chunk: Chunk | None = None) -> float:
    """Compile the plan's kernels (numba compiles, or loads from its disk cache, on first call) by
    computing one point of ``chunk`` (the first of the grid by default), before the timed chunks
    and the progress bar. Its result is thrown away: the chunk computes the point again, with the
    same result. When the phase lasts longer than COMPILE_NOTE_AFTER seconds it is announced on
    stderr, naming the model (with its time when it ends), wherever the run reports its progress:
    a terminal, a notebook's cell, a log (all but ``progress=False``). Returns its seconds (0 when
    this process has compiled or loaded the same kernels before: then nothing is computed)."""
    key = _kernel_key(plan)
    if key in _WARM:  # compiled (or loaded) in this process already: nothing to do, no extra launch
        return 0.0
    start = 0 if chunk is None else chunk.start
    shown = progress is not False
    noted = threading.Event()

    def note():
        noted.set()
        print(f"mechsweep: {COMPILE_NOTE.format(model=plan.model)} ...", file=sys.stderr, flush=True)

    timer = threading.Timer(COMPILE_NOTE_AFTER, note) if shown else None
    t0 = clock()
    if timer is not None:
        timer.daemon = True
        timer.start()
    try:
        evaluate_rows(plan, plan.params(start, start + 1))
    finally:
        if timer is not None:
            timer.cancel()
    seconds = clock() - t0
    _WARM.add(key)
    if noted.is_set():
        print(f"mechsweep: kernels compiled in {seconds:.1f} s", file=sys.stderr, flush=True)
    return seconds


# ----------------------------------------------------------------------------- the local loop
# Seconds the writer thread waits for the next chunk's launch before it writes a chunk anyway.
LAUNCH_WAIT = 1.0


class Launches:
    """The kernel launches of a run's chunks computed here, counted as they begin, so that the
    writer thread starts on chunk k only once chunk k + 1's kernel runs: the writer's Python then
    holds the GIL while the kernel (which releases it) computes, not while the run's thread does
    the chunk boundary's Python. ``end()``: no launch follows. Ordering only: the writer waits at
    most LAUNCH_WAIT seconds; what it writes and when it is synced are unchanged."""

    def __init__(self):
        self._n = 0
        self._ended = False
        self._cv = threading.Condition()

    def launching(self) -> None:
        with self._cv:
            self._n += 1
            self._cv.notify_all()

    def end(self) -> None:
        with self._cv:
            self._ended = True
            self._cv.notify_all()

    def wait_beyond(self, n: int, timeout: float = LAUNCH_WAIT) -> None:
        """Until more than ``n`` launches have begun (or no more will)."""
        with self._cv:
            self._cv.wait_for(lambda: self._ended or self._n > n, timeout)

    def wait(self, timeout: float) -> None:
        """Until the first launch has begun (or none will): the signature of threading.Event.wait."""
        self.wait_beyond(0, timeout)


def local_results(plan: Plan, todo: list[Chunk], launches: Launches | None = None, out_for=None):
    """Chunks computed here, in order, each by the numba kernels on all threads: yields (chunk,
    (outputs, status, n_steps, n_rhs)). ``out_for(chunk)``: the arrays to compute each chunk into
    (or None); ``launches`` counts each chunk's launch as it begins."""
    launching = launches.launching if launches is not None else None
    params = plan.params
    try:
        for chunk in todo:
            out = out_for(chunk) if out_for is not None else None
            yield chunk, evaluate_chunk(plan, chunk, params, out, launching)
    finally:
        if launches is not None:
            launches.end()


# ----------------------------------------------------------------------------- threads
def check_threads(n: int | None, here: bool = True) -> None:
    """Threads for this machine's kernels; on a cluster the workers' cores are not known here
    (each worker uses at most its own)."""
    if n is None:
        return
    if isinstance(n, bool) or not isinstance(n, numbers.Integral):
        raise InputError(f"threads = {n!r} is not allowed; expected a whole number (numba threads)")
    if here and not 1 <= n <= numba.config.NUMBA_NUM_THREADS:
        raise InputError(f"threads = {n} is outside [1, {numba.config.NUMBA_NUM_THREADS}] (cores available)")
    if not here and n < 1:
        raise InputError(f"threads = {n} is not allowed; expected at least 1 (numba threads per dask worker)")


@contextmanager
def threads(n: int | None):
    """numba's thread count set to ``n`` for the block (unchanged when None)."""
    if n is None:
        yield
        return
    check_threads(n)
    before = _jit.num_threads()
    _jit.set_num_threads(n)
    try:
        yield
    finally:
        _jit.set_num_threads(before)
