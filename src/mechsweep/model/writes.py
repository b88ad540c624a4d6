"""What each function of a user model may write into, checked when the model is loaded.

The engine passes a model's functions the arrays it integrates and the point's ``p`` by
reference: an event that writes ``y[1] = -e * y[1]`` changes the integrator's own state behind its
error control, and a function that writes ``p[0]`` changes the parameter every later call reads.
Neither raises; both give wrong numbers with status ok. So each role has the arguments it may
write (``ROLES``: an rhs writes ``dydt``, ``initial`` writes ``y0``, ``prepare`` the internal slots
of ``p``, an event nothing), and a model whose function may write any other argument is refused
(InputError, exit 2) naming the function, the argument, the file and the line.

Two nets:

- a static one (``param_writes``): the function's source, read with :mod:`ast`, followed through
  aliases and views (``z = y``, ``z = y[1:]``, ``y.T``, ``np.asarray(y)``), the ways numpy writes
  an array (``y[i] = ``, ``y[:] = ``, ``y[i] += ``, ``z += `` on an alias, ``y.fill``, ``y.sort``,
  ``np.copyto(y, ...)``, ``np.put``, a ufunc's positional output or ``out=``, ``np.add.at``) and
  into the helpers it passes an argument to (plain or ``@numba.njit``, in the same file or
  imported; nested functions too);
- a dynamic one (``_changed``): each function called once more in plain Python at the probe point
  on copies of its arguments, the bytes of every argument it may not write compared before and
  after. It sees what the source does not show (a helper whose source cannot be read, a compiled
  extension), at the probe point only.

Writing into a local array, or into the argument a role writes, is not a finding.
"""
from __future__ import annotations

import ast
import builtins
import inspect
import textwrap
import types
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .load import with_engine_helpers


@dataclass(frozen=True)
class Role:
    """A function's role: what each argument is (for messages; ``rest`` for ``*args``), which
    positions it may write (prepare: only the internal slots of p, ``Call.slots``), and the rule
    in words."""

    args: tuple[str, ...]
    writes: tuple[int, ...] = ()
    rule: str = ""
    rest: str = ""


_TYP = ("time", "state", "parameter")
ROLES = {
    "rhs": Role(_TYP + ("derivative",), (3,), "an rhs may write only its 4th argument (dydt)"),
    "jac": Role(_TYP + ("Jacobian",), (3,), "jac may write only its 4th argument (J)"),
    "accel": Role(("time", "position", "parameter", "acceleration"), (3,),
                  "accel may write only its 4th argument (the accelerations)"),
    "variational": Role(("time", "variational state", "parameter", "dPhi"), (3,),
                        "variational may write only its 4th argument (dPhi)"),
    "variational_jac": Role(("time", "variational state", "parameter", "Jacobian"), (3,),
                            "variational_jac may write only its 4th argument (JJ)"),
    "initial": Role(("parameter", "initial state"), (1,), "initial may write only its 2nd argument (y0)"),
    "prepare": Role(("parameter", "rtol"), (), "prepare may write only the model's internal slots of p"),
    "event": Role(_TYP, (), "an event may not change the state or the parameters (state jumps are not supported)"),
    "of": Role(_TYP, (), "an expression may not write into its arguments"),
    "error": Role(_TYP, (), "a Kick's error may not write into its arguments"),
    "response": Role(_TYP, (), "a Kick's response may not write into its arguments"),
    "classify": Role(("parameter",), (), "classify may not write into p"),
    "forcing_period": Role(("parameter",), (), "forcing_period may not write into p"),
    "switch_times": Role(("parameter",), (), "switch_times may not write into p"),
    "t_max": Role(("parameter",), (), "t_max may not write into p"),
    "t0": Role(("parameter",), (), "a window's end may not write into p"),
    "t1": Role(("parameter",), (), "a window's end may not write into p"),
    "symplectic_step": Role(("parameter", "rtol"), (), "symplectic_step may not write into p"),
    "value": Role(("parameter", "value"), (), "value may not write into p"),
    "refine": Role(("parameter", "rtol", "value"), (), "refine may not write into p"),
    "closed": Role(("parameter",), (), "a closed form may not write into p", rest="needed value"),
    "invariant": Role(("state", "parameter"), (), "an invariant may not write into its arguments"),
    "period": Role(("parameter",), (), "an invariant's period may not write into p"),
    "compute": Role(("parameter", "want", "row", "curves", "slot", "scratch"), (2, 3, 5),
                    "compute may write only row, curves and scratch", rest="shared data"),
}
_SYSTEM = ("rhs", "initial", "jac", "accel", "symplectic_step", "prepare")
_NAMES = {"of": "expression", "t0": "window start t0", "t1": "window end t1", "closed": "closed form",
          "value": "value"}


