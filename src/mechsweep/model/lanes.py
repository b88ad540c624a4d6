"""SIMD lanes for the layer's first-event kernels: LANES points integrated side by side per thread;
and the lane form of a model's rhs, which the sampled-trajectory lanes (trajectory.py) use too.

Where it applies (``applies``): one measurement that integrates on its own (a FirstEvent, or a lone
first Crossing) without a System or refine, method dop853, and a model ``rhs`` the engine can
rewrite in lane form (``lane_rhs_source``). Everywhere else (radau, auto, symplectic, several
measurements, the shared trajectory, Floquet) compile.py keeps its one-point-at-a-time route.

**The lane right-hand side is built by the engine from the model's scalar rhs**: its source is
parsed and rewritten so that ``y[i]``, ``p[k]``, ``dydt[i]`` and ``t`` become ``Z[i, l]``,
``P[k, l]``, ``dZ[i, l]`` and ``tau[l]`` inside one loop over the lanes ``l`` (state laid out
[state, lane], lanes innermost), which LLVM vectorises (no call but math functions, so nothing
stops it). Module constants the rhs reads (e.g. duffing's slot numbers) are written in as their
values. A plain module-level function called as a whole statement is inlined first (_Flatten:
arguments bound in order, array arguments and slices of them mapped onto y, p, dydt with their
offsets), special.sincos becomes sincos_reduced plus a second pass with sincos where any lane is
beyond its range, and with many dydt rows the rows copied from the inputs get a loop of their own
(LLVM's aliasing checks). An rhs the rewrite does not cover (a call inside an expression, a
``raise``, ``y`` or ``p`` used other than by a scalar index, a write into y or p, a ``while``, an
early ``return``) is not laned: the model keeps the one-at-a-time route (no error, same results). The rewrite is the same
per-lane arithmetic in the same order as the scalar rhs (numba's fastmath is off, so LLVM neither
reassociates nor fuses multiply-adds), so each lane computes the scalar rhs's floats.

**The solver** is ode/dop853_lanes.py's step (stages by the generated tableau sums, per-lane
error test and step-size control) with dop853.make_event_solver's event logic per lane: after
every accepted step the event is evaluated on the lane's new state (the scalar event function, on
a copy of the lane's column), and at a sign change the lane's stages are copied into a one-point
workspace where dop853's own dense output (3 scalar rhs calls) and Brent's root search on its
interpolant run unchanged. The first step is chosen by dop853's own ``start``. Every lane
therefore computes the one-at-a-time route's floats step for step: value, status, n_steps and
n_rhs are bitwise those of the one-point kernel (tests/test_model_lanes.py). A lane whose point is
done is refilled at once from its thread's batch of points, which the thread takes (GRAB at a time)
from one counter shared by the launch's threads (``take``); per-point work before and after the integration (classify, prepare, closed forms, the
value) runs in scalar code around the lanes as in compile.py's kernel.
"""
from __future__ import annotations

import ast
import builtins
import copy
import functools
import inspect
import math
import re
import sys
import textwrap
import types

import numpy as np
from numba.core import cgutils, types as nbtypes
from numba.extending import intrinsic

from .._jit import jit, jit_noalloc
from ..status import MAX_STEPS, NO_EVENT, NONFINITE, OK, STEP_UNDERFLOW
from ..ode import _dop853_lane_sums as sums
from ..ode._dop853_tableau import C, N_STAGES, N_STAGES_EXTENDED
from ..ode.dop853 import (F_DENSE, K_FSAL, WORK_ROWS, Y_NEW, Y_STAGE, _make_dense_output, _make_root_locator,
                          _make_start)
from ..ode.dop853 import _failure, _tests_stiffness
from ..ode.dop853_lanes import _begin_advance, _error_sums, _error_test, _finish, _spread, _stiffness_lane

LANES = 0  # points side by side per thread; 0: lanes_for(number of states)
QUEUE = 32  # the lane kernel has a worker (its own lanes) per LANES * QUEUE points of a launch
GRAB = 16  # points a thread of the lane kernel takes at a time from its launch's shared counter


