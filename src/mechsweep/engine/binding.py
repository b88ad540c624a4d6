"""The one file the engine writes: a kernel's binding module, for numba's disk cache.

A kernel is composed in memory from factories (engine/point.py, lanes.py, trajectory.py, closed.py):
closures over the model's jitted functions. numba caches a function on disk by its source file and
qualified name, and keys a closure's entry by its cells pickled, which does not find the same entry
in another process. So each kernel gets a small module file in the cache folder, named by a digest
of everything its machine code depends on (the model's dependency record, the functions' names, the
measurements' settings, the method, the route), from a fixed template: it takes the composed kernel
from this module's registry (``built``) and defines a ``cache=True`` trampoline per entry point that
calls it. The trampoline has no closure, so numba's index finds its entry in any process whose
binding file is the same; its cached machine code holds every callee's, so a second process
compiles nothing. A changed model gets a new digest, hence a new file, never a stale kernel.

The lane route's binding also holds the lane form of the model's rhs (engine/lane_rhs.py, the
engine's one source transformation): text, so it needs a file of its own to be cached.

Whether a lane kernel is compiled already is mechsweep's own record, kept beside the binding
files (engine/kernels.py, ``record_compiled`` and ``lanes_recorded``).
"""
from __future__ import annotations

import importlib.util
import os
import sys
import tempfile
import threading
from pathlib import Path

from .. import _jit

# the binding modules' names by the kind of kernel (model/sources.py knows them: not a user's module)
PREFIXES = {"point": "mechsweep_gen_", "lanes": "mechsweep_gen_", "trajectory": "mechsweep_traj_",
            "closed": "mechsweep_closed_"}
_TEMPLATE = '''"""mechsweep kernel binding {name}: {what}.
Written by mechsweep.engine.binding (do not edit; a changed model gets a new file)."""
from mechsweep._jit import jit
from mechsweep.engine.binding import built
{extra}
impl = built(__name__{lane_args})
{entries}'''
_ENTRY = '''
_{entry} = impl.{entry}


@jit
def {entry}({args}):
    return _{entry}({args})
'''

_BUILDERS: dict[str, object] = {}  # binding name -> builder(*lane functions) -> namespace of entry points
_BUILT: dict[str, object] = {}  # binding name -> the namespace built (once per process)
_LOADED: dict[str, object] = {}  # binding name -> its imported module
_LOCK = threading.RLock()
_TMP: list[str] = []


class Entries:
    """The composed entry points of one kernel (attributes named as the binding's trampolines)."""

    def __init__(self, **entries):
        self.__dict__.update(entries)


def folder() -> Path:
    """Where binding modules are written: ``<mechsweep cache>/models`` (a private temporary folder
    when caching is off)."""
    if _jit.cache_dir is not None:
        path = Path(_jit.cache_dir) / "models"
    else:
        with _LOCK:
            if not _TMP:
                _TMP.append(tempfile.mkdtemp(prefix="mechsweep-models-"))
        path = Path(_TMP[0])
    path.mkdir(parents=True, exist_ok=True)
    return path


def built(name: str, *lane_functions):
    """The composed entry points of binding ``name`` (called by the binding module as it is
    imported; ``lane_functions``: the functions its text defines, e.g. the lane rhs)."""
    with _LOCK:
        if name not in _BUILT:
            builder = _BUILDERS.get(name)
            if builder is None:
                raise RuntimeError(f"{name}: a mechsweep kernel binding imported outside mechsweep.engine.binding.bind")
            _BUILT[name] = builder(*lane_functions)
        return _BUILT[name]


def text(name: str, what: str, entries: dict, extra: str = "", lane_names: tuple[str, ...] = ()) -> str:
    """The binding module's source: the fixed template filled with the kernel's name, a line saying
    what it computes, its entry points {name: argument list} and the extra text (the lane rhs)."""
    return _TEMPLATE.format(name=name, what=what.replace('"""', "'''"), extra=extra and "\n" + extra,
                            lane_args="".join(", " + x for x in lane_names),
                            entries="".join(_ENTRY.format(entry=e, args=a) for e, a in entries.items()))


def bind(name: str, what: str, entries: dict, builder, extra: str = "", lane_names: tuple[str, ...] = ()):
    """The imported binding module ``name`` (written into the cache folder when absent or different:
    its mtime keys numba's cache index), whose entry points call what ``builder(*lane functions)``
    composes. Threads asking for the same binding at once share one module."""
    with _LOCK:
        mod = _LOADED.get(name)
        if mod is not None:
            return mod
        _BUILDERS[name] = builder
        source = text(name, what, entries, extra, lane_names)
        path = folder() / f"{name}.py"
        try:
            same = path.read_text() == source
        except OSError:
            same = False
        if not same:
            tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")
            tmp.write_text(source)
            os.replace(tmp, path)
        spec = importlib.util.spec_from_file_location(name, path)
        mod = importlib.util.module_from_spec(spec)
        sys.modules[name] = mod
        try:
            spec.loader.exec_module(mod)
        except BaseException:
            del sys.modules[name]
            raise
        _LOADED[name] = mod
        return mod