@dataclass
class Call:
    """One function of a model as the write check sees it: what it is (for messages), its role,
    the function, arguments to call it with at the probe point, and (prepare) the slots of p it
    may write."""

    what: str
    role: str
    func: object
    args: tuple
    slots: tuple[int, int] | None = None  # prepare: [lo, hi) of p it may write


@dataclass(frozen=True)
class Finding:
    """A place where a function may write into one of its parameters (position, or ``"*"`` for
    its ``*args``): file, line, the statement, the constant index written (when it is one), and
    the helpers the write goes through (name, file, line, statement)."""

    pos: object
    file: str
    line: int
    text: str
    index: int | None = None
    via: tuple = field(default=())


# ============================================================================= the static net
_FOREIGN = ("numpy", "numba", "scipy", "math", "cmath", "builtins", "llvmlite")
_VIEW_ATTRS = ("T", "mT", "flat", "real", "imag")
_VIEW_METHODS = ("reshape", "ravel", "view", "transpose", "swapaxes", "squeeze", "__getitem__")
_WRITING_METHODS = ("fill", "sort", "put", "itemset", "resize", "setfield", "partition", "byteswap", "setflags",
                    "__setitem__", "__iadd__", "__isub__", "__imul__", "__itruediv__", "__ifloordiv__", "__ipow__")


def _numpy_sets():
    views = {np.asarray, np.asanyarray, np.ravel, np.reshape, np.squeeze, np.transpose, np.atleast_1d,
             np.atleast_2d, np.atleast_3d, np.expand_dims, np.swapaxes, np.moveaxis, np.ascontiguousarray,
             np.asfortranarray, np.diagonal}
    writing = {np.copyto: "dst", np.put: "a", np.place: "arr", np.putmask: "a", np.fill_diagonal: "a",
               np.put_along_axis: "arr", np.random.shuffle: "x"}  # each writes its first argument (by keyword: this)
    return {id(f) for f in views}, {id(f): kw for f, kw in writing.items()}


_VIEW_FUNCS, _WRITING_FUNCS = _numpy_sets()
_SCANS: dict[tuple, dict] = {}


def param_writes(func, depths: tuple | None = None) -> dict:
    """{parameter position (or "*" for ``*args``): Finding} of the parameters ``func`` may write
    into, read from its source (``func`` a Python function or a numba dispatcher). ``depths``:
    per positional parameter, how many indexings give a scalar (1 for a 1-D array, 0 for a
    number), and for ``*args`` the last entry; None: every parameter an array of any rank.
    Nothing is found for a function whose source cannot be read (the dynamic net's case)."""
    py = getattr(func, "py_func", func)
    code = getattr(py, "__code__", None)
    if code is None or not isinstance(py, types.FunctionType):
        return {}
    key = (code, code.co_filename, depths)  # code objects compare equal across files: the file names the finding
    if key in _SCANS:
        return _SCANS[key]
    _SCANS[key] = {}  # a recursive helper: what is found so far
    try:
        lines, start = inspect.getsourcelines(py)
        src = textwrap.dedent("".join(lines))
        tree = ast.parse(src)
    except (OSError, TypeError, SyntaxError, IndentationError):
        return {}
    node = next((n for n in ast.walk(tree) if isinstance(n, (ast.FunctionDef, ast.AsyncFunctionDef))
                 and n.name == py.__name__), None)
    if node is None:
        return {}
    found = _Scanner(py, src, start - 1).scan(node, depths)
    _SCANS[key] = found
    return found