def lanes_for(n_states: int) -> int:
    """Points side by side per thread: about 256 floats per stage row (a multiple of 8 lanes,
    8 to 64), so that the loops over (state, lane) run long vector bodies."""
    if LANES:
        return LANES
    return max(8, min(64, (256 // max(1, n_states)) // 8 * 8))

# Positions in the workspace tuple.
W, Y, PL, LF, LI, SW, WF, YF, HK, PR, YV = range(11)
# Rows of LF (per-lane floats); T .. SUM3 are dop853_lanes' rows (its helpers index them).
T, T_NEW, H, H_ABS, MIN_STEP, TAU, SUM5, SUM3, T_MAX, G_OLD, RESULT = range(11)
N_LF = 11
# Rows of LI (per-lane integers), as dop853_lanes' where its helpers read them.
STATE, POINT, STATUS, N_STEPS, N_RHS, N_ATTEMPTS, K_NEXT, REJECTED, LAST_NONFINITE, ACCEPTED = range(10)
N_STIFF, N_NONSTIFF = 10, 11  # the counters of dop853's stiffness test (run late in the step budget only)
N_LI = 12
IDLE, ACTIVE, DONE = 0, 1, 2


# --------------------------------------------------------------------------- the lane rhs
class _NotLaneable(Exception):
    pass


_BUILTINS = {"abs", "min", "max", "float", "int", "range"}
_RESERVED = ("_lt", "_lz", "_lp", "_ld", "_ll", "_lb")


class _Rewrite(ast.NodeTransformer):
    """y[i] -> _lz[i, _ll], p[k] -> _lp[k, _ll], dydt[i] -> _ld[i, _ll], t -> _lt[_ll]; module
    constants -> their values; anything else that is not plain arithmetic on scalars refuses."""

    def __init__(self, args, glob, local_names):
        self.t, self.y, self.p, self.d = args
        self.arrays = {self.y: "_lz", self.p: "_lp", self.d: "_ld"}
        self.glob = glob
        self.local = local_names

    def generic_visit(self, node):
        allowed = (ast.Assign, ast.AugAssign, ast.If, ast.For, ast.Pass, ast.Expr, ast.BinOp, ast.UnaryOp,
                   ast.BoolOp, ast.Compare, ast.IfExp, ast.Call, ast.Attribute, ast.Subscript, ast.Name,
                   ast.Constant, ast.Load, ast.Store, ast.operator, ast.unaryop, ast.boolop, ast.cmpop,
                   ast.expr_context, ast.Tuple)
        if not isinstance(node, allowed):
            raise _NotLaneable(type(node).__name__)
        return super().generic_visit(node)

    def visit_Expr(self, node):
        if isinstance(node.value, ast.Constant):  # a docstring
            return None
        raise _NotLaneable("expression statement")

    def visit_For(self, node):
        if node.orelse or not isinstance(node.target, ast.Name):
            raise _NotLaneable("for")
        it = node.iter
        if not (isinstance(it, ast.Call) and isinstance(it.func, ast.Name) and it.func.id == "range"):
            raise _NotLaneable("for over something else than range")
        return self.generic_visit(node)

    def visit_Tuple(self, node):
        if isinstance(node.ctx, ast.Store) and not all(isinstance(e, ast.Name) for e in node.elts):
            raise _NotLaneable("tuple assignment")
        return self.generic_visit(node)

    def visit_Subscript(self, node):
        if not (isinstance(node.value, ast.Name) and node.value.id in self.arrays):
            raise _NotLaneable("subscript of another array")
        name = node.value.id
        if isinstance(node.ctx, ast.Store) and name != self.d:
            raise _NotLaneable(f"write into {name}")
        if isinstance(node.ctx, ast.Load) and name == self.d:
            raise _NotLaneable("dydt read")
        index = node.slice
        if isinstance(index, (ast.Slice, ast.Tuple)):
            raise _NotLaneable("slice")
        index = self.visit(index)
        return ast.copy_location(ast.Subscript(value=ast.Name(self.arrays[name], ast.Load()),
                                               slice=ast.Tuple([index, ast.Name("_ll", ast.Load())], ast.Load()),
                                               ctx=node.ctx), node)

    def visit_Attribute(self, node):
        if isinstance(node.value, ast.Name) and self.glob.get(node.value.id, None) is math \
                and node.value.id not in self.local:
            value = getattr(math, node.attr, None)
            if isinstance(value, float):
                return ast.copy_location(ast.Constant(value), node)
            if isinstance(value, types.BuiltinFunctionType):
                return ast.copy_location(ast.Attribute(ast.Name("math", ast.Load()), node.attr, ast.Load()), node)
        raise _NotLaneable("attribute")

    def visit_Call(self, node):
        if node.keywords:
            raise _NotLaneable("keyword arguments")
        f = node.func
        if isinstance(f, ast.Name) and f.id not in self.local and self.glob.get(f.id, None) is not None \
                and self.glob[f.id] is getattr(math, f.id, None):  # from math import sin
            f = node.func = ast.Attribute(ast.Name("math", ast.Load()), f.id, ast.Load())
            node.args = [self.visit(a) for a in node.args]
            return node
        if isinstance(f, ast.Name) and f.id not in self.local and _intrinsic(self.glob.get(f.id)) not in (None, "_lsincos"):
            f = node.func = ast.Name(_intrinsic(self.glob[f.id]), ast.Load())  # special.ieee_sqrt, sincos_reduced
        if isinstance(f, ast.Name) and f.id in _BUILTINS and f.id not in self.local and f.id not in self.glob:
            pass
        elif isinstance(f, ast.Name) and f.id in _INTRINSIC_NAMES.values() and f.id not in self.local:
            pass  # an engine helper the inliner named (special.ieee_sqrt, sincos, sincos_reduced)
        elif not (isinstance(f, ast.Attribute) and isinstance(f.value, ast.Name)):
            raise _NotLaneable("call")
        node.func = self.visit(f) if not isinstance(f, ast.Name) else f
        node.args = [self.visit(a) for a in node.args]
        return node

    def visit_Name(self, node):
        name = node.id
        if name in _RESERVED:
            raise _NotLaneable("reserved name")
        if name == self.t:
            if isinstance(node.ctx, ast.Store):
                raise _NotLaneable("t assigned")
            return ast.copy_location(ast.Subscript(ast.Name("_lt", ast.Load()), ast.Name("_ll", ast.Load()),
                                                   ast.Load()), node)
        if name in self.arrays:
            raise _NotLaneable(f"{name} used as a whole")
        if name in self.local or isinstance(node.ctx, ast.Store):
            return node
        if name in self.glob:
            value = self.glob[name]
            if isinstance(value, (bool, int, float)) and not isinstance(value, np.generic):
                if value < 0:  # unparsed as -(x), so that e.g. C ** 2 keeps its meaning
                    return ast.copy_location(ast.UnaryOp(ast.USub(), ast.Constant(-value)), node)
                return ast.copy_location(ast.Constant(value), node)
            raise _NotLaneable(f"global {name}")
        if name in _BUILTINS and hasattr(builtins, name):
            return node
        if name in _INTRINSIC_NAMES.values():
            return node
        raise _NotLaneable(f"name {name}")


# --------------------------------------------------------------------------- helper calls inlined
# Engine helpers a lane rhs may call (kept as calls: numba inlines them; they vectorise): the name
# the generated source gives them. special.sincos has a libm branch (|x| > SINCOS_MAX, inf, NaN)
# that would keep the lane loop scalar: the rewrite calls sincos_reduced in the lane loop, counts
# the lanes beyond the range, and where there are any runs the loop again with sincos itself.
_INTRINSIC_NAMES = {"ieee_sqrt": "_lsqrt", "sincos": "_lsincos", "sincos_reduced": "_lsincos_red"}
_INLINE_DECORATORS = ("njit", "jit", "jit_inline", "jit_noalloc")  # dropped: the callee's body is inlined
SPLIT_ROWS = 4  # an rhs writing more dydt rows than this: rows copied from the inputs in a loop of their own
MAX_INLINED = 256  # calls inlined into one lane rhs at most, MAX_DEPTH deep (a recursive helper: not laned)
MAX_DEPTH = 16


def _intrinsic(obj):
    from .. import special
    for name in _INTRINSIC_NAMES:
        if obj is getattr(special, name):
            return _INTRINSIC_NAMES[name]
    return None


def _function_def(func):
    """(FunctionDef, globals) of a plain module-level function (or numba dispatcher), else refuse."""
    func = getattr(func, "py_func", func)
    if not isinstance(func, types.FunctionType) or func.__closure__:
        raise _NotLaneable("not a plain function")
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError, IndentationError):
        raise _NotLaneable("no source") from None
    fdef = tree.body[0] if tree.body else None
    if not isinstance(fdef, ast.FunctionDef) or not _numba_decorated(fdef, _INLINE_DECORATORS):
        raise _NotLaneable("decorated")
    a = fdef.args
    if a.posonlyargs or a.vararg or a.kwonlyargs or a.kwarg or a.defaults:
        raise _NotLaneable("arguments")
    return fdef, func.__globals__


def _const_int(node) -> int:
    try:
        value = ast.literal_eval(node)
    except (ValueError, TypeError, SyntaxError):
        raise _NotLaneable("slice bound") from None
    if not isinstance(value, int) or isinstance(value, bool) or value < 0:
        raise _NotLaneable("slice bound")
    return value


class _Flatten:
    """Inlines, statement by statement, the calls of the top rhs to plain module-level functions
    (``scaled_rhs(t, y, p[OFF:OFF + NP], dydt)``, ``a, b = helper(x, p)``, down the call chain) so
    that the body _Rewrite sees reads y, p, t and writes dydt only. A callee's scalar arguments are
    bound to fresh locals in order (as the call evaluates them), its array arguments (y, p, dydt,
    or a slice of them from a constant offset) to the top arrays with the offset added to its
    indices, its locals renamed (_lkN_name), its module constants written in as values; its one
    return, at the end, is assigned to the call's targets. The same floats in the same order as
    the calls, which numba compiles as they are."""

    def __init__(self, args, glob):
        self.args = args
        self.glob = glob
        self.count = 0
        self.stack = []  # the calls being inlined
        self.sincos = []  # the arguments (local names) of the sincos calls

    # ---- the top function's statements: untouched unless they call a function
    def top(self, body):
        return self._stmts(body, None)

    def _stmts(self, body, scope):
        out = []
        for node in body:
            out += self._stmt(node, scope)
        return out

    def _stmt(self, node, scope):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Call):
            target = self._callee(node.value.func, scope)
            if target is not None:
                return self._inline(target, node.value, None, scope)
        if isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.value, ast.Call):
            target = self._callee(node.value.func, scope)
            if target is not None:
                return self._inline(target, node.value, self._target(node.targets[0], scope), scope)
        if isinstance(node, (ast.If, ast.For)):
            node = node if scope is None else scope.visit_header(node)
            new = type(node)(**{f: getattr(node, f) for f in node._fields})
            new.body = self._stmts(node.body, scope)
            new.orelse = self._stmts(node.orelse, scope)
            return [ast.copy_location(new, node)]
        if scope is None:
            return [node]
        if isinstance(node, ast.Return):
            raise _NotLaneable("return before the end")
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant):
            return []
        return [scope.visit(node)]

    def _target(self, t, scope):
        if scope is None:
            return t
        return scope.visit(t)

    def _callee(self, f, scope):
        """The function object a call statement calls, when it is one to inline (or sincos)."""
        glob = self.glob if scope is None else scope.glob
        local = set() if scope is None else scope.local
        if not isinstance(f, ast.Name) or f.id in local or f.id in self.args:
            return None
        obj = glob.get(f.id)
        if obj is None or obj is getattr(math, f.id, None):
            return None
        if _intrinsic(obj) == "_lsincos":
            return "sincos"
        if _intrinsic(obj) is not None:
            return None
        if isinstance(getattr(obj, "py_func", obj), types.FunctionType):
            return obj
        return None

    def _array(self, node, scope):
        """(top array name, offset) when the argument is an array (y, p, dydt or a slice), else None."""
        base, lower = node, 0
        if isinstance(node, ast.Subscript) and isinstance(node.slice, ast.Slice):
            sl = node.slice
            if sl.step is not None:
                raise _NotLaneable("slice step")
            base = node.value
            if sl.lower is not None:
                lower = _const_int(self._const_expr(sl.lower, scope))
        if not isinstance(base, ast.Name):
            return None
        if scope is None:
            if base.id in self.args[1:]:
                return base.id, lower
            if base is not node:
                raise _NotLaneable("slice of another array")
            return None
        bound = scope.binds.get(base.id)
        if isinstance(bound, tuple):
            return bound[0], bound[1] + lower
        if base is not node:
            raise _NotLaneable("slice of another array")
        return None

    def _const_expr(self, node, scope):
        glob = self.glob if scope is None else scope.glob
        return _Callee(glob, {}, set(), "").visit(_copy(node))

    def _inline(self, target, call, targets, scope):
        if call.keywords:
            raise _NotLaneable("keyword arguments")
        self.count += 1
        if self.count > MAX_INLINED or len(self.stack) >= MAX_DEPTH:  # e.g. a recursive helper
            raise _NotLaneable("too many calls")
        prefix = f"_lk{self.count}_"
        if target == "sincos":  # a, b = sincos(x): x into a local, the call kept (see _finish)
            if len(call.args) != 1 or targets is None:
                raise _NotLaneable("sincos")
            x = prefix + "x"
            arg = call.args[0] if scope is None else scope.visit(_copy(call.args[0]))
            self.sincos.append(x)
            return [ast.Assign([ast.Name(x, ast.Store())], arg),
                    ast.Assign([targets], ast.Call(ast.Name("_lsincos", ast.Load()), [ast.Name(x, ast.Load())], []))]
        fdef, glob = _function_def(target)
        params = [x.arg for x in fdef.args.args]
        if len(params) != len(call.args):
            raise _NotLaneable("argument count")
        out, binds = [], {}
        for param, arg in zip(params, call.args):
            arr = self._array(arg, scope)
            if arr is not None:
                binds[param] = arr
                continue
            name = prefix + param
            out.append(ast.Assign([ast.Name(name, ast.Store())], arg if scope is None else scope.visit(_copy(arg))))
            binds[param] = name
        body = list(fdef.body)
        ret = None
        if body and isinstance(body[-1], ast.Return):
            ret = body.pop().value
        local = {n.id for n in ast.walk(ast.Module(body=body, type_ignores=[]))
                 if isinstance(n, ast.Name) and isinstance(n.ctx, ast.Store)}
        if local & set(params):
            raise _NotLaneable("argument assigned")
        inner = _Callee(glob, binds, local, prefix)
        self.stack.append(prefix)
        out += self._stmts(body, inner)
        self.stack.pop()
        if targets is None:
            if ret is not None:
                raise _NotLaneable("a value dropped")
            return out
        if ret is None:
            raise _NotLaneable("no value returned")
        if isinstance(ret, ast.Call) and self._callee(ret.func, inner) is not None:  # return helper(...)
            self.stack.append(prefix)  # as deep as a call from the body
            out += self._inline(self._callee(ret.func, inner), ret, targets, inner)
            self.stack.pop()
            return out
        value = inner.visit(_copy(ret))
        if isinstance(targets, ast.Tuple) and isinstance(value, ast.Tuple) and len(targets.elts) == len(value.elts):
            return out + [ast.Assign([t], v) for t, v in zip(targets.elts, value.elts)]  # fresh names: no overlap
        return out + [ast.Assign([targets], value)]


