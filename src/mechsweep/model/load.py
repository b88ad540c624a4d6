"""User models: ``"my_models.py:NAME"`` (a path relative to the scene file) or
``"package.module:NAME"``. Loading a model file executes it, as any Python import does.

Every problem is an :class:`~mechsweep.errors.InputError` naming the file (and the line, where
Python or numba gives one), raised while the scene is loaded, before any file is written:
missing file, a file that fails to import, NAME not defined or not an OdeModel (or ClosedFormModel: its
checks are closed.check), an rhs or initial
that raises, reads a parameter beyond the declared ones or writes beyond the state (found by
running them once in plain Python at a probe point), leaves a component unwritten, writes into an
argument its role may not write (model/writes.py), or that numba cannot compile; and an exit while
the model loads (sys.exit, os._exit, a KeyboardInterrupt the code raises itself: exits_refused).
"""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import keyword
import math
import os
import re
import signal
import stat
import sys
import threading
import traceback
import types
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .. import _jit
from ..errors import InputError

_FILES: dict[str, str] = {}  # module name -> path of a user model file loaded by path
_JITTED: dict[tuple, object] = {}
_RESOLVED: dict[tuple, object] = {}


def _module_name(path: Path) -> str:
    stem = re.sub(r"\W", "_", path.stem)
    return f"mechsweep_user_{stem}_{hashlib.sha256(str(path).encode()).hexdigest()[:12]}"


def import_module(module: str, path: str = ""):
    """The user's module (loaded by path under ``module`` when ``path`` is given)."""
    if module in sys.modules:
        return sys.modules[module]
    if not path:
        return importlib.import_module(module)
    spec = importlib.util.spec_from_file_location(module, path)
    mod = importlib.util.module_from_spec(spec)
    sys.modules[module] = mod
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        del sys.modules[module]
        raise
    _FILES[module] = path
    return mod


def module_source(module: str, path: str = "") -> bytes:
    file = path or getattr(sys.modules.get(module), "__file__", None) or ""
    try:
        return Path(file).read_bytes()
    except OSError:
        return b""


def function_ref(func, what: str, model_name: str) -> tuple[str, str, str]:
    """(module, path, qualified name) by which a generated module imports ``func``."""
    func = getattr(func, "py_func", func)
    qual = getattr(func, "__qualname__", "")
    module = getattr(func, "__module__", "") or ""
    if not callable(func) or not qual or "<" in qual or not module or module == "__main__":
        raise InputError(f"model {model_name!r}: {what} must be a function defined at the top level of an "
                         f"importable module or model file (got {func!r})")
    return module, _FILES.get(module, ""), qual


def jitted(module: str, path: str, qualname: str):
    """The numba dispatcher (mechsweep's options, disk cache) of a user function."""
    key = (module, path, qualname)
    if key not in _JITTED:
        obj = import_module(module, path)
        for part in qualname.split("."):
            obj = getattr(obj, part)
        # a function its author compiled without reference counting (jit_noalloc: no arrays allocated) keeps
        # that: a per-design or per-point function called with arrays and views otherwise pays atomic
        # increments and decrements of their reference counts at every call
        noalloc = getattr(obj, "targetoptions", {}).get("_nrt") is False
        decorate = _jit.jit_noalloc if noalloc else _jit.jit
        _JITTED[key] = decorate(_renamed(_with_engine_helpers(getattr(obj, "py_func", obj)), module))
    return _JITTED[key]


_INLINED: dict[tuple, object] = {}


def inlined(module: str, path: str, qualname: str):
    """The user function of :func:`jitted`, compiled into each numba caller (numba IR inlining,
    _jit.jit_into_caller): the one-point kernel's guards take it so (compile.module_prologue), which
    saves numba a compile of its own per function (typing, lowering, an LLVM module optimised and
    turned into machine code, then linked and optimised again in the guard). Called from Python it
    runs as jitted's. A function with a ``raise`` (or ``assert``) statement of its own stays jitted's:
    numba's ``try`` in the guard does not catch a raise inlined into its body (measured: the exception
    escaped the kernel), while an exception raised by a function it calls is caught either way."""
    key = (module, path, qualname)
    if key not in _INLINED:
        func = jitted(module, path, qualname)
        _INLINED[key] = func if _raises(func.py_func) else _jit.jit_into_caller(func.py_func)
    return _INLINED[key]


def _raises(func) -> bool:
    """Whether the function's own code (or code nested in it) has a raise or assert statement."""
    import dis

    stack = [func.__code__]
    while stack:
        code = stack.pop()
        if any(ins.opname in ("RAISE_VARARGS", "RERAISE") for ins in dis.get_instructions(code)):
            return True
        stack.extend(c for c in code.co_consts if isinstance(c, types.CodeType))
    return False


