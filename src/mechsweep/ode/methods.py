"""The integration methods as objects: what ``solver.method`` names.

Each method knows how to integrate one point from its initial state (a *pass*), whatever the
engine measures along the way, with the same factory methods:

- ``workspace(n)``: a jitted allocator ``new() -> work`` of the method's scratch for n states;
- ``event_pass(eq, start, event, n=1, since=0)``: ``run(p, y, t_max, rtol, atol, max_steps, work) ->
  (status, t, n_steps, n_rhs)``: ``start(p, y)`` writes the initial state, then the ``n``-th root of
  ``event`` (from > 0 to <= 0) is searched (:func:`root_search`);
- ``plain_pass(eq, start)``: ``run(p, y, t_end, rtol, atol, max_steps, work) -> (status, n_steps,
  n_rhs)``, to ``t_end`` exactly;
- ``trajectory_pass(eq, start)``: ``run(p, y, t_eval, rtol, atol, max_steps, work, out) -> (status,
  n_steps, n_rhs)``, the states at ``t_eval`` into ``out``.

Every event solver a method makes has one signature, ``solve(t0, y, p, t_max, rtol, atol, h0,
max_steps, work) -> (status, t, n_steps, n_rhs)``: the symplectic method's (which steps q and v with a
fixed step) takes its step as ``h0`` and y = (q, v). ``fixed_step`` says whether a search that
restarts at a root passes ``h0`` on (the fixed step) or 0.0 (a new first step).

``eq`` (:class:`Equation`) bundles the jitted functions of one equation (rhs, jac, accel, step).
``AUTO`` is dop853 with Hairer's stiffness test whose stiff points are integrated again from the
start by radau, the costs added. ``switched(method, switches)`` is a method whose solvers end a
step on each of a model's declared switch times (model/switches.py).
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from .. import status as st
from .._jit import jit_internal, jit_into_caller
from . import dop853, radau, symplectic


@dataclass(frozen=True)
class Equation:
    """One equation's jitted functions: ``rhs(t, y, p, dydt)``, ``jac(t, y, p, J)`` (radau; the engine
    supplies central differences where the model has none), ``accel(t, q, p, a)`` and
    ``step(p, rtol) -> h`` (symplectic, with ``order``), ``n`` states. Hashed by identity of its
    functions, so a factory asked twice for the same equation returns the same solver."""

    rhs: object
    n: int
    jac: object = None
    accel: object = None
    step: object = None
    order: int = 8


class Method:
    """A method of integration (see the module's docstring)."""

    name = ""
    code = -1  # ode.METHOD_CODES
    fixed_step = False
    lanes = False  # whether engine/lanes.py can integrate it in SIMD lanes (dop853)
    jacobian = False  # whether it uses the equation's Jacobian (radau; auto for its stiff points)
    restart = None  # the method a point found stiff is integrated again by (auto: radau)

    def __repr__(self):
        return f"<method {self.name}>"

    # ---- the solvers of one step kind (overridden per method; Switched wraps them)
    def event_solver(self, eq, event):
        raise NotImplementedError

    def solver(self, eq):
        raise NotImplementedError

    def trajectory_solver(self, eq):
        raise NotImplementedError

    def workspace(self, n):
        raise NotImplementedError

    # ---- passes from the initial state
    def event_pass(self, eq, start, event, n=1, since=0):
        solve = root_search(functools.partial(self.event_solver, eq), event, n, since, self.fixed_step)
        return _event_pass(solve, start, self.step_of(eq))

    def plain_pass(self, eq, start):
        return _plain_pass(self.solver(eq), start, self.step_of(eq))

    def trajectory_pass(self, eq, start):
        return _trajectory_pass(self.trajectory_solver(eq), start)

    # the first step handed to the solver: 0.0 (chosen by the solver), or a fixed step from p and rtol
    def step_of(self, eq):
        return _no_step


@jit_internal
def _no_step(p, rtol):
    return 0.0


@functools.cache
def _event_pass(solve, start, step):
    @jit_into_caller  # a thin pass around the solver: compiled into its caller (no link of its own)
    def run(p, y, t_max, rtol, atol, max_steps, work):
        start(p, y)
        h = step(p, rtol)
        if not h >= 0.0:  # a fixed step that is not a number > 0 (symplectic_step): nothing integrated
            return st.NONFINITE, math.nan, 0, 0
        return solve(0.0, y, p, t_max, rtol, atol, h, max_steps, work)

    return run


@functools.cache
def _plain_pass(solve, start, step):
    @jit_into_caller  # a thin pass around the solver: compiled into its caller (no link of its own)
    def run(p, y, t_end, rtol, atol, max_steps, work):
        start(p, y)
        return solve(0.0, y, p, t_end, rtol, atol, step(p, rtol), max_steps, work)

    return run


@functools.cache
def _trajectory_pass(solve, start):
    @jit_into_caller  # a thin pass around the solver: compiled into its caller (no link of its own)
    def run(p, y, t_eval, rtol, atol, max_steps, work, out):
        start(p, y)
        return solve(0.0, y, p, t_eval, rtol, atol, 0.0, max_steps, work, out)

    return run


@functools.cache
def _allocator(make, n):
    @jit_into_caller  # a thin pass around the solver: compiled into its caller (no link of its own)
    def new():
        return make(n)

    return new


class _DOP853(Method):
    name = "dop853"
    code = 0
    lanes = True
    stiffness_test = False

    def event_solver(self, eq, event):
        return dop853.make_event_solver(eq.rhs, event, stiffness_test=self.stiffness_test)

    def solver(self, eq):
        return dop853.make_solver(eq.rhs, stiffness_test=self.stiffness_test)

    def trajectory_solver(self, eq):
        return dop853.make_trajectory_solver(eq.rhs, stiffness_test=self.stiffness_test)

    def workspace(self, n):
        return _allocator(dop853.workspace, n)


class _Radau(Method):
    name = "radau"
    code = 1
    jacobian = True

    def event_solver(self, eq, event):
        return radau.make_event_solver(eq.rhs, eq.jac, event)

    def solver(self, eq):
        return radau.make_solver(eq.rhs, eq.jac)

    def trajectory_solver(self, eq):
        return radau.make_trajectory_solver(eq.rhs, eq.jac)

    def workspace(self, n):
        return _allocator(radau.workspace, n)


class _Symplectic(Method):
    """The symplectic compositions: y = (q, v) with q' = v, v' = accel(t, q, p), a fixed step
    ``step(p, rtol)`` (NONFINITE where it is not a number > 0); event only (the engine's other
    measurements observe dop853). The work is (q, v, the method's workspace)."""

    name = "symplectic"
    code = 2
    fixed_step = True

    def event_solver(self, eq, event):
        return _symplectic_event_solver(symplectic.make_event_solver(eq.accel, _on_qv(event, eq.n), eq.order),
                                        eq.n // 2)

    def step_of(self, eq):
        return _positive_step(eq.step)

    def workspace(self, n):
        return _symplectic_allocator(n // 2)


@functools.cache
def _positive_step(step):
    @jit_internal
    def h_of(p, rtol):
        h = step(p, rtol)
        return h if h > 0.0 else math.nan

    return h_of


@functools.cache
def _symplectic_allocator(nq):
    @jit_internal
    def new():
        return np.empty(nq), np.empty(nq), symplectic.workspace(nq)

    return new


@functools.cache
def _on_qv(event, n):
    """The event of y on the symplectic solver's (q, v): y copied into the last n slots of p (the
    engine's scratch: the user's functions read only the declared slots)."""
    nq = n // 2

    @jit_internal
    def qv_event(t, q, v, p):
        yb = p[p.size - n:]
        for j in range(nq):
            yb[j] = q[j]
            yb[nq + j] = v[j]
        return event(t, yb, p)

    return qv_event


@functools.cache
def _symplectic_event_solver(solve, nq):
    @jit_internal
    def run(t0, y, p, t_max, rtol, atol, h, max_steps, work):
        q, v, sw = work
        for j in range(nq):
            q[j] = y[j]
            v[j] = y[nq + j]
        c, t, a, b = solve(t0, q, v, p, h, t_max, max_steps, sw)
        for j in range(nq):
            y[j] = q[j]
            y[nq + j] = v[j]
        return c, t, a, b

    return run


class Auto(Method):
    """dop853 with the stiffness test; a stiff point again from the start by radau, the costs added."""

    name = "auto"
    code = 3
    jacobian = True

    def __init__(self, first, then):
        self.first, self.restart = first, then

    def workspace(self, n):
        return _pair_allocator(self.first.workspace(n), self.restart.workspace(n))

    def event_pass(self, eq, start, event, n=1, since=0):
        return _restarting(self.first.event_pass(eq, start, event, n, since),
                           self.restart.event_pass(eq, start, event, n, since), 4)

    def plain_pass(self, eq, start):
        return _restarting(self.first.plain_pass(eq, start), self.restart.plain_pass(eq, start), 3)

    def trajectory_pass(self, eq, start):
        return _restarting_out(self.first.trajectory_pass(eq, start), self.restart.trajectory_pass(eq, start))


@functools.cache
def _pair_allocator(a, b):
    @jit_internal
    def new():
        return a(), b()

    return new


@functools.cache
def _restarting(first, then, arity):
    if arity == 4:
        @jit_internal
        def run(p, y, t_max, rtol, atol, max_steps, work):
            c, val, a, b = first(p, y, t_max, rtol, atol, max_steps, work[0])
            if c == st.STIFF:  # a stiff point starts again with radau; the costs add up
                c, val, a2, b2 = then(p, y, t_max, rtol, atol, max_steps, work[1])
                a += a2
                b += b2
            return c, val, a, b
    else:
        @jit_internal
        def run(p, y, t_end, rtol, atol, max_steps, work):
            c, a, b = first(p, y, t_end, rtol, atol, max_steps, work[0])
            if c == st.STIFF:
                c, a2, b2 = then(p, y, t_end, rtol, atol, max_steps, work[1])
                a += a2
                b += b2
            return c, a, b
    return run


@functools.cache
def _restarting_out(first, then):
    @jit_internal
    def run(p, y, t_eval, rtol, atol, max_steps, work, out):
        c, a, b = first(p, y, t_eval, rtol, atol, max_steps, work[0], out)
        if c == st.STIFF:
            c, a2, b2 = then(p, y, t_eval, rtol, atol, max_steps, work[1], out)
            a += a2
            b += b2
        return c, a, b

    return run


@functools.cache
def negated(event):
    """The event of the other direction: -event."""
    @jit_internal
    def other(t, y, p):
        return -event(t, y, p)

    return other


def root_search(make, event, n=1, since=0, fixed_step=False):
    """The solver (event solver signature) of the ``n``-th root of ``event`` (from > 0 to <= 0),
    ``make(event)`` making the method's event solver: itself for n = 1; else 2 n - 1 searches,
    alternating with the other direction's (``negated``) so that a search never restarts on the root
    it just found, each from the previous root with a new first step (the fixed step for a fixed-step
    method) and what is left of max_steps after the accepted steps before it. A search without a root
    (NO_EVENT: fewer than n before t_max) or failing ends it with its status. ``since`` > 0: the time
    returned is from root ``since`` to root n (1 and 2: the period of an autonomous oscillation)."""
    if n == 1:
        return make(event)
    return _nth_root(make(event), make(negated(event)), n, since, fixed_step)


@functools.cache
def _nth_root(forward, back, n, since, fixed_step):
    searches = 2 * (n - 1)
    at_since = 2 * since - 3  # the search that ends on root `since` (since >= 2)

    @jit_internal
    def solve(t0, y, p, t_max, rtol, atol, h0, max_steps, work):
        h = h0 if fixed_step else 0.0
        c, t, a, b = forward(t0, y, p, t_max, rtol, atol, h0, max_steps, work)
        ts = t if since == 1 else 0.0  # the time the result is counted from
        for j in range(searches):
            if c != st.OK:
                break
            if a >= max_steps:
                c = st.MAX_STEPS
                break
            if j % 2 == 0:
                c, t, a2, b2 = back(t, y, p, t_max, rtol, atol, h, max_steps - a, work)
            else:
                c, t, a2, b2 = forward(t, y, p, t_max, rtol, atol, h, max_steps - a, work)
            a += a2
            b += b2
            if j == at_since:
                ts = t
        return c, t - ts, a, b

    return solve


DOP853 = _DOP853()
RADAU = _Radau()
SYMPLECTIC = _Symplectic()


class _StiffDOP853(_DOP853):
    name = "dop853 (stiffness test)"
    lanes = False
    stiffness_test = True


AUTO = Auto(_StiffDOP853(), RADAU)
METHODS = {m.name: m for m in (DOP853, RADAU, SYMPLECTIC, AUTO)}


def method(name: str) -> Method:
    """The method object ``solver.method`` names."""
    return METHODS[name]