def _copy(node):
    return ast.parse(ast.unparse(node), mode="eval").body if isinstance(node, ast.expr) else node


class _Callee(ast.NodeTransformer):
    """An inlined function's expressions in the top function's terms (see _Flatten)."""

    def __init__(self, glob, binds, local, prefix):
        self.glob, self.binds, self.local, self.prefix = glob, binds, local, prefix

    def visit_header(self, node):
        if isinstance(node, ast.If):
            return ast.copy_location(ast.If(self.visit(_copy(node.test)), node.body, node.orelse), node)
        return ast.copy_location(ast.For(self.visit(_copy(node.target)), self.visit(_copy(node.iter)), node.body,
                                         node.orelse), node)

    def visit_Name(self, node):
        name = node.id
        if name in self.binds:
            bound = self.binds[name]
            if isinstance(bound, tuple):
                raise _NotLaneable(f"{name} used as a whole")
            return ast.copy_location(ast.Name(bound, node.ctx), node)
        if name in self.local:
            return ast.copy_location(ast.Name(self.prefix + name, node.ctx), node)
        if isinstance(node.ctx, ast.Store):
            raise _NotLaneable("store")
        if name in self.glob:
            value = self.glob[name]
            if value is math:
                return node
            if isinstance(value, (bool, int, float)) and not isinstance(value, np.generic):
                if value < 0:
                    return ast.copy_location(ast.UnaryOp(ast.USub(), ast.Constant(-value)), node)
                return ast.copy_location(ast.Constant(value), node)
            alias = _intrinsic(value)
            if alias is not None and alias != "_lsincos":
                return ast.copy_location(ast.Name(alias, ast.Load()), node)
            if value is getattr(math, name, None):  # from math import sin
                return ast.copy_location(ast.Attribute(ast.Name("math", ast.Load()), name, ast.Load()), node)
            raise _NotLaneable(f"global {name}")
        if name in _BUILTINS and hasattr(builtins, name):
            return node
        raise _NotLaneable(f"name {name}")

    def visit_Subscript(self, node):
        if isinstance(node.value, ast.Name) and isinstance(self.binds.get(node.value.id), tuple):
            if isinstance(node.slice, (ast.Slice, ast.Tuple)):
                raise _NotLaneable("slice")
            array, offset = self.binds[node.value.id]
            index = self.visit(node.slice)
            if offset:
                if isinstance(index, ast.Constant) and isinstance(index.value, int):
                    index = ast.Constant(index.value + offset)
                else:
                    index = ast.BinOp(ast.Constant(offset), ast.Add(), index)
            return ast.copy_location(ast.Subscript(ast.Name(array, ast.Load()), index, node.ctx), node)
        return self.generic_visit(node)

    def visit_Attribute(self, node):
        if isinstance(node.value, ast.Name) and self.glob.get(node.value.id) is math and node.value.id not in self.local:
            return ast.copy_location(ast.Attribute(ast.Name("math", ast.Load()), node.attr, node.ctx), node)
        raise _NotLaneable("attribute")


