"""Chunks as tasks on a dask.distributed cluster.

Each task carries the scene's text and one chunk; a worker parses the scene once (cached per
process), runs the same numba kernels as a local run on its own threads, and returns the chunk's
arrays. The client that submitted the tasks is the only writer: it saves each result to the run's
journal as it arrives (in any order), so a failure loses at most the chunks in flight. At most
IN_FLIGHT_PER_THREAD tasks per worker thread are submitted at a time, so the client's memory stays
bounded by that many chunks, whatever the grid. If a worker dies, the scheduler runs its tasks
again on another worker; a chunk is saved once, when its result arrives, whichever worker made it.

Needs the optional packages ``dask`` and ``distributed`` (``pip install "mechsweep[distributed]"``)
on the client and on every worker, with the same mechsweep version.
"""
from __future__ import annotations

import functools
import itertools
import uuid

from .errors import InputError

IN_FLIGHT_PER_THREAD = 2
CONNECT_TIMEOUT_S = 20


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


def dask_results(scene, todo, scheduler: str, threads: int | None = None, client=None):
    """Yield ``(chunk, result)`` as the cluster at ``scheduler`` finishes them. Closing the
    generator cancels the tasks still in flight (and disconnects, unless ``client`` was given:
    its owner closes it)."""
    try:
        from distributed import as_completed
    except ImportError:
        raise InputError(NEEDS_DISTRIBUTED) from None
    owner = client is None
    if owner:
        client = connect(scheduler)
    run_id = uuid.uuid4().hex[:12]
    futures = as_completed(loop=client.loop)
    live = {}  # key -> (future, chunk), submitted and not yet handed out

    def submit(chunk) -> None:
        fut = client.submit(compute_chunk, scene.text, chunk, threads, key=f"mechsweep-{run_id}-{chunk.index}")
        live[fut.key] = (fut, chunk)
        futures.add(fut)

    try:
        slots = max(1, sum(client.nthreads().values()))
        pending = iter(todo)
        for chunk in itertools.islice(pending, IN_FLIGHT_PER_THREAD * slots):
            submit(chunk)
        for fut in futures:
            result = fut.result()
            _, chunk = live.pop(fut.key)
            fut.release()
            following = next(pending, None)
            if following is not None:
                submit(following)
            yield chunk, result
    finally:
        if live:
            client.cancel([f for f, _ in live.values()])
        if owner:
            client.close()


def compute_chunk(scene_text: str, chunk, threads: int | None = None):
    """A worker's task: the chunk's (outputs, status, n_steps, n_rhs), as a local run computes them,
    on ``threads`` numba threads (at most the worker's; default all of them)."""
    import numba

    from .runner import evaluate_chunk

    scene, params = _scene(scene_text)
    # numba's thread count is per calling thread: set it for this task's thread, every time
    numba.set_num_threads(min(threads or numba.config.NUMBA_NUM_THREADS, numba.config.NUMBA_NUM_THREADS))
    return evaluate_chunk(scene, chunk, params)


@functools.lru_cache(maxsize=4)
def _scene(text: str):
    from .grid import ParameterMatrix
    from .scene import load_scene_text

    scene = load_scene_text(text, label="scene sent by the mechsweep client")
    return scene, ParameterMatrix(scene)