_FOREIGN = ("mechsweep", "numba", "numpy", "scipy")  # packages whose numba functions are left as they are
_HELPERS: dict[int, object] = {}  # id(user's dispatcher) -> the same function compiled with the engine's options


def _with_engine_helpers(func):
    """``func`` with the numba functions of the user's own code that it calls by a global name
    (``@numba.njit`` helpers, and theirs) compiled again with the engine's options (_jit: fastmath
    off, ``error_model="numpy"``). numba's default error model ("python") raises ZeroDivisionError
    on a float division by zero, which in a sweep would make the point USER_ERROR, while the same code
    without the decorator (compiled by the engine) gives IEEE +-inf / NaN: recompiled, it does either way.
    The globals are a copy with the helpers swapped (numba freezes a function's globals when it
    compiles anyway); a function that calls no such helper is returned as it is."""
    from numba.core.dispatcher import Dispatcher

    g = getattr(func, "__globals__", None)
    if g is None:
        return func
    names = set()
    stack = [func.__code__]
    while stack:  # the names the function and its nested code objects read
        code = stack.pop()
        names.update(code.co_names)
        stack.extend(c for c in code.co_consts if isinstance(c, types.CodeType))
    swap = {}
    for name in names:
        v = g.get(name)
        if not isinstance(v, Dispatcher) or (getattr(v.py_func, "__module__", "") or "").split(".")[0] in _FOREIGN:
            continue
        if id(v) not in _HELPERS:
            _HELPERS[id(v)] = v  # a recursive helper keeps its own compilation
            helper = _with_engine_helpers(v.py_func)
            h = types.FunctionType(helper.__code__, helper.__globals__, helper.__name__, helper.__defaults__,
                                   helper.__closure__)
            # named after its module too (see _renamed: one file may be loaded under two module names)
            tag = _module_tag(helper.__module__ or "")
            h.__module__, h.__qualname__ = helper.__module__, f"{helper.__qualname__}__engine_{tag}"
            _HELPERS[id(v)] = (v, _jit.jit(h))  # the dispatcher kept alive: its id stays its own
        swap[name] = _HELPERS[id(v)][1] if isinstance(_HELPERS[id(v)], tuple) else v
    if not swap:
        return func
    out = types.FunctionType(func.__code__, {**g, **swap}, func.__name__, func.__defaults__, func.__closure__)
    out.__kwdefaults__ = func.__kwdefaults__
    out.__module__ = func.__module__
    out.__qualname__ = func.__qualname__
    return out


def _renamed(func, module: str):
    """``func`` with its qualified name suffixed by a hash of ``module`` and of what the module's code
    depends on (sources.module_digest). numba names a function's disk-cache entry after its file and
    qualified name only, and a cached entry re-imports the module it was compiled in: one file loaded
    under two module names (by path in a scene, and as a module, an entry point or the user's own
    import for run(models=...)) would otherwise load the other name's entry and fail with "No module
    named ..." in every later process. numba's index checks only the function's own file: the machine
    code of a helper from another file (linked into the entry) would outlive an edit of that file,
    while the digest gives an edited dependency a new name."""
    g = types.FunctionType(func.__code__, func.__globals__, func.__name__, func.__defaults__, func.__closure__)
    g.__kwdefaults__ = func.__kwdefaults__
    g.__module__ = func.__module__
    g.__qualname__ = f"{func.__qualname__}__{_module_tag(module)}"
    return g


def _module_tag(module: str) -> str:
    """8 hex digits naming ``module`` and its dependencies (mechsweep's own modules: the name alone; the
    cache folder is keyed by mechsweep's sources)."""
    from .sources import module_digest

    digest = module_digest(module)
    return hashlib.sha256((module + (f"|{digest}" if digest else "")).encode()).hexdigest()[:8]


ENTRY_POINT_GROUP = "mechsweep.models"


def is_file_ref(ref: str) -> bool:
    """Whether a model reference names a file path ("file.py:NAME", "dir/file.py:NAME")."""
    left = ref.rpartition(":")[0]
    return bool(left) and (left.endswith(".py") or "/" in left or "\\" in left)


def entry_points(quiet: bool = False) -> dict:
    """Models installed packages register: name -> importlib.metadata.EntryPoint of the group
    ``mechsweep.models`` (value "package.module:NAME"). Two packages registering one name is an
    InputError naming both (unless ``quiet``: then the first is kept)."""
    from importlib import metadata

    found: dict = {}
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        if ep.name in found and found[ep.name].value != ep.value and not quiet:
            raise InputError(f"model {ep.name!r} is registered twice in entry-point group {ENTRY_POINT_GROUP!r}: "
                             f"{found[ep.name].value!r} and {ep.value!r}; uninstall one of the packages")
        found.setdefault(ep.name, ep)
    return found


