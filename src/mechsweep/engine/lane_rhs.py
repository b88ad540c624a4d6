"""The lane form of a model's right-hand side: the engine's one source transformation.

The lane kernels (engine/lanes.py, engine/trajectory.py) integrate LANES points side by side, the state
laid out [state, lane], lanes innermost. Their right-hand side is built from the model's scalar rhs:
its source is parsed and rewritten so that ``y[i]``, ``p[k]``, ``dydt[i]`` and ``t`` become ``Z[i, l]``,
``P[k, l]``, ``dZ[i, l]`` and ``tau[l]`` inside one loop over the lanes ``l``, which LLVM vectorises (no
call but math functions, so nothing stops it). Module constants the rhs reads (e.g. duffing's slot
numbers) are written in as their values. A plain module-level function called as a whole statement
is inlined first (_Flatten: arguments bound in order, array arguments and slices of them mapped onto
y, p, dydt with their offsets), special.sincos becomes sincos_reduced plus a second pass with sincos
where any lane is beyond its range, and with many dydt rows the rows copied from the inputs get a loop
of their own (LLVM's aliasing checks). An rhs the rewrite does not cover (a call inside an
expression, a ``raise``, ``y`` or ``p`` used other than by a scalar index, a write into y or p, a
``while``, an early ``return``) is not laned: the model keeps the one-at-a-time route (no error, same
results). The rewrite is the same per-lane arithmetic in the same order as the scalar rhs (numba's
fastmath is off, so LLVM neither reassociates nor fuses multiply-adds), so each lane computes the
scalar rhs's floats.

``lane_rhs_source(func)`` returns the text of ``rhs_lanes(tau, Z, P, dZ)`` decorated ``@jit_noalloc``
(it goes into the kernel's binding module, engine/binding.py, which binds that name to
``jit_internal_noalloc``: only the kernel calls it), or None.
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
    return (f"# the lane form of {func.__module__}.{func.__qualname__}, written by mechsweep.engine.lane_rhs\n"
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


def binding_text(source: str) -> str:
    """The lane rhs ``source`` as a kernel's binding module holds it: with the names its text uses."""
    # only the kernel calls it: jit_noalloc without the wrappers a Python caller needs (_jit.jit_internal)
    return "import math\n\nfrom mechsweep._jit import jit_internal_noalloc as jit_noalloc\n\n" + source
