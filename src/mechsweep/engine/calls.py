"""How a kernel calls the model's functions: jitted, guarded, chained; and how statuses combine.

A user's function is compiled by model/load.py (``jitted``: a function of its own; ``inlined``:
compiled into each caller). The one-point kernel calls them as they are and catches an exception
once per point (engine/point.py); the lane and trajectory kernels call them through a *guard*: an
exception the user's code raises at a point inside a parallel loop must not escape the kernel (numba
would lose it or leave Python's error indicator set), so the guard catches it, writes NaN (or returns
USER_ERROR for a status function) and raises the point's flag ``p[npi]`` (the slot after the internal
ones); the kernel then gives that point USER_ERROR and computes the others. numba's ``try`` catches
only what a called (not inlined) function raises, hence the guards call ``jitted`` functions.

Every factory here is memoised on its arguments (jitted functions compare by identity), so a kernel
asked for twice is composed from the same functions.
"""
from __future__ import annotations

import functools
import math

import numpy as np
from numba.np.unsafe.ndarray import to_fixed_tuple

from .. import status as st
from .._jit import jit_internal, jit_into_caller
from ..model import load


def user(model_name: str, func, role: str, inline: bool = False):
    """The jitted ``func`` of a model (``inline``: compiled into each numba caller, load.inlined)."""
    ref = load.function_ref(func, role, model_name)
    return load.inlined(*ref) if inline else load.jitted(*ref)


def ref(model_name: str, func, role: str) -> tuple:
    """(module, path, qualified name) of a model's function: what a binding's name is keyed by."""
    return load.function_ref(func, role, model_name)


# ----------------------------------------------------------------------------- guards
@functools.cache
def guard_fill(f, npi: int):
    """``g(t, y, p, out)`` (rhs, accel, a variational system, a Jacobian): NaN into ``out`` if ``f`` raises."""
    @jit_internal
    def g(t, y, p, out):
        try:
            f(t, y, p, out)
        except Exception:
            out.fill(np.nan)
            p[npi] = 1.0

    return g


@functools.cache
def guard_initial(f, npi: int):
    """``g(p, y0)``: NaN into ``y0`` if ``f`` raises."""
    @jit_internal
    def g(p, y0):
        try:
            f(p, y0)
        except Exception:
            y0[:] = np.nan
            p[npi] = 1.0

    return g


@functools.cache
def guard_status(f, arity: int):
    """``g(p)`` or ``g(p, x)`` returning a status (classify, prepare): USER_ERROR if ``f`` raises."""
    if arity == 1:
        @jit_internal
        def g(p):
            try:
                return f(p)
            except Exception:
                return st.USER_ERROR
    else:
        @jit_internal
        def g(p, x):
            try:
                return f(p, x)
            except Exception:
                return st.USER_ERROR
    return g


@functools.cache
def guard_value(f, npi: int, args: str):
    """A function returning a number, NaN if it raises: ``args`` "p" (t_max, a window's end, the
    forcing period), "p,x" (value, time_value, symplectic_step), "p,x,y" (refine) or "t,y,p" (an event,
    an observable)."""
    if args == "p":
        @jit_internal
        def g(p):
            try:
                return f(p)
            except Exception:
                p[npi] = 1.0
                return np.nan
    elif args == "p,x":
        @jit_internal
        def g(p, x):
            try:
                return f(p, x)
            except Exception:
                p[npi] = 1.0
                return np.nan
    elif args == "p,x,y":
        @jit_internal
        def g(p, x, y):
            try:
                return f(p, x, y)
            except Exception:
                p[npi] = 1.0
                return np.nan
    elif args == "t,y,p":
        @jit_internal
        def g(t, y, p):
            try:
                return f(t, y, p)
            except Exception:
                p[npi] = 1.0
                return np.nan
    else:
        raise ValueError(args)
    return g