def from_object(name: str, obj):
    """The ModelSpec of a model given from Python (``run(scene, models={name: obj})``): an OdeModel
    or a ClosedFormModel (checked as a model file's is) or a ModelSpec (used as is)."""
    from ..models import MODELS, ModelSpec
    from .closed import ClosedFormModel
    from .ode import OdeModel

    if name in MODELS:
        raise InputError(f"models[{name!r}]: {name!r} is a built-in model; give your model another name")
    if isinstance(obj, ModelSpec):
        return obj
    if not isinstance(obj, (OdeModel, ClosedFormModel)):
        raise InputError(f"models[{name!r}] is a {type(obj).__name__}; expected a mechsweep.model.OdeModel "
                         "or ClosedFormModel, or a mechsweep.models.ModelSpec")
    key = ("object", id(obj))
    if key in _RESOLVED and _RESOLVED[key][0] is obj:
        return _RESOLVED[key][1]
    func = obj.compute if isinstance(obj, ClosedFormModel) else obj.rhs
    module = getattr(getattr(func, "py_func", func), "__module__", "") or ""
    file = _FILES.get(module) or getattr(sys.modules.get(module), "__file__", "") or module
    _check_any(obj, f"models[{name!r}]", file)
    spec = obj.spec(origin=f"{module}:{name}")
    check_declaration(spec, f"models[{name!r}]")
    _RESOLVED[key] = (obj, spec)
    return spec


def resolve(ref: str, base: Path | None = None):
    """The ModelSpec of a user model reference (cached per file and name in this process)."""
    from .closed import ClosedFormModel
    from .ode import OdeModel

    left, _, name = ref.rpartition(":")
    if not left or not name:
        raise InputError(f"{ref!r}: expected a built-in model name, 'file.py:NAME' or 'package.module:NAME'")
    if is_file_ref(ref):
        path = Path(left)
        if not path.is_absolute():
            path = (base or Path.cwd()) / path
        path = path.resolve()
        where = str(path)
        check_model_file(ref, path)
        module, file = _module_name(path), where
    else:
        module, file, where = left, "", left
    key = (module, file, name, module_source(module, file) if file else b"")
    if key in _RESOLVED:
        return _RESOLVED[key]
    fresh = module not in sys.modules
    mod = import_model(ref, module, file, where, base)
    if fresh and key[3]:  # the model file's bytes as imported now (its record's hash: model/sources.py)
        from . import sources
        sources.seen(file, key[3])
    file = file or getattr(mod, "__file__", "") or ""
    if not hasattr(mod, name):
        found = [k for k, v in vars(mod).items() if isinstance(v, (OdeModel, ClosedFormModel))]
        import difflib
        hint = difflib.get_close_matches(name, found, n=1, cutoff=0.5)
        raise InputError(f"{ref!r}: {where} does not define {name!r}" + (f"; did you mean {hint[0]!r}?" if hint else "")
                         + f" (models it defines: {', '.join(found) if found else 'none'})")
    model = getattr(mod, name)
    if not isinstance(model, (OdeModel, ClosedFormModel)):
        raise InputError(f"{ref!r}: {name!r} in {where} is a {type(model).__name__}, "
                         "not a mechsweep.model.OdeModel or ClosedFormModel")
    _check_any(model, ref, file)
    spec = model.spec(origin=f"{where}:{name}")
    check_declaration(spec, ref)
    _RESOLVED[key] = spec
    return spec


def check_declaration(spec, ref: str) -> None:
    """Refuse (InputError) a model whose names a dataset cannot use or whose units CF cannot read:
    every parameter, output, setting and extra dimension is named by a Python identifier that is no
    keyword (a dataset's dimensions and variables are selected by keyword: ``ds.sel(lam=0.3)``),
    its unit is one UDUNITS-2 parses (the dataset says it follows CF), and its ``latex``, when
    given, is mathtext matplotlib's parser reads (it labels the figures)."""
    from .. import cf

    items = [("parameter", p.name, "" if p.categorical else p.unit) for p in spec.params]
    items += [("output", o.name, o.unit) for o in spec.outputs]
    items += [("dimension", d.name, d.unit) for o in spec.outputs for d in o.extra_dims]
    items += [("setting", s.name, s.unit) for s in spec.settings]
    problems = []
    for what, name, unit in items:
        if not isinstance(name, str) or not name.isidentifier() or keyword.iskeyword(name):
            problems.append(f"{what} {name!r}: the name must be a Python identifier that is not a keyword "
                            f"(a dataset's dimensions and variables are selected by it, e.g. ds.sel(x=...)); "
                            f"e.g. {_identifier(name)!r}")
        if (why := cf.unit_problem(unit)) is not None:
            problems.append(f"{what} {name!r}: unit {why}")
    # a declared latex labels every figure of the model: one matplotlib cannot read is refused here,
    # naming it, rather than dropped silently when a figure is drawn (matplotlib only when one is given)
    declared = [(what, x.name, x.latex) for what, xs in (("parameter", spec.params), ("output", spec.outputs))
                for x in xs if getattr(x, "latex", "")]
    if declared:
        from ..figures._style import latex_problem

        for what, name, latex in declared:
            if (why := latex_problem(latex)) is not None:
                problems.append(f"{what} {name!r}: latex = {latex!r}: {why}")
    if problems:
        raise InputError(f"{ref!r}: model {spec.name!r}: " + "; ".join(dict.fromkeys(problems)))


