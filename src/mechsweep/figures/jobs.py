"""Figures drawn side by side: ``mechsweep plot``'s figures, each a Python job of matplotlib, on the
cores of the machine (forked processes on Linux)."""
from __future__ import annotations

import os
import signal
import sys


def can_fork() -> bool:
    """Whether `plot` may draw its figures in forked processes: Linux (elsewhere, e.g. macOS, a fork
    without exec is unsafe once some system libraries are loaded), more than one core for this process,
    and no other Python thread (a thread holding a lock at the fork would leave it held in the child: the
    command's process has none; a notebook or a test runner calling ``main`` may)."""
    import threading

    if not sys.platform.startswith("linux") or not hasattr(os, "fork") or threading.active_count() != 1:
        return False
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return cores > 1


def side_by_side(jobs) -> None:
    """Run ``jobs`` (callables) at the same time: every one but the first in a forked child, the first
    here; return when all have finished. A job that raised has its exception raised here (the first
    in the jobs' order), after the others have finished (no figure file is left half written by a
    sibling's error). When this process is interrupted (Ctrl-C, SIGTERM), the children are stopped
    (SIGTERM) and reaped before the interruption goes on. What matplotlib spends on a figure (its
    layout, tick labels, rendering, PNG) is Python in one process: two figures on two cores take the
    time of the longer one instead of the sum."""
    import pickle

    children = []
    try:
        for job in jobs[1:]:
            read, write = os.pipe()
            pid = os.fork()
            if pid == 0:  # the child: do the job, send back what it raised, leave without cleaning up
                code = 0
                try:
                    os.close(read)
                    job()
                except BaseException as exc:  # noqa: BLE001 (sent to the parent, raised there)
                    code = 1
                    try:
                        try:
                            data = pickle.dumps(exc)
                        except Exception:  # an exception that cannot be pickled: its type and text
                            data = pickle.dumps(RuntimeError(f"{type(exc).__name__}: {exc}"))
                        with os.fdopen(write, "wb") as f:
                            f.write(data)
                    except BaseException:  # noqa: BLE001
                        pass
                finally:
                    os._exit(code)  # no atexit handlers, no flush of the parent's buffers
            os.close(write)
            children.append((pid, read))
        raised = None
        try:
            jobs[0]()
        except Exception as exc:  # the children finish first (below), then this is raised
            raised = exc
        while children:
            pid, read = children[0]
            with os.fdopen(read, "rb") as f:
                data = f.read()
            _, status = os.waitpid(pid, 0)
            children.pop(0)
            if raised is None and data:
                raised = pickle.loads(data)
            elif raised is None and status != 0:
                raised = RuntimeError(f"drawing a figure in process {pid} failed (wait status {status})")
        if raised is not None:
            raise raised
    finally:
        for pid, read in children:  # interrupted: stop the others
            try:
                os.kill(pid, signal.SIGTERM)
            except ProcessLookupError:
                pass
            os.waitpid(pid, 0)
            try:
                os.close(read)
            except OSError:
                pass