@functools.lru_cache(maxsize=256)
def lane_rhs_source(func, name: str = "rhs_lanes") -> str | None:
    """Source of ``name(tau, Z, P, dZ)``: the lane form of the scalar ``func(t, y, p, dydt)``, or
    None when the rewrite does not cover it (then the model is integrated one point at a time)."""
    func = getattr(func, "py_func", func)
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError, IndentationError):
        return None
    fdef = tree.body[0] if tree.body else None
    if not isinstance(fdef, ast.FunctionDef) or fdef.decorator_list and not _numba_decorated(fdef):
        return None
    a = fdef.args
    if a.posonlyargs or a.vararg or a.kwonlyargs or a.kwarg or a.defaults or len(a.args) != 4:
        return None
    args = [x.arg for x in a.args]
    body = list(fdef.body)
    if body and isinstance(body[-1], ast.Return) and body[-1].value is None:
        body = body[:-1]  # a bare return at the end changes nothing
    glob = dict(getattr(func, "__globals__", {}))
    if func.__closure__:
        return None
    if any(isinstance(n, ast.Name) and (n.id.startswith("_lk") or n.id in _INTRINSIC_NAMES.values())
           for n in ast.walk(fdef)):
        return None  # the names the inliner gives
    try:
        flat = _Flatten(args, glob)
        body = flat.top(body)
    except _NotLaneable:
        return None
    local = set()
    for node in ast.walk(ast.Module(body=body, type_ignores=[])):
        if isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            local.add(node.id)
    if local & set(args):
        return None
    main, moved = _split(body, args)
    try:
        rw = _Rewrite(args, glob, local)
        new_body = [s for s in (rw.visit(stmt) for stmt in main) if s is not None]
        new_moved = [s for s in (rw.visit(stmt) for stmt in moved) if s is not None]
    except _NotLaneable:
        return None
    if not new_body and not new_moved:
        return None

    def loop(stmts):
        return ast.For(target=ast.Name("_ll", ast.Store()),
                       iter=ast.Call(ast.Name("range", ast.Load()),
                                     [ast.Attribute(ast.Name("_lt", ast.Load()), "size", ast.Load())], []),
                       body=stmts, orelse=[])

    if flat.sincos:  # the fast loop with sincos_reduced, counting the lanes beyond its range; any: sincos
        from ..special import SINCOS_MAX
        fast = _SincosFast(set(flat.sincos), SINCOS_MAX).visit(ast.Module(body=copy.deepcopy(new_body),
                                                                          type_ignores=[])).body
        top = [ast.Assign([ast.Name("_lb", ast.Store())], ast.Constant(0)), loop(fast),
               ast.If(ast.Name("_lb", ast.Load()), [loop(new_body)], [])]
    else:
        top = [loop(new_body)] if new_body else []
    if new_moved:
        top.append(loop(new_moved))
    new = ast.FunctionDef(name=name, args=ast.arguments(posonlyargs=[], args=[ast.arg(x) for x in _RESERVED[:4]],
                                                        kwonlyargs=[], kw_defaults=[], defaults=[]),
                          body=top, decorator_list=[], returns=None,
                          **({"type_params": []} if sys.version_info >= (3, 12) else {}))
    mod = ast.fix_missing_locations(ast.Module(body=[new], type_ignores=[]))
    text = ast.unparse(mod)
    used = [f"{k} as {v}" for k, v in _INTRINSIC_NAMES.items() if re.search(rf"\b{v}\b", text)]
    imports = f"from mechsweep.special import {', '.join(used)}\n" if used else ""
    return (f"# the lane form of {func.__module__}.{func.__qualname__}, written by mechsweep.model.lanes\n"
            f"{imports}@jit_noalloc\n{text}\n")