# ----------------------------------------------------------------------------- statuses
@functools.cache
def folder(order: tuple):
    """``fold(code, c)``: the point's status after a stage gave ``c``: the first failure wins, or
    with a model's ``status_order`` (most severe first) the more severe (status.ranks)."""
    if not order:
        @jit_into_caller
        def fold(code, c):
            if c != st.OK and code == st.OK:
                return c
            return code
        return fold

    rank = st.ranks(order)

    @jit_into_caller
    def worse(code, c):
        return c if rank[c] < rank[code] else code

    return worse


# ----------------------------------------------------------------------------- closed forms
@functools.cache
def closed_call(f, plain, slots: tuple, npi: int, guarded: bool):
    """``call(p, cv, buf) -> float``: the closed form ``f(p, cv[slots[0]], cv[slots[1]], ...)``, the values
    it needs read from the point's value row ``cv`` (``buf``: scratch of at least len(slots) floats);
    ``guarded``: NaN and the point's flag if it raises. ``f`` may be compiled into the caller (numba
    inlines no call with ``*args``: more than four values go through ``plain``, compiled on its own)."""
    k = len(slots)
    if guarded or k > 4:
        return _star_call(plain, slots, npi, guarded)
    a0, a1, a2, a3 = slots + (0,) * (4 - k)
    if k == 0:
        @jit_into_caller
        def call(p, cv, buf):
            return f(p)
    elif k == 1:
        @jit_into_caller
        def call(p, cv, buf):
            return f(p, cv[a0])
    elif k == 2:
        @jit_into_caller
        def call(p, cv, buf):
            return f(p, cv[a0], cv[a1])
    elif k == 3:
        @jit_into_caller
        def call(p, cv, buf):
            return f(p, cv[a0], cv[a1], cv[a2])
    else:
        @jit_into_caller
        def call(p, cv, buf):
            return f(p, cv[a0], cv[a1], cv[a2], cv[a3])
    return call


@functools.cache
def _star_call(f, slots: tuple, npi: int, guarded: bool):
    k = len(slots)
    if guarded:  # the call in a function of its own: numba reads no ``*args`` call inside a try
        inner = _star_call(f, slots, npi, False)

        @jit_internal
        def call(p, cv, buf):
            try:
                return inner(p, cv, buf)
            except Exception:
                p[npi] = 1.0
                return np.nan
    elif k == 0:
        @jit_internal
        def call(p, cv, buf):
            return f(p)
    else:
        @jit_internal
        def call(p, cv, buf):
            for j in range(k):
                buf[j] = cv[slots[j]]
            return f(p, *to_fixed_tuple(buf, k))
    return call


@functools.cache
def closed_link(call, classify, j: int, col: int, slot: int, fold):
    """One closed form j of a point (where ``need[j]``): its value into ``table[i, col]`` and ``cv[slot]``
    (NaN where not computed); ``classify`` (or None): where the formula does not apply, its status
    folds into the point's."""
    if classify is None:
        @jit_into_caller
        def link(i, p, need, cv, buf, table, code):
            v = math.nan
            if need[j]:
                v = call(p, cv, buf)
                table[i, col] = v
            cv[slot] = v
            return code
    else:
        @jit_into_caller
        def link(i, p, need, cv, buf, table, code):
            v = math.nan
            if need[j]:
                cc = classify(p)
                if cc != st.OK:
                    code = fold(code, cc)
                else:
                    v = call(p, cv, buf)
                    table[i, col] = v
            cv[slot] = v
            return code
    return link


@functools.cache
def chain(links: tuple):
    """``run(i, p, need, cv, buf, table, code) -> code``: the links one after the other."""
    if not links:
        @jit_into_caller
        def none(i, p, need, cv, buf, table, code):
            return code
        return none
    if len(links) == 1:
        return links[0]
    first, rest = links[0], chain(links[1:])

    @jit_into_caller
    def both(i, p, need, cv, buf, table, code):
        code = first(i, p, need, cv, buf, table, code)
        return rest(i, p, need, cv, buf, table, code)

    return both
