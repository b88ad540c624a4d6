"""User models, found by reference and checked as they load: ``"my_models.py:NAME"`` (a path
relative to the scene file) or ``"package.module:NAME"``. Loading a model file executes it, as any
Python import does.

Every problem is an :class:`~mechsweep.errors.InputError` naming the file (and the line, where
Python or numba gives one), raised while the scene is loaded, before any file is written: a file
that is missing or fails to import, NAME not defined or not an OdeModel (or ClosedFormModel:
closed.check), a function that raises, reads or writes beyond its arrays or leaves a component
unwritten at a probe point (run once in plain Python), writes into an argument its role may not
write (model/writes.py), or that numba cannot compile; and an exit while the model loads
(exits_refused)."""
from __future__ import annotations

import importlib
import keyword
import os
import re
import signal
import stat
import sys
import threading
import traceback
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..models import MODELS
from . import load, sources, writes
from .closed import ClosedFormModel, check as check_closed
from .ode import OdeModel
from .spec import ModelSpec

_RESOLVED: dict[tuple, object] = {}


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
    file = sources.FILES.get(module) or getattr(sys.modules.get(module), "__file__", "") or module
    _check_any(obj, f"models[{name!r}]", file)
    spec = obj.spec(origin=f"{module}:{name}")
    check_declaration(spec, f"models[{name!r}]")
    _RESOLVED[key] = (obj, spec)
    return spec


def resolve(ref: str, base: Path | None = None):
    """The ModelSpec of a user model reference (cached per file and name in this process)."""
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
        module, file = load.module_name(path), where
    else:
        module, file, where = left, "", left
    key = (module, file, name, load.module_source(module, file) if file else b"")
    if key in _RESOLVED:
        return _RESOLVED[key]
    fresh = module not in sys.modules
    mod = import_model(ref, module, file, where, base)
    if fresh and key[3]:  # the model file's bytes as imported now (its record's hash: model/sources.py)
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
        from .._mathtext import latex_problem

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
    with exits_refused(f"{ref!r}: model {model.name!r} in {file}: running its functions at the probe point", file):
        (check_closed if isinstance(model, ClosedFormModel) else check)(model, ref, file)


def _probe_layout(model) -> np.ndarray:
    """The probe row of p: parameters, settings at their defaults, internal slots 0 (exactly the
    declared length: reading beyond it is an IndexError at the probe)."""
    settings = [float(s.default) for s in getattr(model, "settings", ())]
    return np.concatenate([load.probe_params(model), np.array(settings, dtype=np.float64),
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
    args = {"event": lambda p, y: (0.0, y.copy(), p),
            "t_max": lambda p, y: (p,),
            "value": lambda p, y: (p, 1.0),
            "refine": lambda p, y: (p, 1e-10, 1.0),
            "of": lambda p, y: (0.0, y.copy(), p),  # an Extremum's expression f(t, y, p)
            "t0": lambda p, y: (p,),  # an Extremum's window ends t0(p), t1(p)
            "t1": lambda p, y: (p,),
            # Floquet's variational system about the known orbit: Phi = I
            "variational": lambda p, y: (0.0, np.eye(n_s).ravel(), p, np.full(n_s * n_s, np.nan)),
            "variational_jac": lambda p, y: (0.0, np.eye(n_s).ravel(), p, np.zeros((n_s * n_s, n_s * n_s)))}
    for m in model.measurements:
        for role, func in getattr(m, "functions", lambda: ())():
            if role in args and not (role == "of" and getattr(m, "sampled", False)):
                out.append((f"{m.name}.{role}", func, args[role]))
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
    :func:`load.return_problem`)."""
    label = f"{ref!r}: model {model.name!r} in {file}"
    n_p, n_s = len(model.params), len(model.states)
    p = _probe_layout(model)
    layout = (f"the model declares {n_p} parameter(s), {len(getattr(model, 'settings', ()))} setting(s), "
              f"{len(getattr(model, 'internal', ()))} internal slot(s) and {n_s} state(s)")
    y0 = np.full(n_s, np.nan)
    dydt = np.full(n_s, np.nan)

    def probe(what, func, args):
        own = getattr(func, "py_func", func)
        # the user's numba helpers as the kernel runs them
        return load.probe_call(label, what, load.with_engine_helpers(own), args, p, layout, file, own)

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
        module, path, qual = load.function_ref(func, what, model.name)
        try:
            disp = load.jitted(module, path, qual)
            disp(*args)
        except Exception as exc:
            raise load.compile_failure(exc, file, label, what) from None
        if what.rsplit(".", 1)[-1] in writers:
            continue
        problem = load.return_problem(disp, what, status=what.rsplit(".", 1)[-1] in ("classify", "prepare"))
        if problem is not None:
            raise InputError(f"{label}: {problem}")


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
        if hint is None or not hint.is_file():  # a misspelt name: the closest Python file beside it
            import difflib
            try:
                beside = sorted(p.name for p in path.parent.glob("*.py") if p.is_file())
            except OSError:
                beside = []
            close = difflib.get_close_matches(path.name, beside, n=1, cutoff=0.8)
            hint = path.parent / close[0] if close else None
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
            return load.import_module(module, file)
        except ModuleNotFoundError as exc:
            if not file and exc.name and left.startswith(exc.name):
                path = (base or Path.cwd()) / left
                if os.path.lexists(path):
                    check_model_file(ref, path.resolve())
                raise InputError(f"{ref!r}: module {left!r} is not importable ({exc})") from None
            raise InputError(f"{ref!r}: importing {where} failed: {load.where(exc, file)}") from None
        except Exception as exc:  # the user's code raised on import
            raise InputError(f"{ref!r}: importing {where} failed: {load.where(exc, file)}") from None


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