def _split(body, args):
    """(main, moved): with more than SPLIT_ROWS dydt rows written, the statements ``dydt[c] = ...``
    of the inputs only (y, p, t, constants; written once) go into a second lane loop: LLVM adds
    run-time aliasing checks per pair of rows read and written and leaves a loop with too many
    scalar (the order of the writes of different rows changes no float)."""
    t, y, p, d = args
    rows = []
    for node in ast.walk(ast.Module(body=body, type_ignores=[])):
        if isinstance(node, ast.Subscript) and isinstance(node.ctx, ast.Store) and \
                isinstance(node.value, ast.Name) and node.value.id == d:
            if not (isinstance(node.slice, ast.Constant) and isinstance(node.slice.value, int)):
                return body, []
            rows.append(node.slice.value)
    if len(set(rows)) <= SPLIT_ROWS:
        return body, []
    inputs = {t, y, p, "math"} | _BUILTINS
    main, moved = [], []
    for node in body:
        if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Subscript)
                and isinstance(node.targets[0].value, ast.Name) and node.targets[0].value.id == d
                and rows.count(node.targets[0].slice.value) == 1
                and all(n.id in inputs for n in ast.walk(node.value) if isinstance(n, ast.Name))
                and not any(isinstance(n, ast.Call) for n in ast.walk(node.value))):
            moved.append(node)
        else:
            main.append(node)
    return main, moved


class _SincosFast(ast.NodeTransformer):
    """The fast lane loop: sincos -> sincos_reduced, and after each sincos argument's assignment
    ``_lb += 1 if abs(x) > SINCOS_MAX else 0`` (NaN counts as inside: sincos_reduced gives NaN for
    it, as libm, and idle lanes may hold NaN)."""

    def __init__(self, names, limit):
        self.names, self.limit = names, limit

    def visit_Name(self, node):
        if node.id == "_lsincos":
            return ast.copy_location(ast.Name("_lsincos_red", node.ctx), node)
        return node

    def generic_visit(self, node):
        node = super().generic_visit(node)
        for field in ("body", "orelse"):
            stmts = getattr(node, field, None)
            if isinstance(stmts, list) and stmts and isinstance(stmts[0], ast.stmt):
                out = []
                for st_ in stmts:
                    out.append(st_)
                    if isinstance(st_, ast.Assign) and isinstance(st_.targets[0], ast.Name) \
                            and st_.targets[0].id in self.names:
                        x = ast.Name(st_.targets[0].id, ast.Load())
                        out.append(ast.AugAssign(ast.Name("_lb", ast.Store()), ast.Add(), ast.IfExp(
                            ast.Compare(ast.Call(ast.Name("abs", ast.Load()), [x], []), [ast.Gt()],
                                        [ast.Constant(self.limit)]), ast.Constant(1), ast.Constant(0))))
                setattr(node, field, out)
        return node


def _numba_decorated(fdef, names=("njit", "jit")) -> bool:
    """A decorator we may drop: numba's njit/jit (mechsweep compiles the function with its own
    options), for an inlined helper also mechsweep's jit_inline/jit_noalloc."""
    for d in fdef.decorator_list:
        d = d.func if isinstance(d, ast.Call) else d
        name = d.attr if isinstance(d, ast.Attribute) else getattr(d, "id", "")
        if name not in names:
            return False
    return True


def applies(model, chosen, method: str) -> str | None:
    """The lane rhs source when the lane kernel serves this choice, else None: one measurement
    integrated on its own (a FirstEvent, possibly of a System, or a lone first Crossing) without
    refine, by dop853, of an rhs the rewrite covers."""
    if method != "dop853" or len(chosen) != 1 or getattr(model, "switch_times", None) is not None:
        return None  # a model with switch times integrates one point at a time (model/switches.py)
    m = chosen[0]
    from .compile import _system, is_direct

    if not is_direct(chosen) or getattr(m, "refine", None) is not None:
        return None
    system = _system(m)
    return lane_rhs_source(model.rhs if system is None else system.rhs)


# --------------------------------------------------------------------------- the lane event solver
@jit
def workspace(n, n_lp, lanes, n_p):
    """Everything the lanes of one thread need, as a tuple (indexed by W, Y, PL, LF, LI, SW, WF, YF,
    HK, PR, YV): stages W (WORK_ROWS, n, lanes) in dop853's row layout, states Y (n, lanes), the
    rhs's parameters PL (n_lp, lanes), per-lane floats LF and integers LI, a one-point workspace SW,
    flat views WF, YF of W and Y, the step per flat element HK, each lane's p PR (lanes, n_p) and
    two state vectors YV."""
    w = np.zeros((WORK_ROWS, n, lanes))
    y = np.zeros((n, lanes))
    return (w, y, np.zeros((n_lp, lanes)), np.zeros((N_LF, lanes)), np.zeros((N_LI, lanes), dtype=np.int64),
            np.zeros((WORK_ROWS, n)), w.reshape((WORK_ROWS, n * lanes)), y.reshape(n * lanes), np.zeros(n * lanes),
            np.zeros((lanes, n_p)), np.zeros((2, n)))


@intrinsic
def _fetch_add(typingctx, counter, k):
    """Atomically add ``k`` to ``counter[0]`` (an int64 array), returning its value before: LLVM's
    ``atomicrmw add``, sequentially consistent."""
    if not (isinstance(counter, nbtypes.Array) and counter.dtype == nbtypes.int64
            and isinstance(k, nbtypes.Integer)):
        return None

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [context.get_constant(nbtypes.intp, 0)])
        inc = context.cast(builder, args[1], signature.args[1], nbtypes.int64)
        return builder.atomic_rmw("add", ptr, inc, "seq_cst")

    return nbtypes.int64(counter, k), codegen


