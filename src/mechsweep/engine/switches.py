"""A model's declared switch times in its kernels (``OdeModel(switch_times=...)``, model/switches.py).

Every integration of such a model ends a step exactly on each switch and starts the next step there
afresh, so no step, dense output, event search or stiffness count straddles a switch; and the time its
rhs (its jac, a Floquet's own variational system) sees is kept inside the segment being integrated,
[a + d(a), b - d(b)] with d(x) = SIDE |x| (about ten ulps): the step that ends on b sees the interval
before b, the step that starts at b the interval after it, whatever the rhs does at b exactly. The
integration's own start (t = 0, or a restart at an event) is not moved.

``functions(...)``: the per-point functions of the switches, kept in two slots of p (``at``, ``at +
1``: the clamp of the rhs's time): ``check(p)`` (OK, or INFEASIBLE where the switch times are not
increasing times in [0, T) of the forcing period T), ``next_switch(t, p)`` and ``clamp(p, lo, hi)``;
``clamped(f)``: a function of t that sees the clamped time. ``switched(method, ...)``: a method
(ode/methods.py) whose solvers integrate from switch to switch.

Each segment is a new call of the wrapped solver: its first step is chosen again and its step budget
is what is left of ``max_steps`` after the accepted steps before it. A trajectory segment whose last
sample lies before the switch is integrated on to the switch by the plain solver. The shared
trajectory (engine/shared.py) keeps its step size across a switch and re-evaluates f there.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .. import status as st
from .._jit import jit_internal, jit_into_caller
from ..model.switches import SIDE
from ..ode import methods


@functools.cache
def functions(switch_list, forcing, at: int, npi: int, guarded: bool):
    """(check, next_switch, clamp) of one model's switches: ``switch_list(p)`` the times in [0, T)
    (the declared constants, or the model's function), ``forcing(p)`` the period T, p[at], p[at + 1]
    the clamp; ``guarded``: an exception of the model's code flags the point (p[npi]) and gives
    USER_ERROR (check) or NaN (next_switch) instead of ending the point."""
    body = jit_internal if guarded else jit_into_caller

    @body
    def check_times(p):
        # OK, or INFEASIBLE where the switch times are not increasing times in [0, T), T finite > 0
        T = forcing(p)
        if not (math.isfinite(T) and T > 0.0):
            return st.INFEASIBLE
        last = -1.0
        n = 0
        for b in switch_list(p):
            x = float(b)
            if not (math.isfinite(x) and x >= 0.0 and x < T and x > last):
                return st.INFEASIBLE
            last = x
            n += 1
        return st.OK if n > 0 else st.INFEASIBLE

    @body
    def next_time(t, p):
        # the first switch time after t (k T + b > t)
        T = forcing(p)
        k = math.floor(t / T) - 1.0
        best = math.inf
        for j in range(3):
            base = (k + j) * T
            for b in switch_list(p):
                x = base + float(b)
                if x > t and x < best:
                    best = x
        return best

    if guarded:
        @jit_internal
        def check(p):
            try:
                return check_times(p)
            except Exception:
                p[npi] = 1.0
                return st.USER_ERROR

        @jit_internal
        def next_switch(t, p):
            try:
                return next_time(t, p)
            except Exception:
                p[npi] = 1.0
                return math.nan
    else:
        check, next_switch = check_times, next_time

    @jit_internal
    def clamp(p, lo, hi):
        p[at] = lo
        p[at + 1] = hi

    return check, next_switch, clamp


@functools.cache
def constant_list(times: tuple):
    """``switch_list(p)`` of switch times declared as constants."""
    @jit_into_caller
    def switch_list(p):
        return times

    return switch_list


@functools.cache
def clamped(f, at: int):
    """``g(t, a, p, out)``: ``f`` at the time kept in [p[at], p[at + 1]] (the segment's inside)."""
    @jit_internal
    def g(t, a, p, out):
        f(min(max(t, p[at]), p[at + 1]), a, p, out)

    return g


@functools.cache
def reset(at: int):
    """``reset(p)``: the clamp open (-inf, inf), as at the start of every point."""
    @jit_into_caller
    def r(p):
        p[at] = -math.inf
        p[at + 1] = math.inf

    return r


@jit_into_caller
def no_reset(p):
    pass


@jit_into_caller
def _below(x):
    return x - SIDE * abs(x)


@jit_into_caller
def _above(x):
    return x + SIDE * abs(x)


class Switched(methods.Method):
    """``base`` (dop853 or radau, with its options) integrating from switch to switch."""

    def __init__(self, base, nxt, check, clamp):
        self.base, self.switches = base, (nxt, check, clamp)
        self.name, self.code, self.jacobian = base.name, base.code, base.jacobian

    def event_solver(self, eq, event):
        return event_solver(self.base.event_solver(eq, event), *self.switches)

    def solver(self, eq):
        return solver(self.base.solver(eq), *self.switches)

    def trajectory_solver(self, eq):
        return trajectory_solver(self.base.trajectory_solver(eq), self.base.solver(eq), *self.switches)

    def workspace(self, n):
        return self.base.workspace(n)


def switched(method, nxt, check, clamp):
    """``method`` whose solvers end a step on each switch (auto: both of its methods)."""
    if method.restart is not None:
        return methods.Auto(switched(method.first, nxt, check, clamp), switched(method.restart, nxt, check, clamp))
    return Switched(method, nxt, check, clamp)


@functools.cache
def event_solver(solve, nxt, check, clamp):
    """``solve``'s signature and contract, integrating from switch to switch: the root of the first
    segment that has one; NO_EVENT only at t_max."""
    @jit_internal
    def run(t0, y, p, t_max, rtol, atol, h0, max_steps, work):
        c = check(p)
        if c != st.OK:
            return c, t0, 0, 0
        t = t0
        lo = -math.inf  # the start itself is not moved
        h = h0
        n_steps = 0
        n_rhs = 0
        while True:
            tb = nxt(t, p)
            if not tb > t:
                c, tr = st.NONFINITE, t
                break
            hi = min(tb, t_max)
            clamp(p, lo, _below(tb))
            c, tr, a, b_ = solve(t, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
            n_steps += a
            n_rhs += b_
            if c != st.NO_EVENT or hi >= t_max:
                break
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, tr, n_steps, n_rhs

    return run


@functools.cache
def solver(solve, nxt, check, clamp):
    """``solve``'s signature and contract (to t_end exactly), integrating from switch to switch."""
    @jit_internal
    def run(t0, y, p, t_end, rtol, atol, h0, max_steps, work):
        c = check(p)
        if c != st.OK:
            return c, 0, 0
        t = t0
        lo = -math.inf
        h = h0
        n_steps = 0
        n_rhs = 0
        while t < t_end:
            tb = nxt(t, p)
            if not tb > t:
                c = st.NONFINITE
                break
            hi = min(tb, t_end)
            clamp(p, lo, _below(tb))
            c, a, b_ = solve(t, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
            n_steps += a
            n_rhs += b_
            if c != st.OK:
                break
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, n_steps, n_rhs

    return run


@functools.cache
def trajectory_solver(traj, plain, nxt, check, clamp):
    """``traj``'s signature and contract (rows of out at t_eval; ends at t_eval[-1]), integrating
    from switch to switch: the rows of each segment from its own call of ``traj``, then ``plain`` on
    to the switch where the segment's last row lies before it."""
    @jit_internal
    def run(t0, y, p, t_eval, rtol, atol, h0, max_steps, work, out):
        out[:, :] = np.nan
        n = t_eval.size
        if n == 0:
            return st.OK, 0, 0
        c = check(p)
        if c != st.OK:
            return c, 0, 0
        t_end = t_eval[n - 1]
        t = t0
        lo = -math.inf
        h = h0
        k = 0
        n_steps = 0
        n_rhs = 0
        while True:
            tb = nxt(t, p)
            if not tb > t:
                c = st.NONFINITE
                break
            hi = min(tb, t_end)
            k1 = k
            while k1 < n and t_eval[k1] <= hi:
                k1 += 1
            clamp(p, lo, _below(tb))
            tl = t
            if k1 > k:
                c, a, b_ = traj(t, y, p, t_eval[k:k1], rtol, atol, h, max_steps - n_steps, work, out[k:k1])
                n_steps += a
                n_rhs += b_
                tl = max(t, t_eval[k1 - 1])
                h = 0.0
            if c == st.OK and tl < hi:
                c, a, b_ = plain(tl, y, p, hi, rtol, atol, h, max_steps - n_steps, work)
                n_steps += a
                n_rhs += b_
            if c != st.OK or hi >= t_end:
                break
            k = k1
            t = hi
            lo = _above(tb)
            h = 0.0
        clamp(p, -math.inf, math.inf)
        return c, n_steps, n_rhs

    return run