class _Scanner:
    """A flow-sensitive may-alias walk of one function's statements: which names may refer to
    (a view of) which parameter, and every place such a name is written through."""

    def __init__(self, func, src: str, offset: int):
        self.func, self.src, self.offset = func, src, offset
        self.file = func.__code__.co_filename
        self.globals = func.__globals__
        self.closure = {}
        for name, cell in zip(func.__code__.co_freevars, func.__closure__ or ()):
            try:
                self.closure[name] = cell.cell_contents
            except ValueError:  # an empty cell
                pass
        self.found: dict = {}
        self.stmt = None
        self.local_defs: dict = {}
        self.inlining: set = set()
        self.own: dict = {}  # each parameter's name -> what it refers to on entry

    # -- entry
    def scan(self, node, depths) -> dict:
        a = node.args
        names = [x.arg for x in a.posonlyargs + a.args]
        env = {}
        for i, name in enumerate(names):  # depths: one per positional parameter, then *args'
            d = depths[i] if depths is not None and i < len(depths) - 1 else 9
            if d:
                env[name] = frozenset({(i, d)})
        if a.vararg:
            d = 9 if depths is None else depths[-1]
            env[a.vararg.arg] = frozenset({("*", d + 1)})
        self.own = dict(env)
        self.block(node.body, env)
        return self.found

    # -- what an expression may refer to: {(origin, depth)}, depth >= 1 (an array)
    def origins(self, e, env) -> frozenset:
        if isinstance(e, ast.Name):
            return env.get(e.id, frozenset())
        if isinstance(e, ast.Subscript):
            base = self.origins(e.value, env)
            if not base:
                return base
            sl = e.slice
            parts = sl.elts if isinstance(sl, ast.Tuple) else [sl]
            if any(isinstance(x, ast.List) for x in parts):  # fancy indexing: a copy
                return frozenset()
            drop = sum(not isinstance(x, ast.Slice) and not (isinstance(x, ast.Constant) and x.value in (None, ...))
                       for x in parts)
            return frozenset((o, d - drop) for o, d in base if d - drop >= 1)
        if isinstance(e, ast.Attribute):
            return self.origins(e.value, env) if e.attr in _VIEW_ATTRS else frozenset()
        if isinstance(e, ast.Call):
            f = e.func
            if isinstance(f, ast.Attribute) and f.attr in _VIEW_METHODS:
                return self.origins(f.value, env)
            if e.args and id(self.resolve(f)) in _VIEW_FUNCS:
                return self.origins(e.args[0], env)
            return frozenset()
        if isinstance(e, ast.IfExp):
            return self.origins(e.body, env) | self.origins(e.orelse, env)
        if isinstance(e, ast.BoolOp):
            return frozenset().union(*(self.origins(v, env) for v in e.values))
        if isinstance(e, (ast.NamedExpr, ast.Starred)):
            return self.origins(e.value, env)
        if isinstance(e, (ast.Tuple, ast.List)):  # a container of arrays: one more indexing to reach them
            return frozenset((o, d + 1) for x in e.elts for o, d in self.origins(x, env))
        return frozenset()

    def resolve(self, e):
        """The object a callee expression names (a global, a closure variable, a builtin, an
        attribute of a module or of a numpy ufunc), or None."""
        if isinstance(e, ast.Name):
            for space in (self.closure, self.globals, vars(builtins)):
                if e.id in space:
                    return space[e.id]
            return None
        if isinstance(e, ast.Attribute):
            base = self.resolve(e.value)
            if isinstance(base, (types.ModuleType, np.ufunc, type)):
                try:
                    return getattr(base, e.attr)
                except Exception:  # noqa: BLE001 (an attribute that is not there)
                    return None
        return None

    def const(self, e):
        """An int index known before the function runs (a literal, a module constant, + - * of them)."""
        if isinstance(e, ast.Constant) and isinstance(e.value, int) and not isinstance(e.value, bool):
            return e.value
        if isinstance(e, ast.Name):
            v = self.closure.get(e.id, self.globals.get(e.id))
            return v if isinstance(v, (int, np.integer)) and not isinstance(v, bool) else None
        if isinstance(e, ast.UnaryOp) and isinstance(e.op, ast.USub):
            v = self.const(e.operand)
            return None if v is None else -v
        if isinstance(e, ast.BinOp) and isinstance(e.op, (ast.Add, ast.Sub, ast.Mult)):
            a, b = self.const(e.left), self.const(e.right)
            if a is None or b is None:
                return None
            return a + b if isinstance(e.op, ast.Add) else a - b if isinstance(e.op, ast.Sub) else a * b
        return None

    # -- findings
    def write(self, origins, index=None, via=()):
        stmt = self.stmt
        text = (ast.get_source_segment(self.src, stmt) or "").strip().splitlines()
        text = text[0] if text else ""
        text = text if len(text) <= 80 else text[:77] + "..."
        for o, d in origins:
            if d >= 1 and o not in self.found:
                self.found[o] = Finding(o, self.file, stmt.lineno + self.offset, text, index, via)

    def target(self, t, env):
        """A store into ``t`` that is not a plain name: a write into what its base refers to."""
        while isinstance(t, ast.Starred):
            t = t.value
        if isinstance(t, ast.Subscript):
            own = isinstance(t.value, ast.Name) and env.get(t.value.id) == self.own.get(t.value.id)
            index = self.const(t.slice) if own else None  # p[k] itself, not an alias or a view of p
            self.write(self.origins(t.value, env), index)
        elif isinstance(t, ast.Attribute):
            self.write(self.origins(t.value, env))

    def bind(self, t, origins, value, env):
        if isinstance(t, ast.Name):
            env[t.id] = origins
        elif isinstance(t, (ast.Tuple, ast.List)):
            if isinstance(value, (ast.Tuple, ast.List)) and len(value.elts) == len(t.elts) \
                    and not any(isinstance(x, ast.Starred) for x in t.elts + value.elts):
                for x, v in zip(t.elts, value.elts):
                    self.bind(x, self.origins(v, env), v, env)
            else:  # unpacking iterates the first axis
                inner = frozenset((o, d - 1) for o, d in origins if d - 1 >= 1)
                for x in t.elts:
                    self.bind(x.value if isinstance(x, ast.Starred) else x, inner, None, env)
        elif isinstance(t, ast.Starred):
            self.bind(t.value, origins, None, env)
        else:
            self.target(t, env)

    # -- calls: methods and functions that write their arguments, helpers
    def calls(self, node, env):
        if node is None:
            return
        for c in ast.walk(node):
            if isinstance(c, ast.NamedExpr):
                self.bind(c.target, self.origins(c.value, env), c.value, env)
            if not isinstance(c, ast.Call):
                continue
            f = c.func
            if isinstance(f, ast.Attribute) and f.attr in _WRITING_METHODS:
                self.write(self.origins(f.value, env))
                continue
            if isinstance(f, ast.Name) and f.id in self.local_defs:
                self.inline(self.local_defs[f.id], c, env)
                continue
            callee = self.resolve(f)
            if self.helper(callee, c, env):  # the user's own function: what it writes, by its source
                continue
            for kw in c.keywords:  # numpy's (or an unknown callee's) output argument
                if kw.arg == "out":
                    for v in (kw.value.elts if isinstance(kw.value, ast.Tuple) else [kw.value]):
                        self.write(self.origins(v, env))
            if isinstance(callee, np.ufunc):
                for a in c.args[callee.nin:]:
                    self.write(self.origins(a, env))
            elif isinstance(f, ast.Attribute) and f.attr == "at" and isinstance(self.resolve(f.value), np.ufunc):
                if c.args:
                    self.write(self.origins(c.args[0], env))
            elif callee is not None and id(callee) in _WRITING_FUNCS:
                first = c.args[0] if c.args else next((k.value for k in c.keywords
                                                       if k.arg == _WRITING_FUNCS[id(callee)]), None)
                if first is not None:
                    self.write(self.origins(first, env))

    def helper(self, callee, c, env) -> bool:
        """A call of a Python function (plain or numba's dispatcher) of the user's, or of any package
        but numpy, numba, scipy: the parameters it writes, mapped back to the arguments of this
        call. False for any other callee."""
        py = getattr(callee, "py_func", callee)
        if not isinstance(py, types.FunctionType) or (py.__module__ or "").split(".")[0] in _FOREIGN:
            return False
        code = py.__code__
        params = code.co_varnames[:code.co_argcount + code.co_kwonlyargcount]
        args = {}
        for i, a in enumerate(c.args):
            if isinstance(a, ast.Starred):
                break
            key = i if i < code.co_argcount else "*"
            args[key] = args.get(key, frozenset()) | self.origins(a, env)
        for kw in c.keywords:
            if kw.arg in params:
                pos = params.index(kw.arg)
                args[pos if pos < code.co_argcount else kw.arg] = self.origins(kw.value, env)
        if not any(args.values()):
            return True
        depths = tuple(max((d for _, d in args.get(i, ())), default=0) for i in range(code.co_argcount))
        depths += (max((d for _, d in args.get("*", ())), default=0),)
        for pos, f in param_writes(py, depths).items():
            if pos in args:
                hop = (getattr(py, "__qualname__", py.__name__), f.file, f.line, f.text)
                self.write(args[pos], via=(hop,) + f.via)
        return True

    def inline(self, node, c, env):
        """A call of a function nested in this one: its body walked with its parameters bound to
        what the arguments refer to (and the enclosing names it reads)."""
        if id(node) in self.inlining:
            return
        self.inlining.add(id(node))
        inner = dict(env)
        names = [x.arg for x in node.args.posonlyargs + node.args.args]
        for name in names:
            inner.pop(name, None)
        for name, a in zip(names, c.args):
            inner[name] = self.origins(a, env)
        for kw in c.keywords:
            if kw.arg in names:
                inner[kw.arg] = self.origins(kw.value, env)
        stmt = self.stmt
        self.block(node.body, inner)
        self.stmt = stmt
        self.inlining.discard(id(node))

    # -- statements
    def block(self, body, env) -> dict:
        for s in body:
            env = self.statement(s, env)
        return env

    @staticmethod
    def join(*envs) -> dict:
        out: dict = {}
        for e in envs:
            for k, v in e.items():
                out[k] = out.get(k, frozenset()) | v
        return out

    def loop(self, body, env, bind=None) -> dict:
        start = env
        for _ in range(2):  # twice: an alias made in one pass is seen by the next
            inner = dict(env)
            if bind is not None:
                bind(inner)
            env = self.join(start, self.block(body, inner))
        return env

    def statement(self, s, env) -> dict:
        self.stmt = s
        env = dict(env)
        if isinstance(s, ast.Assign):
            self.calls(s.value, env)
            origins = self.origins(s.value, env)
            for t in s.targets:
                self.stmt = s
                self.bind(t, origins, s.value, env)
        elif isinstance(s, ast.AnnAssign):
            if s.value is not None:
                self.calls(s.value, env)
                self.bind(s.target, self.origins(s.value, env), s.value, env)
        elif isinstance(s, ast.AugAssign):
            self.calls(s.value, env)
            self.stmt = s
            if isinstance(s.target, ast.Name):  # in place on an array
                self.write(env.get(s.target.id, frozenset()))
            else:
                self.target(s.target, env)
        elif isinstance(s, (ast.For, ast.AsyncFor)):
            self.calls(s.iter, env)
            items = frozenset((o, d - 1) for o, d in self.origins(s.iter, env) if d - 1 >= 1)
            env = self.loop(s.body, env, lambda e: self.bind(s.target, items, None, e))
            env = self.block(s.orelse, env)
        elif isinstance(s, ast.While):
            self.calls(s.test, env)
            env = self.loop(s.body, env)
            env = self.block(s.orelse, env)
        elif isinstance(s, ast.If):
            self.calls(s.test, env)
            env = self.join(self.block(s.body, dict(env)), self.block(s.orelse, dict(env)))
        elif isinstance(s, (ast.With, ast.AsyncWith)):
            for item in s.items:
                self.calls(item.context_expr, env)
                if item.optional_vars is not None:
                    self.bind(item.optional_vars, self.origins(item.context_expr, env), item.context_expr, env)
            env = self.block(s.body, env)
        elif isinstance(s, ast.Try) or type(s).__name__ == "TryStar":
            after = self.block(s.body, dict(env))
            handlers = [self.block(h.body, self.join(env, after)) for h in s.handlers]
            env = self.join(self.block(s.orelse, after), *handlers)
            env = self.block(s.finalbody, env)
        elif isinstance(s, (ast.FunctionDef, ast.AsyncFunctionDef)):
            self.local_defs[s.name] = s
            env.pop(s.name, None)
            inner = dict(env)  # what it writes through the names it closes over
            for x in s.args.posonlyargs + s.args.args + s.args.kwonlyargs:
                inner.pop(x.arg, None)
            self.block(s.body, inner)
        else:
            for child in ast.iter_child_nodes(s):
                if isinstance(child, ast.expr):
                    self.stmt = s
                    self.calls(child, env)
        return env


