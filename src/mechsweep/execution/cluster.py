"""Chunks as tasks on a dask.distributed cluster.

Each task carries the run's plan and one chunk; a worker computes it with the function a local run
calls (execute.evaluate_chunk) and returns the chunk's arrays. The client is the only writer: it
saves each result to the journal as it arrives, so a failure loses at most the chunks in flight,
of which there are at most IN_FLIGHT_PER_THREAD per worker thread (the client's memory stays
bounded whatever the grid). A dead worker's tasks run again elsewhere; a chunk is saved once. A
scheduler that goes away, does not answer, or has no worker for ``worker_timeout`` seconds stops
the run with ``ClusterLost``; the chunks saved stay in the journal for a --resume.

Needs ``dask`` and ``distributed`` (``pip install "mechsweep[distributed]"``) on the client and on
every worker, with the same mechsweep version."""
from __future__ import annotations

from concurrent.futures import CancelledError
import itertools
import time
import uuid

from ..errors import ClusterLost, InputError

IN_FLIGHT_PER_THREAD = 2
CONNECT_TIMEOUT_S = 20
HEALTH_CHECK_S = 1.0  # how often the client asks the scheduler for its workers while it waits
RESULT_WAIT_S = 5.0  # at least this long for one attempt to fetch a finished chunk


NEEDS_DISTRIBUTED = ("running on a dask cluster needs the optional packages dask and distributed: "
                     "pip install \"mechsweep[distributed]\"")