def _identifier(name) -> str:
    text = re.sub(r"\W", "_", str(name)) or "x"
    text = "x" + text if text[0].isdigit() else text
    return text + "_" if keyword.iskeyword(text) else text


def _check_any(model, ref: str, file: str) -> None:
    """check() for an OdeModel, closed.check() for a ClosedFormModel."""
    from . import closed

    with exits_refused(f"{ref!r}: model {model.name!r} in {file}: running its functions at the probe point", file):
        (closed.check if isinstance(model, closed.ClosedFormModel) else check)(model, ref, file)


def _where(exc: BaseException, file: str, func=None) -> str:
    """'ExcType: message (file, line N)' with the deepest frame in the user's file; when none is
    there (the call itself failed, e.g. a function declared with the wrong number of arguments),
    the line of ``func``'s def."""
    line = None
    for frame in traceback.extract_tb(exc.__traceback__):
        if file and Path(frame.filename).resolve() == Path(file).resolve():
            line = frame.lineno
    code = getattr(func, "__code__", None)
    if line is None and code is not None and file and Path(code.co_filename).resolve() == Path(file).resolve():
        line = code.co_firstlineno
    if line is None and isinstance(exc, SyntaxError) and exc.lineno:
        line = exc.lineno
    at = getattr(exc, "mechsweep_declared_at", None)  # a measurement's own line (model/ode.py _at_declaration)
    if at is not None and file and Path(at[0]).resolve() == Path(file).resolve():
        line = at[1]
    # a SyntaxError's str() names the file and line already: its bare message, the full path after it
    text = exc.msg if isinstance(exc, SyntaxError) and exc.msg else str(exc)
    msg = f"{type(exc).__name__}: {text.splitlines()[0] if text else ''}".rstrip(": ")
    return f"{msg} ({file}, line {line})" if line else msg


def probe_params(model) -> np.ndarray:
    """One admissible parameter point: the default, else 1 clipped into the declared range."""
    values = []
    for prm in model.params:
        if prm.categorical:
            values.append(0.0)
            continue
        if prm.default is not None:
            values.append(float(prm.default))
            continue
        lo, hi = prm.lo, prm.hi
        v = 1.0
        if v < lo or (prm.lo_open and v <= lo):
            v = lo + 1.0 if math.isfinite(lo) else v
        if v > hi or (prm.hi_open and v >= hi):
            v = 0.5 * (lo + hi) if math.isfinite(lo) else hi - 1.0
        values.append(v)
    return np.array(values, dtype=np.float64)


_ANSI = re.compile(r"\x1b\[[0-9;]*m")


def _probe_layout(model) -> np.ndarray:
    """The probe row of p: parameters, settings at their defaults, internal slots 0 (exactly the
    declared length: reading beyond it is an IndexError at the probe)."""
    settings = [float(s.default) for s in getattr(model, "settings", ())]
    return np.concatenate([probe_params(model), np.array(settings, dtype=np.float64),
                           np.zeros(len(getattr(model, "internal", ())))])