# ============================================================================= the checks
def ode_calls(model, p: np.ndarray, y0: np.ndarray) -> list[Call]:
    """Every function an OdeModel declares, with arguments for one call at the probe point
    (``p``: the probe row after classify and prepare; ``y0``: the initial state there)."""
    n = len(model.states)
    npa, nse, nin = len(model.params), len(getattr(model, "settings", ())), len(getattr(model, "internal", ()))
    slots = (npa + nse, npa + nse + nin)
    state = lambda: y0.copy()  # noqa: E731
    args = {
        "rhs": lambda: (0.0, state(), p.copy(), np.zeros(n)),
        "jac": lambda: (0.0, state(), p.copy(), np.zeros((n, n))),
        "accel": lambda: (0.0, state()[:n // 2].copy(), p.copy(), np.zeros(n // 2)),
        "initial": lambda: (p.copy(), np.zeros(n)),
        "prepare": lambda: (p.copy(), 1e-10),
        "symplectic_step": lambda: (p.copy(), 1e-10),
        "event": lambda: (0.0, state(), p.copy()),
        "of": lambda: (0.0, state(), p.copy()),
        "error": lambda: (0.0, state(), p.copy()),
        "response": lambda: (0.0, state(), p.copy()),
        "value": lambda: (p.copy(), 1.0),
        "refine": lambda: (p.copy(), 1e-10, 1.0),
        "variational": lambda: (0.0, np.eye(n).ravel(), p.copy(), np.zeros(n * n)),
        "variational_jac": lambda: (0.0, np.eye(n).ravel(), p.copy(), np.zeros((n * n, n * n))),
        "invariant": lambda: (state(), p.copy()),
    }
    one_p = lambda: (p.copy(),)  # noqa: E731
    out = []

    def add(what, role, func):
        if callable(func):
            out.append(Call(what, role, func, args.get(role, one_p)(), slots if role == "prepare" else None))

    for role in ("rhs", "initial", "jac", "accel", "symplectic_step", "classify", "prepare", "forcing_period",
                 "switch_times"):
        add(role, role, getattr(model, role, None))
    for m in model.measurements:
        kind = type(m).__name__
        for role, func in getattr(m, "functions", lambda: ())():
            if kind == "FirstEvent" and role in _SYSTEM:
                add(f"the System's {role} of FirstEvent {m.name!r}", role, func)
            else:
                add(f"{_NAMES.get(role, role)} of {kind} {m.name!r}", role, func)
        add(f"classify of {kind} {m.name!r}", "classify", getattr(m, "classify", None))
    for c in getattr(model, "closed_forms", ()):
        if callable(c.func):
            out.append(Call(f"closed form {c.name!r}", "closed", c.func, (p.copy(),) + (1.0,) * len(c.needs)))
        add(f"classify of closed form {c.name!r}", "classify", getattr(c, "classify", None))
    inv = getattr(model, "invariant", None)
    if inv is not None:
        add(f"invariant {inv.name!r}", "invariant", inv.func)
        add(f"period of invariant {inv.name!r}", "period", inv.period)
    return out


def closed_calls(model, args: tuple, data: tuple) -> list[Call]:
    """A ClosedFormModel's ``compute`` with its probe arguments (p, want, row, curves, slot,
    scratch) and the shared data."""
    return [Call("compute", "compute", model.compute, tuple(a.copy() for a in args) + tuple(a.copy() for a in data))]


def check(calls, label: str, dynamic: bool = True) -> None:
    """InputError for the first function of ``calls`` that may write an argument its role may
    not: by its source first (file and line), then by a call at the probe point."""
    for call in calls:
        _check_static(call, label)
    if dynamic:
        for call in calls:
            _check_dynamic(call, label)


def _depth(a) -> int:
    return a.ndim if isinstance(a, np.ndarray) else 0


def _argument(call: Call, pos) -> str:
    """'its state argument y' for a parameter position (``"*"``: the ``*args``)."""
    role = ROLES[call.role]
    code = getattr(getattr(call.func, "py_func", call.func), "__code__", None)
    names = list(code.co_varnames[:code.co_argcount]) if code is not None else []
    star = code.co_varnames[code.co_argcount + code.co_kwonlyargcount] \
        if code is not None and code.co_flags & inspect.CO_VARARGS else "args"
    if pos == "*" or pos >= len(role.args):
        name = names[pos] if pos != "*" and pos < len(names) else f"*{star}"
        return f"its {role.rest or 'extra'} argument {name}"
    return f"its {role.args[pos]} argument {names[pos] if pos < len(names) else pos}"


def _rule(call: Call) -> str:
    rule = ROLES[call.role].rule
    if call.role == "prepare" and call.slots is not None:
        lo, hi = call.slots
        rule += f" (p[{lo}:{hi}]: {'none declared' if lo == hi else 'declared by internal='})"
    return rule


def _allowed(call: Call, pos) -> bool:
    """Whether the role writes the argument at ``pos`` (prepare: see its slots)."""
    return isinstance(pos, int) and pos in ROLES[call.role].writes


def _check_static(call: Call, label: str) -> None:
    depths = tuple(_depth(a) for a in call.args)
    py = getattr(call.func, "py_func", call.func)
    code = getattr(py, "__code__", None)
    if code is None:
        return
    n = code.co_argcount
    star = max([_depth(a) for a in call.args[n:]] or [0])
    found = param_writes(call.func, depths[:n] + (0,) * (n - len(depths[:n])) + (star,))
    for pos in sorted(found, key=str):
        f = found[pos]
        if _allowed(call, pos):
            continue
        if call.role == "prepare" and pos == 0:
            lo, hi = call.slots
            if f.index is None or lo <= f.index < hi:  # a slot known only when it runs: the dynamic net
                continue
        where = f"{f.file}:{f.line}"
        via = "".join(f"; through {name}, which writes it at {file}:{line} ({text})"
                      for name, file, line, text in f.via)
        raise InputError(f"{label}: {call.what} writes into {_argument(call, pos)} at {where} ({f.text}){via}; "
                         f"{_rule(call)}")


def _check_dynamic(call: Call, label: str) -> None:
    own = getattr(call.func, "py_func", call.func)
    func = with_engine_helpers(own)
    args = call.args
    before = [a.copy() if isinstance(a, np.ndarray) else None for a in args]
    try:
        with np.errstate(all="ignore"):
            func(*args)
    except Exception:  # noqa: BLE001 (the probe reports what raises; this only looks for writes)
        return
    for pos, (a, old) in enumerate(zip(args, before)):
        if old is None:
            continue
        changed = [k for k in range(a.size) if a.flat[k].tobytes() != old.flat[k].tobytes()]
        if call.role == "prepare" and pos == 0:
            lo, hi = call.slots
            changed = [k for k in changed if not lo <= k < hi]
        elif _allowed(call, pos):
            continue
        if changed:
            shown = ", ".join(str(k) for k in changed[:5]) + (", ..." if len(changed) > 5 else "")
            raise InputError(f"{label}: {call.what} wrote into {_argument(call, pos)} (component(s) {shown}) "
                             f"when run at the probe point{_defined_at(own)}; {_rule(call)}")


def _defined_at(func) -> str:
    code = getattr(func, "__code__", None)
    return f" (def {func.__name__} at {code.co_filename}:{code.co_firstlineno})" if code is not None else ""