def connect(scheduler: str):
    """A client of the dask scheduler at ``scheduler``; InputError if the packages are missing or
    the scheduler does not answer within CONNECT_TIMEOUT_S. A run calls this before it creates
    any file, so an unreachable cluster leaves nothing behind."""
    try:
        from distributed import Client
    except ImportError:
        raise InputError(NEEDS_DISTRIBUTED) from None
    _check_address(scheduler)

    class QuietClient(Client):
        """A Client whose failed construction leaves nothing to clean up at exit (distributed's
        own clean-up of a half-made client waits 40 s and prints a traceback)."""

        def __init__(self, *args, **kwargs):
            self._mechsweep_failed = True
            super().__init__(*args, **kwargs)
            self._mechsweep_failed = False

        def __del__(self):
            if not getattr(self, "_mechsweep_failed", False):
                super().__del__()

    try:
        return QuietClient(scheduler, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
    except Exception as exc:  # OSError, TimeoutError, tornado's TimeoutError, ValueError for a bad address...
        raise InputError(f"cannot reach the dask scheduler at {scheduler!r} within {CONNECT_TIMEOUT_S} s "
                         f"({exc}); start one with `dask scheduler` and workers with `dask worker ADDRESS`") from None


def _check_address(scheduler: str) -> None:
    """Refuse an address dask cannot parse (unknown scheme, no host, a port out of range) before a
    Client is made: a Client that fails on it is left half made, and its clean-up at exit prints a
    traceback after a 40 s wait."""
    from distributed.comm import parse_address
    from distributed.comm.addressing import parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, location = parse_address(scheduler)
        get_backend(scheme)
        if scheme in ("tcp", "tls", "ws", "wss"):
            host, port = parse_host_port(location)
            if not host or not 0 < int(port) < 65536:
                raise ValueError(f"host {host!r}, port {port} (expected 1-65535)")
    except Exception as exc:
        raise InputError(f"scheduler {scheduler!r} is not a dask scheduler address ({exc}); expected an address "
                         "such as 'tcp://10.0.0.5:8786' or 'localhost:8786'") from None


def dask_results(plan, todo, scheduler: str, threads: int | None = None, *, worker_timeout: float = 120.0,
                 client=None):
    """Yield ``(chunk, result)`` as the cluster at ``scheduler`` finishes them. Closing the
    generator cancels the tasks still in flight (and disconnects, unless ``client`` was given:
    its owner closes it). ``ClusterLost`` when the scheduler is lost, or has no worker for
    ``worker_timeout`` seconds."""
    try:
        from distributed import KilledWorker, as_completed
    except ImportError:
        raise InputError(NEEDS_DISTRIBUTED) from None
    owner = client is None
    if owner:
        client = connect(scheduler)
    run_id = uuid.uuid4().hex[:12]
    lost = False
    futures = as_completed(loop=client.loop)
    live = {}  # key -> (future, chunk), submitted and not yet handed out

    from ..model import sources

    scene = plan.scene
    depends = sources.record(scene.model).attrs(scene.base or None).get("dependencies", "")

    def submit(chunk) -> None:
        fut = client.submit(compute_chunk, plan, chunk, threads, depends, key=f"mechsweep-{run_id}-{chunk.index}")
        live[fut.key] = (fut, chunk)
        futures.add(fut)

    try:
        slots = max(1, sum(client.nthreads().values()))
        pending = iter(todo)
        for chunk in itertools.islice(pending, IN_FLIGHT_PER_THREAD * slots):
            submit(chunk)
        health = _Health(client, scheduler, worker_timeout, live)
        while (fut := _next_done(futures, health)) is not None:
            try:
                result = _result(fut, health)
            except KilledWorker as exc:
                raise ClusterLost(f"the dask workers at {scheduler} died while computing a chunk, too many "
                                  f"times ({exc}); {_lost(live)}") from None
            except Exception as exc:
                if fut.status == "error":  # the task itself failed on its worker: a real error, shown as is
                    raise
                lost = "scheduler"
                why = "its tasks were cancelled" if isinstance(exc, CancelledError) else f"{type(exc).__name__}: {exc}"
                raise ClusterLost(f"lost the dask scheduler at {scheduler} ({why}); {_lost(live)}") from None
            _, chunk = live.pop(fut.key)
            fut.release()
            following = next(pending, None)
            if following is not None:
                submit(following)
            yield chunk, result
    except BaseException:
        lost = lost or "stopped"  # no worker, an interruption, or a failed write here
        raise
    finally:
        _disconnect(client, live, quiet=bool(lost), cancel=lost != "scheduler", close=owner)


def _disconnect(client, live: dict, quiet: bool, cancel: bool, close: bool = True) -> None:
    """Cancel what is in flight and close the client (if ``close``: a client given by the caller
    is closed by the caller, with ``disconnect``). After a lost cluster or an interruption
    the process is about to report and stop: the tracebacks that distributed and asyncio log
    about the connection the client can no longer make (some of them later, from the client's
    event loop) are silenced for the rest of the process."""
    import logging

    if quiet:
        for name in ("distributed.client", "distributed.core", "asyncio"):
            logging.getLogger(name).setLevel(logging.CRITICAL + 1)
    try:
        if live and cancel and client.status == "running":
            client.cancel([f for f, _ in live.values()])
        if close:
            client.close(timeout=CONNECT_TIMEOUT_S)
    except Exception:  # the scheduler is gone: nothing left to cancel or to say goodbye to
        pass


def disconnect(client) -> None:
    """Close a client made by ``connect``; a scheduler that has gone meanwhile is not waited for."""
    _disconnect(client, {}, quiet=False, cancel=False)


def _lost(live: dict) -> str:
    chunks = sorted(chunk.index for _, chunk in live.values())
    shown = ", ".join(map(str, chunks[:8])) + (", ..." if len(chunks) > 8 else "")
    return f"{len(chunks)} chunks in flight were not computed: {shown}" if chunks else "no chunk in flight"


def _next_done(futures, health: "_Health"):
    """The next finished future, or None when all are handed out; meanwhile ``health`` is checked."""
    while not futures.has_ready():
        if futures.is_empty():
            return None
        time.sleep(0.01)
        health.check()
    health.ok()
    return next(futures)


def _result(fut, health: "_Health"):
    """A finished future's result. Fetching it from a worker that died meanwhile waits for the
    chunk to be computed again, so ``health`` is checked between attempts (each long enough for a
    large chunk to arrive: a timed-out attempt starts the transfer over)."""
    while True:
        try:
            return fut.result(timeout=max(RESULT_WAIT_S, health.timeout / 2))
        except TimeoutError:
            if fut.status == "error":  # the task itself raised it
                raise
            health.check(now=True)


class _Health:
    """Every HEALTH_CHECK_S the scheduler is asked for its workers; one that does not answer, or
    has none, for ``timeout`` seconds raises ``ClusterLost``."""

    def __init__(self, client, scheduler: str, timeout: float, live: dict):
        self.client, self.scheduler, self.timeout, self.live = client, scheduler, timeout, live
        self.trouble_since = None
        self.next_check = time.monotonic() + HEALTH_CHECK_S

    def ok(self) -> None:
        self.trouble_since = None

    def check(self, now: bool = False) -> None:
        if not now and time.monotonic() < self.next_check:
            return
        why = _trouble(self.client, self.timeout)
        self.next_check = time.monotonic() + HEALTH_CHECK_S
        if why is None:
            self.trouble_since = None
            return
        self.trouble_since = self.trouble_since or time.monotonic()
        if time.monotonic() - self.trouble_since >= self.timeout:
            raise ClusterLost(f"the dask scheduler at {self.scheduler} {why} for {self.timeout:g} s "
                              f"([execution] worker_timeout); {_lost(self.live)}")


def _trouble(client, timeout: float) -> str | None:
    """What keeps the cluster from computing (no connection, no worker), or None."""
    if client.status != "running":
        return "has been unreachable (connection lost)"
    try:
        nthreads = client.nthreads(callback_timeout=max(1.0, min(timeout, CONNECT_TIMEOUT_S)))
    except Exception:
        return "has not answered"
    if not nthreads:
        return "has had no worker"
    return None


def compute_chunk(plan, chunk, threads: int | None = None, depends: str = ""):
    """A worker's task: the chunk's (outputs, status, n_steps, n_rhs), computed from the run's ``plan``
    as a local run computes them (execute.evaluate_chunk), on ``threads`` numba threads (at most the
    worker's; default all of them). A user model file path in the scene is resolved against the
    client's scene folder (``plan.base``; the worker's own working directory plays no part; the file
    must be readable there). ``depends``: the client's dependency record (model/sources.py, JSON): a
    worker whose model sources differ (a file edited since the client loaded it, another mechsweep)
    refuses the task instead of computing points of another model."""
    import numba

    from .. import _jit
    from .execute import evaluate_chunk

    scene = plan.scene
    if depends:
        from ..model import sources

        changed = sources.differences(depends, sources.record(scene.model), plan.base or None,
                                      since="the run began on the client")
        if changed:
            raise InputError(f"the dask worker would compute from other sources than the client's: "
                             f"{'; '.join(changed)}; restore them (the worker sees the files at the paths "
                             "named), then run again with --resume")
    # numba's thread count is per calling thread: set it for this task's thread, every time
    _jit.set_num_threads(min(threads or numba.config.NUMBA_NUM_THREADS, numba.config.NUMBA_NUM_THREADS))
    return evaluate_chunk(plan, chunk)
