"""A user model's module and functions as the engine compiles them: the module imported (a model
file under a name of its own, :func:`module_name`), a function's reference (module, path, qualified
name), and its numba dispatcher with mechsweep's options (:func:`jitted`, :func:`inlined`,
:func:`with_engine_helpers`), named for numba's disk cache after its module and what that depends
on. Also the probe point (:func:`probe_params`) and a failure's text at the line of the user's file
(:func:`where`, :func:`compile_failure`). Finding and checking a model: model/user.py."""
from __future__ import annotations

import hashlib
import importlib
import importlib.util
import math
import re
import sys
import traceback
import types
from pathlib import Path

import numpy as np

from .. import _jit
from ..errors import InputError
from . import sources

_JITTED: dict[tuple, object] = {}


def module_name(path: Path) -> str:
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
    sources.FILES[module] = path
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
    return module, sources.FILES.get(module, ""), qual


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
        _JITTED[key] = decorate(_renamed(with_engine_helpers(getattr(obj, "py_func", obj)), module))
    return _JITTED[key]


_INLINED: dict[tuple, object] = {}


def inlined(module: str, path: str, qualname: str):
    """The user function of :func:`jitted`, compiled into each numba caller (_jit.jit_into_caller):
    the one-point kernel's guards take it so (engine/calls.py), which saves numba a compile of its
    own per function. A function with a ``raise`` (or ``assert``) of its own stays jitted's: numba's
    ``try`` in the guard does not catch a raise inlined into its body (measured: the exception
    escaped the kernel), while one raised by a function it calls is caught either way."""
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


def with_engine_helpers(func):
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
            helper = with_engine_helpers(v.py_func)
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
    """``func`` with its qualified name suffixed by a hash of ``module`` and of what its code depends
    on (sources.module_digest). numba names a disk-cache entry after the file and qualified name
    only, and the entry re-imports the module it was compiled in: one file loaded under two module
    names would otherwise load the other name's entry ("No module named ..."). And numba's index
    checks only the function's own file: the digest gives an edited dependency a new name."""
    g = types.FunctionType(func.__code__, func.__globals__, func.__name__, func.__defaults__, func.__closure__)
    g.__kwdefaults__ = func.__kwdefaults__
    g.__module__ = func.__module__
    g.__qualname__ = f"{func.__qualname__}__{_module_tag(module)}"
    return g


def _module_tag(module: str) -> str:
    """8 hex digits naming ``module`` and its dependencies (mechsweep's own modules: the name alone; the
    cache folder is keyed by mechsweep's sources)."""
    digest = sources.module_digest(module)
    return hashlib.sha256((module + (f"|{digest}" if digest else "")).encode()).hexdigest()[:8]


def where(exc: BaseException, file: str, func=None) -> str:
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


def probe_call(label: str, what: str, func, args: tuple, p: np.ndarray, sizes: str, file: str, own=None):
    """``func(*args)`` at the probe point ``p``, an exception an InputError naming the function and
    the line of the user's file (``sizes``: what the model declares, for an IndexError)."""
    try:
        with np.errstate(all="ignore"):
            return func(*args)
    except IndexError as exc:
        raise InputError(f"{label}: {what} indexes beyond its arrays at the probe point p = {p.tolist()} "
                         f"({sizes}): {where(exc, file, own)}") from None
    except Exception as exc:
        raise InputError(f"{label}: {what} raised at the probe point p = {p.tolist()}: "
                         f"{where(exc, file, own)}") from None


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