@jit_noalloc
def take(counter, k=1):
    """The first of the next ``k`` items of a launch for the calling thread: counter[0], then
    counter[0] += k, as one atomic step. The lane kernel's threads take their points this way, in
    batches, as their lanes free up, so a thread that got a core for less of the launch (another
    thread or process had it) computes fewer points instead of the others waiting for it at the
    launch's end. Which thread or lane computes a point does not change its results."""
    return _fetch_add(counter, k)


@jit_noalloc
def idle(ws, lane):
    """No point left for the lane: it keeps being stepped with h = 0 and is never read."""
    ws[LI][STATE, lane] = IDLE


@jit_noalloc
def lane_result(ws, lane):
    """(point, status, t, n_steps, n_rhs) of the point that has just ended in the lane (t: the
    root's time when OK, else the time reached, as dop853's event solver returns them)."""
    li = ws[LI]
    return li[POINT, lane], li[STATUS, lane], ws[LF][RESULT, lane], li[N_STEPS, lane], li[N_RHS, lane]


@functools.cache
def make_lane_event_solver(rhs_lanes, rhs, event):
    """(load, run): dop853.make_event_solver(rhs, event) for LANES points side by side.

    ``load(ws, lane, point, y0, t_max, rtol, atol)``: start point ``point`` from (0, y0) with the
    parameters ``ws[PR][lane]`` (written by the caller) in the lane.
    ``run(ws, rtol, atol, max_steps) -> lane``: advance the active lanes until one ends and return
    it (-1 when none is left); its outcome is ``lane_result(ws, lane)``; the caller must ``load``
    or ``idle`` the lane before the next ``run``."""
    start = _make_start(rhs)
    dense_output = _make_dense_output(rhs)
    locate_root = _make_root_locator(event)

    @jit_noalloc
    def load(ws, lane, point, y0, t_max, rtol, atol):
        w, y, pl, lf, li, sw, wf, yf, hk, pr, yv = ws
        p = pr[lane]
        li[STATE, lane] = ACTIVE
        li[POINT, lane] = point
        li[STATUS, lane] = OK
        li[N_STEPS, lane] = 0
        li[N_ATTEMPTS, lane] = 0
        li[ACCEPTED, lane] = 0
        li[N_STIFF, lane] = 0
        li[N_NONSTIFF, lane] = 0
        lf[T, lane] = 0.0
        lf[RESULT, lane] = 0.0
        status, h_abs, n_rhs = start(0.0, y0, p, t_max, rtol, atol, 0.0, sw)
        li[N_RHS, lane] = n_rhs
        if status != OK:
            _finish(li, lane, status)
            return
        lf[G_OLD, lane] = event(0.0, y0, p)
        for i in range(y0.size):
            y[i, lane] = y0[i]
            w[0, i, lane] = sw[0, i]
        for j in range(pl.shape[0]):
            pl[j, lane] = p[j]
        lf[T_MAX, lane] = t_max
        lf[H_ABS, lane] = h_abs
        if not 0.0 < t_max:
            _finish(li, lane, NO_EVENT)
        else:
            _begin_advance(lf, li, lane)

    @jit_noalloc
    def stages(w, pl, lf, wf, yf, hk):
        """Stages 1..12 of every lane (dop853 rk_step; stage 12 is f(t + h, y_new), C[12] = 1)."""
        tau = lf[TAU]
        for s in range(1, N_STAGES + 1):
            for l in range(tau.size):
                tau[l] = lf[T, l] + C[s] * lf[H, l]
            if s == K_FSAL:
                sums.solution(yf, hk, wf, wf[Y_NEW])
                rhs_lanes(tau, w[Y_NEW], pl, w[s])
            else:
                sums.stage_argument(s, yf, hk, wf, wf[Y_STAGE])
                rhs_lanes(tau, w[Y_STAGE], pl, w[s])

    @jit_noalloc
    def prepare_attempts(lf, li, max_steps):
        """The checks of dop853's advance() before an attempt, and its step, per lane."""
        attempting = 0
        for l in range(li.shape[1]):
            li[ACCEPTED, l] = 0
            lf[H, l] = 0.0
            lf[T_NEW, l] = lf[T, l]
            if li[STATE, l] != ACTIVE:
                continue
            if lf[H_ABS, l] < lf[MIN_STEP, l]:
                _finish(li, l, NONFINITE if li[LAST_NONFINITE, l] else STEP_UNDERFLOW)
                lf[RESULT, l] = lf[T, l]
                continue
            if li[N_ATTEMPTS, l] >= max_steps:
                _finish(li, l, _failure(MAX_STEPS, li[N_STIFF, l]))
                lf[RESULT, l] = lf[T, l]
                continue
            li[N_ATTEMPTS, l] += 1
            li[N_RHS, l] += N_STAGES
            t_new = min(lf[T, l] + lf[H_ABS, l], lf[T_MAX, l])
            lf[T_NEW, l] = t_new
            lf[H, l] = t_new - lf[T, l]
            attempting += 1
        return attempting

    @jit_noalloc
    def error_tests(w, lf, li, n):
        """Accept or reject each attempting lane (dop853's advance())."""
        for l in range(li.shape[1]):
            if li[STATE, l] != ACTIVE:
                continue
            _error_test(w, lf, li, l, n)

    @jit_noalloc
    def events(w, y, lf, li, sw, pr, yv, max_steps):
        """dop853 event solver's logic after an accepted step, per accepted lane: the event at the
        step end; a sign change: dense output and root on the one-point workspace; else its stiffness
        test late in the step budget, and commit."""
        n, lanes = y.shape
        y_new = yv[0]
        y_old = yv[1]
        for l in range(lanes):
            if not li[ACCEPTED, l]:
                continue
            li[N_STEPS, l] += 1
            t = lf[T, l]
            t_new = lf[T_NEW, l]
            p = pr[l]
            for i in range(n):
                y_new[i] = w[Y_NEW, i, l]
            g_new = event(t_new, y_new, p)
            g_old = lf[G_OLD, l]
            if g_old > 0.0 and g_new <= 0.0:
                h = t_new - t
                for r in range(K_FSAL + 1):
                    for i in range(n):
                        sw[r, i] = w[r, i, l]
                for i in range(n):
                    sw[Y_NEW, i] = y_new[i]
                    y_old[i] = y[i, l]
                dense_output(t, h, y_old, p, sw)
                li[N_RHS, l] += N_STAGES_EXTENDED - N_STAGES - 1
                lf[RESULT, l] = locate_root(t, h, g_old, t_new, g_new, y_old, p, sw)
                _finish(li, l, OK)
                continue
            if _tests_stiffness(False, li[N_ATTEMPTS, l], max_steps, li[N_STIFF, l]):
                li[N_STIFF, l], li[N_NONSTIFF, l] = _stiffness_lane(t_new - t, y, w, l, sw[Y_STAGE], li[N_STIFF, l],
                                                                    li[N_NONSTIFF, l])
            for i in range(n):
                y[i, l] = y_new[i]
                w[0, i, l] = w[K_FSAL, i, l]  # first same as last
            lf[T, l] = t_new
            lf[G_OLD, l] = g_new
            if t_new < lf[T_MAX, l]:
                _begin_advance(lf, li, l)
            else:
                lf[RESULT, l] = t_new
                _finish(li, l, NO_EVENT)

    @jit_noalloc
    def run(ws, rtol, atol, max_steps):
        w, y, pl, lf, li, sw, wf, yf, hk, pr, yv = ws
        n, lanes = y.shape
        e5 = wf[Y_STAGE]  # scratch rows of the error estimates, free after the step
        e3 = wf[F_DENSE]
        while True:
            active = 0
            for l in range(lanes):
                if li[STATE, l] == DONE:
                    return l
                if li[STATE, l] == ACTIVE:
                    active += 1
            if active == 0:
                return -1
            if prepare_attempts(lf, li, max_steps) == 0:
                continue  # every active lane ended in the checks
            _spread(lf[H], hk, lanes)
            stages(w, pl, lf, wf, yf, hk)
            sums.error_estimates(wf, e5, e3)
            _error_sums(y, w, e5, e3, rtol, atol, lf[SUM5], lf[SUM3])
            error_tests(w, lf, li, n)
            events(w, y, lf, li, sw, pr, yv, max_steps)

    return load, run


