"""The commands of ``mechsweep``, one module each: its help text, its arguments (``add_parser``) and
what it does (``command(args)``, returning the exit code). cli.py parses the command line and says
errors; a command module imports what its work needs only when it runs, so that parsing stays light.

Also the start-up of a command's process: Python's cyclic garbage collector is held off while the
command imports its libraries and reads its input (``held_collector``, ``started``); and its end
(``leave``: `plot`'s process ends without taking the interpreter apart)."""
from __future__ import annotations

import gc
import os
import sys
from contextlib import contextmanager

EXIT_INVALID = 2  # invalid input (nothing written) or a failed write: the exit codes cli.DESCRIPTION lists
QUICK_EXIT = ("plot",)  # commands whose process ends at once when they are done (see leave)

_COLLECTOR = {"held": False}  # True while the collector is held off for a command's start-up (see started)


@contextmanager
def held_collector(argv: list[str] | None):
    """For the process of a `run` or `plot` command (``argv`` None: main of the ``mechsweep`` script):
    no full collections during its start-up, until ``started``."""
    quick = argv is None and len(sys.argv) > 1 and sys.argv[1] in ("run", "plot") and gc.isenabled()
    if quick:
        gc.disable()
        _COLLECTOR["held"] = True
    try:
        yield
    finally:
        if quick and _COLLECTOR["held"]:
            _COLLECTOR["held"] = False
            gc.enable()


def started() -> None:
    """The start-up of a `run` or `plot` process is over (imports, scene or dataset): the objects made so
    far are frozen (``gc.freeze``: never traversed by a collection again) and the collector is turned
    back on for the command's work. During the start-up it is off (``held_collector``, only for the
    command's own process, ``argv`` None: a caller of ``main`` in a process of its own keeps its collector as it is).
    The imports (numpy, numba, xarray, matplotlib, the package) make hundreds of thousands of objects that
    live as long as the process, and each full collection traversed all of them (measured with
    ``python benchmarks/startup.py --only warmstart``: docs/performance-startup.md). A forked figure process
    (figures/jobs.py, ``side_by_side``) then also leaves the frozen objects' memory shared with its parent."""
    if _COLLECTOR["held"]:
        _COLLECTOR["held"] = False
        gc.freeze()
        gc.enable()


def leave(command: str | None, code: int) -> None:
    """End the process of the ``mechsweep`` program (``cli.script``, never a caller of ``main``) at once
    with exit code ``code`` when ``command`` is one of QUICK_EXIT: its output flushed and the
    ``atexit`` handlers run as at any exit, but the interpreter is not taken apart (every module and
    object of numpy, pandas, xarray and matplotlib freed one by one, a last collection), which took a
    `plot` longer than writing a figure's PNG. Its files are written and closed by then. Returns
    (the usual exit follows) for other commands, when another thread is running (Python's exit
    waits for it), or when the output cannot be flushed (Python's exit says why)."""
    import threading

    if command not in QUICK_EXIT or threading.active_count() != 1:
        return
    import atexit

    run_handlers = getattr(atexit, "_run_exitfuncs", None)
    if run_handlers is None:
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        return
    run_handlers()
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        pass
    os._exit(code)