def _system_args(role, n_s):
    """Args builder of one call of a System function at the probe point."""
    return {"rhs": lambda p, y: (0.0, np.zeros(n_s), p, np.zeros(n_s)),
            "initial": lambda p, y: (p, np.zeros(n_s)),
            "jac": lambda p, y: (0.0, np.zeros(n_s), p, np.zeros((n_s, n_s))),
            "accel": lambda p, y: (0.0, np.zeros(n_s // 2), p, np.zeros(n_s // 2)),
            "symplectic_step": lambda p, y: (p, 1e-10),
            "prepare": lambda p, y: (p, 1e-10)}[role]


def _extra_functions(model):
    """(what, function, args builder) of the optional functions the kernel calls besides initial,
    rhs, forcing_period and jac; args builder: (p, y0) -> arguments of one call."""
    n_s = len(model.states)
    out = []
    if getattr(model, "classify", None) is not None:
        out.append(("classify", model.classify, lambda p, y: (p,)))
    if getattr(model, "accel", None) is not None:
        out.append(("accel", model.accel, lambda p, y: (0.0, y[:n_s // 2].copy(), p, np.zeros(n_s // 2))))
        out.append(("symplectic_step", model.symplectic_step, lambda p, y: (p, 1e-10)))
    for m in model.measurements:
        for role, func in getattr(m, "functions", lambda: ())():
            if role == "event":
                out.append((f"{m.name}.event", func, lambda p, y: (0.0, y.copy(), p)))
            elif role == "t_max":
                out.append((f"{m.name}.t_max", func, lambda p, y: (p,)))
            elif role == "value":
                out.append((f"{m.name}.value", func, lambda p, y: (p, 1.0)))
            elif role == "refine":
                out.append((f"{m.name}.refine", func, lambda p, y: (p, 1e-10, 1.0)))
            elif role == "of" and not getattr(m, "sampled", False):  # an Extremum's expression f(t, y, p)
                out.append((f"{m.name}.{role}", func, lambda p, y: (0.0, y.copy(), p)))
            elif role in ("t0", "t1"):  # an Extremum's window end t0(p), t1(p)
                out.append((f"{m.name}.{role}", func, lambda p, y: (p,)))
            elif role == "variational":  # Floquet's variational system about the known orbit: Phi = I
                out.append((f"{m.name}.variational", func,
                            lambda p, y: (0.0, np.eye(n_s).ravel(), p, np.full(n_s * n_s, np.nan))))
            elif role == "variational_jac":
                out.append((f"{m.name}.variational_jac", func,
                            lambda p, y: (0.0, np.eye(n_s).ravel(), p, np.zeros((n_s * n_s, n_s * n_s)))))
            elif role in ("rhs", "initial", "jac", "accel", "symplectic_step", "prepare"):
                out.append((f"{m.name}.system.{role}", func, _system_args(role, n_s)))
    for c in getattr(model, "closed_forms", ()):
        out.append((f"closed form {c.name}", c.func, lambda p, y, k=len(c.needs): (p,) + (1.0,) * k))
        if getattr(c, "classify", None) is not None:
            out.append((f"closed form {c.name}.classify", c.classify, lambda p, y: (p,)))
    return out


def check(model, ref: str, file: str) -> None:
    """Run the model's functions once in plain Python at a probe point (p of exactly the declared
    length: parameters, settings, internal slots; an undeclared read is an IndexError): classify,
    prepare, initial, rhs, then the others; then compile them with numba (and refuse one whose
    value is used but that can return None, or a status function whose result is no int:
    :func:`return_problem`)."""
    label = f"{ref!r}: model {model.name!r} in {file}"
    n_p, n_s = len(model.params), len(model.states)
    p = _probe_layout(model)
    layout = (f"the model declares {n_p} parameter(s), {len(getattr(model, 'settings', ()))} setting(s), "
              f"{len(getattr(model, 'internal', ()))} internal slot(s) and {n_s} state(s)")
    y0 = np.full(n_s, np.nan)
    dydt = np.full(n_s, np.nan)

    def probe(what, func, args):
        own = getattr(func, "py_func", func)
        func = _with_engine_helpers(own)  # the user's numba helpers as the kernel runs them
        try:
            with np.errstate(all="ignore"):
                return func(*args)
        except IndexError as exc:
            raise InputError(f"{label}: {what} indexes beyond its arrays at the probe point p = {p.tolist()} "
                             f"({layout}): {_where(exc, file, own)}") from None
        except Exception as exc:
            raise InputError(f"{label}: {what} raised at the probe point p = {p.tolist()}: "
                             f"{_where(exc, file, own)}") from None

    for what in ("classify", "prepare"):
        func = getattr(model, what, None)
        if func is not None:
            code = probe(what, func, (p,) if what == "classify" else (p, 1e-10))
            if not isinstance(code, (int, np.integer)) or isinstance(code, bool):
                raise InputError(f"{label}: {what} returned {code!r}; expected a status code (an int of "
                                 "mechsweep.status)")
    for what, func, args, result in (("initial", model.initial, (p, y0), y0),
                                     ("rhs", model.rhs, (0.0, y0, p, dydt), dydt)):
        probe(what, func, args)
        unwritten = [model.states[i] for i in range(n_s) if np.isnan(result[i])
                     and not _writes_nan(getattr(func, "py_func", func), args, i)]
        if unwritten:
            raise InputError(f"{label}: {what} did not write {', '.join(unwritten)} (it must write all "
                             f"{n_s} components)")
    if model.forcing_period is not None:
        T = probe("forcing_period", model.forcing_period, (p,))
        if not isinstance(T, (int, float, np.floating, np.integer)):
            raise InputError(f"{label}: forcing_period returned {T!r}; expected a number")
    sw = getattr(model, "switch_times", None)
    if callable(sw):  # a tuple of numbers (model/switches.py checks the values per point at run time)
        value = probe("switch_times", sw, (p,))
        if not isinstance(value, (tuple, np.ndarray)) or not len(value) or not all(
                isinstance(x, (float, np.floating)) for x in value):
            raise InputError(f"{label}: switch_times returned {value!r}; expected a non-empty tuple of floats (times "
                             "in [0, T) of one forcing period)")
    extra = _extra_functions(model)
    for what, func, build in extra:
        args = build(p, y0)
        value = probe(what, func, args)
        if what.endswith(".variational"):  # every one of the n*n components of dPhi
            unwritten = [i for i in range(n_s * n_s) if np.isnan(args[-1][i])
                         and not _writes_nan(getattr(func, "py_func", func), args, i)]
            if unwritten:
                raise InputError(f"{label}: {what} did not write dPhi[{unwritten[0]}] (it must write all "
                                 f"{n_s * n_s} components: Phi is n*n = {n_s} x {n_s}, column-major)")
        writes = what == "accel" or what.endswith((".rhs", ".initial", ".jac", ".accel", ".variational",
                                                   ".variational_jac"))  # return nothing
        if not writes and not isinstance(value, (int, float, np.floating, np.integer)):
            raise InputError(f"{label}: {what} returned {value!r}; expected a number")
    _check_writes(model, label, p, y0)
    pp = np.concatenate([p, np.zeros(3 * n_s + n_s * n_s)])
    funcs = [("initial", model.initial, (pp, np.zeros(n_s))), ("rhs", model.rhs, (0.0, y0.copy(), pp, np.zeros(n_s)))]
    if model.forcing_period is not None:
        funcs.append(("forcing_period", model.forcing_period, (pp,)))
    if callable(sw):
        funcs.append(("switch_times", sw, (pp,)))
    if getattr(model, "jac", None) is not None:
        funcs.append(("jac", model.jac, (0.0, y0.copy(), pp, np.zeros((n_s, n_s)))))
    if getattr(model, "prepare", None) is not None:
        funcs.append(("prepare", model.prepare, (pp.copy(), 1e-10)))
    funcs += [(what, func, build(pp, y0)) for what, func, build in extra]
    writers = ("initial", "rhs", "jac", "accel", "variational", "variational_jac")  # their results are unused
    for what, func, args in funcs:
        module, path, qual = function_ref(func, what, model.name)
        try:
            disp = jitted(module, path, qual)
            disp(*args)
        except Exception as exc:
            raise compile_failure(exc, file, label, what) from None
        if what.rsplit(".", 1)[-1] in writers:
            continue
        problem = return_problem(disp, what, status=what.rsplit(".", 1)[-1] in ("classify", "prepare"))
        if problem is not None:
            raise InputError(f"{label}: {problem}")


def compile_failure(exc: Exception, file: str | None, label: str, what: str) -> InputError:
    """numba's compile error, trimmed to its first line and the line of the user's file."""
    text = _ANSI.sub("", str(exc))
    line = None
    for m in re.finditer(r'File "([^"]+)", line (\d+)', text):
        if file and Path(m.group(1)).name == Path(file).name:
            line = int(m.group(2))
    lines = [s.strip() for s in text.splitlines() if s.strip()
             and not s.startswith(("Failed in", "During:", "File ", "^", "<source"))]
    why = lines[0] if lines else type(exc).__name__
    at = f" ({file}, line {line})" if line else ""
    helper = re.search(r"Untyped global name '(\w+)'.*<class 'function'>", text)
    if helper:  # a plain Python helper: mechsweep jit-compiles only the functions it is given
        why += (f" ({helper.group(1)} is a plain Python function: a helper that {what} calls must be a numba "
                f"function; decorate it with @numba.njit)")
    return InputError(f"{label}: numba cannot compile {what}{at}: {why}")


def return_problem(disp, what: str, *, status: bool = False) -> str | None:
    """Why the compiled user function ``disp`` cannot be called for its value (None: it can): a
    path that returns nothing (numba types the result as Optional: at a point where that path is
    taken the compiled code fails on None, inside the parallel loop), or, with ``status``, a
    result that is no whole number (a float status 0.5 would be stored as 0, ok). Judged from
    the types numba inferred, whatever path the probe point took; the message names the line
    of a bare ``return`` or the end reached without one (:func:`_missing_returns`)."""
    from numba.core import types as nb

    found = [c.signature.return_type for c in getattr(disp, "overloads", {}).values()]
    bad = next((t for t in found if isinstance(t, (nb.Optional, nb.NoneType))
                or (status and not isinstance(t, nb.Integer))), None)
    if bad is None:
        return None
    expected = "a status code of mechsweep.status (an int, e.g. st.OK)" if status else "a value"
    if isinstance(bad, (nb.Optional, nb.NoneType)):
        where = _missing_returns(getattr(disp, "py_func", disp))
        return (f"{what} can return None (numba types its result as {bad}): every path must return {expected}"
                + (f"; {where}" if where else ""))
    return f"{what} returns {bad}, not {expected}"


def _missing_returns(func) -> str:
    """Where ``func`` returns nothing: each bare ``return`` (or ``return None``) and its end when
    the last statement can complete, with file and line (judged from the source; '' when the
    source cannot be read)."""
    import ast
    import inspect
    import textwrap

    try:
        lines, first = inspect.getsourcelines(func)
        tree = ast.parse(textwrap.dedent("".join(lines)))
        file = inspect.getsourcefile(func) or ""
    except (OSError, TypeError, SyntaxError):
        return ""
    fn = tree.body[0] if tree.body else None
    if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
        return ""
    at = (lambda n: n.lineno + first - 1)  # noqa: E731 (the file's line of a node)
    bare = []
    stack = list(fn.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue  # a nested function's returns are its own
        if isinstance(node, ast.Return) and (node.value is None or (isinstance(node.value, ast.Constant)
                                                                     and node.value.value is None)):
            bare.append(at(node))
        stack.extend(ast.iter_child_nodes(node))
    place = (lambda n: f"({file}, line {n})" if file else f"(line {n})")  # noqa: E731
    parts = [f"a return without a value {place(n)}" for n in sorted(bare)]
    if _completes(fn.body):
        parts.append(f"its end is reached without a return {place(at(fn.body[-1]))}")
    return "; ".join(parts)


def _completes(body) -> bool:
    """Whether control can run off the end of the statements ``body`` (True when unsure)."""
    import ast

    def breaks(stmts) -> bool:  # a break of this loop (not of a loop nested in it)
        stack = list(stmts)
        while stack:
            node = stack.pop()
            if isinstance(node, ast.Break):
                return True
            if not isinstance(node, (ast.For, ast.AsyncFor, ast.While, ast.FunctionDef, ast.AsyncFunctionDef,
                                     ast.Lambda, ast.ClassDef)):
                stack.extend(ast.iter_child_nodes(node))
        return False

    def completes(s) -> bool:
        if isinstance(s, (ast.Return, ast.Raise)):
            return False
        if isinstance(s, ast.If):
            return _completes(s.body) or _completes(s.orelse)
        if isinstance(s, (ast.With, ast.AsyncWith)):
            return _completes(s.body)
        if isinstance(s, ast.Try):
            if s.finalbody and not _completes(s.finalbody):
                return False
            return (_completes(s.body) and _completes(s.orelse)) or any(_completes(h.body) for h in s.handlers)
        if isinstance(s, ast.While):
            forever = isinstance(s.test, ast.Constant) and bool(s.test.value)
            return breaks(s.body) or (not forever and _completes(s.orelse))
        if isinstance(s, (ast.For, ast.AsyncFor)):
            return breaks(s.body) or _completes(s.orelse)
        return True

    return all(completes(s) for s in body)


def _writes_nan(func, args, i) -> bool:
    """Whether component i really is computed as NaN (written) rather than left unwritten."""
    args = tuple(a.copy() if isinstance(a, np.ndarray) else a for a in args)
    out = args[-1]
    out[:] = 12345.678
    with np.errstate(all="ignore"):
        func(*args)
    return out[i] != 12345.678


def _check_writes(model, label: str, p: np.ndarray, y0: np.ndarray) -> None:
    """Every function of the model writes only the arguments its role may write (model/writes.py:
    an event nothing, an rhs its dydt, prepare the internal slots of p, ...), by its source and by
    one more call at the probe point (``p`` after prepare, ``y0`` from initial)."""
    from . import writes

    writes.check(writes.ode_calls(model, p.copy(), y0.copy()), label)


# ============================================================================= loading is an input step
def check_model_file(ref: str, path: Path) -> None:
    """InputError unless ``path`` is a regular file whose name ends in .py (a model file is
    imported as Python source: a folder, a device, a FIFO or another kind of file is named as
    what it is, not reported as a failed import)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        mode = None
    if mode is None:
        hint = path.with_suffix(".py") if path.suffix != ".py" else None
        raise InputError(f"{ref!r}: model file {path} does not exist"
                         + (f" (did you mean {hint.name}?)" if hint is not None and hint.is_file() else ""))
    kinds = ((stat.S_ISDIR, "is a folder"), (stat.S_ISFIFO, "is a FIFO (named pipe)"),
             (stat.S_ISCHR, "is a character device"), (stat.S_ISBLK, "is a block device"),
             (stat.S_ISSOCK, "is a socket"))
    for test, what in kinds:
        if test(mode):
            raise InputError(f"{ref!r}: model file {path} {what}, not a Python file")
    if not stat.S_ISREG(mode):
        raise InputError(f"{ref!r}: model file {path} is not a regular file")
    if path.suffix != ".py":
        raise InputError(f"{ref!r}: {path} is not a Python file: a model file's name ends in .py "
                         "(a model is a built-in name, 'file.py:NAME' or 'package.module:NAME')")


def import_model(ref: str, module: str, file: str, where: str, base: Path | None = None):
    """The user's module (``import_module``), every failure of its import an InputError naming the
    file and line: an exception, and an exit (sys.exit, os._exit, KeyboardInterrupt raised by the
    code, any other BaseException; :func:`exits_refused`). A module name that is no module but a
    file beside the scene ("notes.txt:NAME") is named as the file it is."""
    left = ref.rpartition(":")[0]
    with exits_refused(f"{ref!r}: importing {where}", file):
        try:
            return import_module(module, file)
        except ModuleNotFoundError as exc:
            if not file and exc.name and left.startswith(exc.name):
                path = (base or Path.cwd()) / left
                if os.path.lexists(path):
                    check_model_file(ref, path.resolve())
                raise InputError(f"{ref!r}: module {left!r} is not importable ({exc})") from None
            raise InputError(f"{ref!r}: importing {where} failed: {_where(exc, file)}") from None
        except Exception as exc:  # the user's code raised on import
            raise InputError(f"{ref!r}: importing {where} failed: {_where(exc, file)}") from None


class ExitAtLoad(BaseException):
    """Raised in place of ``os._exit``/``os.abort`` when the user's code calls one while a model
    loads (:func:`exits_refused`)."""


@contextmanager
def exits_refused(what: str, file: str = ""):
    """Run the user's code of a model's loading (its import, the probe) so that no way of ending
    the process passes as success or as an interruption: SystemExit (``sys.exit``, ``exit()``),
    ``os._exit`` and ``os.abort`` (replaced in this thread while the block runs: they cannot be
    caught), a KeyboardInterrupt the code raises itself and any other BaseException become an
    InputError (exit 2) naming the file and line. A real Ctrl-C or SIGTERM during the block (the
    handler in place is wrapped to note it) goes on as the interruption it is (exit 130, 143)."""
    ident = threading.get_ident()
    noted: list[int] = []
    patched = []

    def stand_in(name, real):
        def call(*args):
            if threading.get_ident() != ident:  # another thread's exit is not the model's
                return real(*args)
            raise ExitAtLoad(f"{name}({', '.join(repr(a) for a in args)}) called")
        return call

    for mod in {id(m): m for m in (os, sys.modules.get("posix"), sys.modules.get("nt")) if m is not None}.values():
        for name in ("_exit", "abort"):
            real = getattr(mod, name, None)
            if real is not None:
                patched.append((mod, name, real))
                setattr(mod, name, stand_in(f"os.{name}", real))
    handlers = {}
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            previous = signal.getsignal(sig)
            if callable(previous):
                def note(signum, frame, previous=previous):
                    noted.append(signum)
                    return previous(signum, frame)
                handlers[sig] = previous
                signal.signal(sig, note)
    try:
        yield
    except Exception:
        raise
    except BaseException as exc:
        if noted and isinstance(exc, KeyboardInterrupt):  # a real signal: the interruption it is
            raise
        raise InputError(f"{what}: {_exit_text(exc, file)}; loading a model may not exit or interrupt the "
                         "process") from None
    finally:
        for mod, name, real in patched:
            setattr(mod, name, real)
        for sig, previous in handlers.items():
            signal.signal(sig, previous)


def _exit_text(exc: BaseException, file: str) -> str:
    """What ended the load and where: the deepest frame of the user's code (not mechsweep's stand-in
    nor importlib's), and the model file's line when that frame is in a module the file imports."""
    if isinstance(exc, SystemExit):
        what = f"SystemExit({exc.code!r}) raised (sys.exit, exit() or raise SystemExit)"
    elif isinstance(exc, ExitAtLoad):
        what = str(exc)
    elif isinstance(exc, KeyboardInterrupt):
        what = "KeyboardInterrupt raised by the code (no Ctrl-C was pressed)"
    else:
        text = str(exc).splitlines()[0] if str(exc) else ""
        what = f"{type(exc).__name__} raised (a BaseException, not an Exception){': ' + text if text else ''}"
    frames = [f for f in traceback.extract_tb(exc.__traceback__)
              if not f.filename.startswith("<") and Path(f.filename).resolve() != Path(__file__).resolve()
              and not Path(f.filename).resolve().is_relative_to(Path(importlib.__file__).resolve().parent)]
    if not frames:
        return what
    last = frames[-1]
    at = f"{what} at {last.filename}, line {last.lineno}"
    if file and Path(last.filename).resolve() != Path(file).resolve():
        own = [f for f in frames if Path(f.filename).resolve() == Path(file).resolve()]
        if own:
            at += f" (reached from {file}, line {own[-1].lineno})"
    return at