# --------------------------------------------------------------------------- the generated kernel
def kernel_source(model, chosen, refs: dict, origin: str, closed, lane_rhs: str) -> str:
    """Source of the generated module for the lane kernel (same contract as compile.kernel_source:
    ``kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs)``)."""
    from .compile import _guard_call, _describe, _system, columns, layout, module_prologue

    n_p, n_set, n_int = layout(model)
    n_s = len(model.states)
    npi = n_p + n_set + n_int
    (m,) = chosen
    own = "" if _system(m) is None else "0"  # the suffix of the measurement's equation (compile._own_body)
    lines = module_prologue(f"mechsweep.model.compile (lanes) for model {model.name!r}, method dop853",
                            ("from mechsweep._jit import jit, jit_noalloc, pjit, prange",
                             "from mechsweep.model import lanes"), refs)
    lines.append(f"NP = {n_p}\nNSET = {n_set}\nNPI = {npi}  # p[NPI]: the point's user-error flag\nSCR = NPI + 1\n"
                 f"NS = {n_s}\nNSCR = {n_s}\nLANES = {lanes_for(n_s)}\nLBLOCK = {lanes_for(n_s) * QUEUE}\nGRAB = {GRAB}\nNKEEP = {1 + len(closed)}\n")
    for j, c in enumerate(closed):
        args = ", ".join(["p"] + [f"x{i}" for i in range(len(c.needs))])
        lines.append("\n" + _guard_call(f"closed{j}", args))
    lines.append(f"\n# ---- measurement 0: {_describe(m)}, direct, dop853 in lanes\n")
    if type(m).__name__ == "Crossing":
        sign = 1.0 if m.direction == "down" else -1.0
        idx = model.states.index(m.state)
        lines.append(f"@jit\ndef event0(t, y, p):\n    return {sign!r} * (y[{idx}] - {float(m.level)!r})\n\n")
    else:
        lines.append(_guard_call("event0", "t, y, p"))
        if "t_max0" in refs:
            lines.append(_guard_call("t_max0", "p"))
        if "value0" in refs:
            lines.append(_guard_call("value0", "p, t"))
    tm = "t_max0(p)" if "t_max0" in refs else repr(float(m.t_max))
    lines.append("\n\n" + lane_rhs + f"\n\nlane_load, lane_run = lanes.make_lane_event_solver(rhs_lanes, rhs{own}, event0)\n")
    cols = columns(chosen)
    closed_col = {c.name: cols[-1] + j for j, c in enumerate(closed)}
    after = [j for j, c in enumerate(closed) if m.name in c.needs]
    before = [j for j in range(len(closed)) if j not in after]
    names = [c.name for c in closed]

    def closed_code(which, ind):
        out = []
        for j in which:
            c = closed[j]
            args = ", ".join(["p"] + ["m0" if x == m.name else f"cf{names.index(x)}" for x in c.needs])
            if f"cfclassify{j}" in refs:
                out.append(f"""
{ind}cf{j} = math.nan
{ind}if need[{j}]:
{ind}    cc = cfclassify{j}(p)
{ind}    if cc != st.OK:
{ind}        if code == st.OK:
{ind}            code = cc
{ind}    else:
{ind}        cf{j} = closed{j}({args})
{ind}        table[i, {closed_col[c.name]}] = cf{j}""")
            else:
                out.append(f"""
{ind}cf{j} = math.nan
{ind}if need[{j}]:
{ind}    cf{j} = closed{j}({args})
{ind}    table[i, {closed_col[c.name]}] = cf{j}""")
        return "".join(out)

    ind = " " * 8
    classify = ""
    if "classify" in refs:
        classify = f"""
{ind}c = classify(p)
{ind}if c != st.OK:
{ind}    status[i] = c
{ind}    continue"""
    prepare = f"\n{ind}c = prepare(p, rtol)" if "prepare" in refs else f"\n{ind}c = st.OK"
    keep = "".join(f"\n{ind}keep[lane, {1 + k}] = cf{j}" for k, j in enumerate(before))
    restore = "".join(f"\n    cf{j} = kp[{1 + k}]" for k, j in enumerate(before))
    value = "\n    if c == st.OK:\n        val = value0(p, val)" if "value0" in refs else ""
    if own:  # compile._own_body / _pass_source: the System's prepare, then t_max, then its initial state
        start = f"\n        tm = {tm}\n        initial0(p, y)\n        lane_load(ws, lane, ii, y, tm, rtol, atol)"
        if "prepare0" in refs:
            start = ("\n        c = prepare0(p, rtol)\n        if c != st.OK:\n"
                     "            conclude(ii, p, keep[lane], c, math.nan, 0, 0, need, table, status, n_steps, n_rhs)\n"
                     "            continue" + start)
    else:
        start = f"\n        initial(p, y)\n        lane_load(ws, lane, ii, y, {tm}, rtol, atol)"
    # feed, conclude, settle and refill run once per point and take the ws tuple (11 arrays) and ~10
    # arrays more: compiled with numba's reference counting, each call and each view (p = ws[PR][lane])
    # cost atomic increments and decrements of those arrays' counts: 12 % of the Duffing lane kernel's
    # perf samples (tests/data/nrt_share.py), and `mechsweep bench duffing` went from 1.29-1.30 to
    # 1.67-1.72 M points/s on 2 threads when they became jit_noalloc. They allocate nothing; work()
    # allocates the lanes.
    lines.append(f"""

@jit_noalloc
def feed(lane, i, n, stride, ws, keep, y, P, S, need, rtol, atol, table, status, n_steps, n_rhs):
    \"\"\"The next point of this queue (from i on, every stride-th) that needs the integration goes
    into the lane (returns the index after it); points settled before it are written here.\"\"\"
    p = ws[lanes.PR][lane]
    while i < n:
        ii = i
        i += stride
        if status[ii] != st.OK:
            continue
        for j in range(NP):
            p[j] = P[ii, j]
        for j in range(NSET):
            p[NP + j] = S[j]
        for j in range(NP + NSET, SCR + NSCR):
            p[j] = 0.0
        code = st.OK{classify.replace('[i]', '[ii]')}{closed_code(before, ind).replace('[i,', '[ii,')}
        m0 = math.nan{prepare}
        if c != st.OK:
            code = c{closed_code(after, ind + '    ').replace('[i,', '[ii,')}
            if p[NPI] != 0.0 and code == st.OK:
                code = st.USER_ERROR
            status[ii] = code
            continue
        keep[lane, 0] = code{keep}{start}
        return i
    lanes.idle(ws, lane)
    return n


@jit_noalloc
def conclude(i, p, kp, c, val, a, b_, need, table, status, n_steps, n_rhs):
    \"\"\"What the one-point kernel does after the integration of point i (status c, root time val,
    a steps, b_ rhs calls); kp: what the point kept from before it.\"\"\"
    code = np.int64(kp[0]){restore}
    m0 = math.nan
    n_steps[i] += a
    n_rhs[i] += b_{value}
    if p[NPI] != 0.0:
        c = st.USER_ERROR
    if c == st.OK and not math.isfinite(val):
        c = st.NONFINITE
    if c == st.OK:
        table[i, {cols[0]}] = val
        m0 = val
    elif code == st.OK:
        code = c{closed_code(after, '    ')}
    if p[NPI] != 0.0 and code == st.OK:
        code = st.USER_ERROR
    status[i] = code


@jit_noalloc
def settle(lane, ws, keep, need, table, status, n_steps, n_rhs):
    \"\"\"conclude() for the point the lane has finished.\"\"\"
    i, c, val, a, b_ = lanes.lane_result(ws, lane)
    conclude(i, ws[lanes.PR][lane], keep[lane], c, val, a, b_, need, table, status, n_steps, n_rhs)


@jit_noalloc
def refill(lane, mine, taken, n, ws, keep, y, P, S, need, rtol, atol, table, status, n_steps, n_rhs):
    \"\"\"The lane's next point: from this thread's batch mine = [next, end) of the launch's points, and
    when it is used up from a new batch of GRAB points taken from the launch's shared counter; the
    lane idles when every point is taken.\"\"\"
    while True:
        if mine[0] >= mine[1]:
            lo = lanes.take(taken, GRAB)
            if lo >= n:
                lanes.idle(ws, lane)
                return
            mine[0] = lo
            mine[1] = min(lo + GRAB, n)
        mine[0] = feed(lane, mine[0], mine[1], 1, ws, keep, y, P, S, need, rtol, atol, table, status, n_steps, n_rhs)
        if ws[lanes.LI][lanes.STATE, lane] != lanes.IDLE:
            return


@jit
def work(taken, P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs):
    \"\"\"One thread's share of the launch: its LANES lanes, each refilled as its point ends, from
    batches of points it takes until none is left (nothing is allocated if none is left at its start).\"\"\"
    n = P.shape[0]
    lo = lanes.take(taken, GRAB)
    if lo >= n:
        return
    mine = np.empty(2, dtype=np.int64)
    mine[0] = lo
    mine[1] = min(lo + GRAB, n)
    ws = lanes.workspace(NS, NPI, LANES, SCR + NSCR)
    keep = np.empty((LANES, NKEEP))
    y = np.empty(NS)
    for lane in range(LANES):
        refill(lane, mine, taken, n, ws, keep, y, P, S, need, rtol, atol, table, status, n_steps, n_rhs)
    while True:
        lane = lane_run(ws, rtol, atol, max_steps)
        if lane < 0:
            break
        settle(lane, ws, keep, need, table, status, n_steps, n_rhs)
        refill(lane, mine, taken, n, ws, keep, y, P, S, need, rtol, atol, table, status, n_steps, n_rhs)


@pjit
def kernel(P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs):
    n = P.shape[0]
    # Points are taken, not dealt: numba splits a prange's iterations evenly among the threads in
    # advance (its omp layer), so a thread that lost its core for a while (the run's writer thread,
    # another process) made the others wait at the end of each launch. Here each thread's lanes take
    # the launch's points in batches of GRAB from one shared counter (lanes.take, atomic) until none
    # is left, so the threads end within about a point's integration of each other, and each
    # thread's lanes run idle only once per launch, at its end. Each prange iteration is a worker
    # with its own lanes: the first worker of each thread does the work, the others find nothing
    # taken by them; their number is enough for any thread count that can have points (up to 16 for
    # a small launch, one per LANES * QUEUE points beyond). The thread count is not read here:
    # numba.get_num_threads() would keep the kernel out of the disk cache.
    n_workers = max((n + LBLOCK - 1) // LBLOCK, min((n + 16 * LANES - 1) // (16 * LANES), 16))
    taken = np.zeros(1, dtype=np.int64)
    for worker in prange(n_workers):
        work(taken, P, S, need, rtol, atol, max_steps, table, status, n_steps, n_rhs)
""")
    return "".join(lines)
