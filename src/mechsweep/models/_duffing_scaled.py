"""The two-term Duffing oscillator's scaled quarter-period integration as it was before the
built-in Duffing moved onto the model layer: the parameter layout p = (a, b, c, ., ., ., level,
direction), one event solver per method and the compile-time method switch (``make_quarter_period``).

Kept for what is not on the layer yet: models/torsional_circuit.py (its two-term period and its
exact-moment period use these kernels) and the benches' reference integrations
(bench/workprecision.py, bench/period_error.py). models/duffing.py itself is a declaration on the
layer and uses none of this (its formulas are imported from there, not the other way round).
"""
from __future__ import annotations

import math

import numpy as np

from .. import status as st
from .._jit import compile_time_switch, jit, jit_noalloc
from ..ode import AUTO, DOP853, RADAU, SYMPLECTIC, dop853, radau, symplectic
from .duffing import (K_OMEGA2, K_Q, SADDLE_DELTA, SYMPLECTIC_ORDER, T_MAX_PERIODS, UNIT_ROUNDOFF,  # noqa: F401
                      a_max_closed_form, classify, period_closed_form, period_condition, symplectic_step,
                      v_max_closed_form)

# Full output layout of these kernels (column k of the internal table of torsional_circuit).
OUTPUTS = ("period", "period_exact", "period_error", "v_max", "a_max", "kv", "ka", "epsilon")
K_PERIOD, K_PERIOD_EXACT, K_PERIOD_ERROR, K_VMAX, K_AMAX, K_KV, K_KA, K_EPS = range(8)


@jit
def fill_closed_forms(omega2, mu, A, want, row):
    """Write the algebraic outputs a caller wants into ``row`` (full layout)."""
    need_T = want[K_PERIOD_EXACT] or want[K_KV] or want[K_KA] or want[K_PERIOD_ERROR]
    T = period_closed_form(omega2, mu, A) if need_T else math.nan
    if want[K_PERIOD_EXACT]:
        row[K_PERIOD_EXACT] = T
    vmax = v_max_closed_form(omega2, mu, A) if (want[K_VMAX] or want[K_KV]) else math.nan
    amax = a_max_closed_form(omega2, mu, A) if (want[K_AMAX] or want[K_KA]) else math.nan
    if want[K_VMAX]:
        row[K_VMAX] = vmax
    if want[K_AMAX]:
        row[K_AMAX] = amax
    if want[K_KV]:
        row[K_KV] = vmax * T / A  # 2 pi for the linear oscillator
    if want[K_KA]:
        row[K_KA] = amax * T * T / A  # 4 pi^2 for the linear oscillator
    if want[K_EPS]:
        row[K_EPS] = mu * A * A / omega2


# --------------------------------------------------------------------------- integrated period
# One scaled oscillator serves both formulations (see integrate_period):
#   y'' = -(p0 y + p1 y^3 + p2 y^2),  event  p7 (y - p6) from > 0 to <= 0.
# The plain formulation is x = phi / A with p = (a, b, 0, ., ., ., 0, 1): x'' = -a x - b x^3, event
# x = 0 (the quadratic term and the level are exact zeros, so its results are those of the two-term
# rhs). The saddle formulation near the soft separatrix has p2 != 0, p6 = event level, p7 = -1.
# The event reads the same slots (6, 7) as torsional_circuit's, so that the two models' event
# functions are the same code: numba's disk cache was once seen (one cache folder, not reproduced)
# to link one model's event into the other's cached kernel, harmless only while they are equal.
N_P = 8


@jit
def _scaled_rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0] - p[1] * y[0] * y[0] * y[0] - p[2] * y[0] * y[0]


@jit
def _phi_event(t, y, p):
    return p[7] * (y[0] - p[6])


@jit_noalloc
def _scaled_jac(t, y, p, J):
    J[0, 0] = 0.0
    J[0, 1] = 1.0
    J[1, 0] = -p[0] - 3.0 * p[1] * y[0] * y[0] - 2.0 * p[2] * y[0]
    J[1, 1] = 0.0


@jit_noalloc
def _scaled_accel(t, q, p, a):
    a[0] = -p[0] * q[0] - p[1] * q[0] * q[0] * q[0] - p[2] * q[0] * q[0]


@jit_noalloc
def _q_event(t, q, v, p):
    return p[7] * (q[0] - p[6])


quarter_period_solver = dop853.make_event_solver(_scaled_rhs, _phi_event)
quarter_period_stiffness_test = dop853.make_event_solver(_scaled_rhs, _phi_event, stiffness_test=True)
quarter_period_radau = radau.make_event_solver(_scaled_rhs, _scaled_jac, _phi_event)
quarter_period_symplectic = symplectic.make_event_solver(_scaled_accel, _q_event, SYMPLECTIC_ORDER)


def make_quarter_period(name, explicit, explicit_stiffness_test, implicit, composed):
    """``name(method, y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v) -> (status, tau,
    n_steps, n_rhs)``: tau of the first zero of x from y = (1, 0) by solver.method, for an
    oscillator whose dop853, dop853-with-stiffness-test, radau and symplectic event solvers are
    given; only the method's solver is compiled into a kernel. auto: dop853 with the stiffness
    test, and a stiff point starts again with radau (costs add up)."""
    @jit_noalloc
    def by_dop853(y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v):
        return explicit(0.0, y, p, t_max, rtol, atol, 0.0, max_steps, work)

    @jit_noalloc
    def by_radau(y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v):
        return implicit(0.0, y, p, t_max, rtol, atol, 0.0, max_steps, rwork)

    @jit_noalloc
    def by_symplectic(y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v):
        q[0] = y[0]
        v[0] = y[1]
        code, tq, ns, nr = composed(0.0, q, v, p, symplectic_step(rtol), t_max, max_steps, swork)
        y[0] = q[0]
        y[1] = v[0]
        return code, tq, ns, nr

    @jit_noalloc
    def by_auto(y, p, t_max, rtol, atol, max_steps, work, rwork, swork, q, v):
        y0, y1 = y[0], y[1]
        code, tq, ns, nr = explicit_stiffness_test(0.0, y, p, t_max, rtol, atol, 0.0, max_steps, work)
        if code != st.STIFF:
            return code, tq, ns, nr
        y[0] = y0
        y[1] = y1
        code, tq, ns2, nr2 = implicit(0.0, y, p, t_max, rtol, atol, 0.0, max_steps, rwork)
        return code, tq, ns + ns2, nr + nr2

    return compile_time_switch(name, {DOP853: by_dop853, RADAU: by_radau, SYMPLECTIC: by_symplectic,
                                      AUTO: by_auto})


quarter_period = make_quarter_period("quarter_period", quarter_period_solver, quarter_period_stiffness_test,
                                     quarter_period_radau, quarter_period_symplectic)


@jit_noalloc
def integrate_period(method, omega2, mu, A, rtol, atol, max_steps, t_max_periods, y, p, work, rwork, swork, q, v,
                     k_omega2, k_q):
    """Integrated period of the two-term Duffing model. Returns (status, T, n_steps, n_rhs).
    k_omega2, k_q: sensitivities of omega^2 and mu A^2 to the caller's inputs (period_condition);
    ILL_CONDITIONED where the period's condition number times round-off exceeds rtol."""
    if not period_condition(omega2, mu, A, k_omega2, k_q) * UNIT_ROUNDOFF <= rtol:  # NaN-safe: a NaN bound flags
        return st.ILL_CONDITIONED, math.nan, 0, 0
    muA2 = mu * A * A
    w2 = omega2 + abs(muA2)
    w = math.sqrt(w2)
    delta = (omega2 + muA2) / w2
    if mu < 0.0 and delta < SADDLE_DELTA:
        bneg = -muA2 / w2  # -b > 0
        xs = math.sqrt(1.0 + delta / bneg)  # saddle, x_s^2 = a / -b with a = delta - b
        u0 = delta / (bneg * (xs + 1.0))  # x_s - 1
        p[0] = -2.0 * (delta + bneg)
        p[1] = -bneg * u0 * u0
        p[2] = 3.0 * bneg * xs * u0
        p[6] = xs / u0
        p[7] = -1.0
    else:
        p[0] = omega2 / w2
        p[1] = muA2 / w2
        p[2] = 0.0
        p[6] = 0.0
        p[7] = 1.0
    y[0] = 1.0
    y[1] = 0.0
    code, tau_q, ns, nr = quarter_period(method, y, p, t_max_periods * 2.0 * math.pi, rtol, atol, max_steps,
                                         work, rwork, swork, q, v)
    if code != st.OK:
        return code, math.nan, ns, nr
    return st.OK, 4.0 * tau_q / w, ns, nr


@jit
def workspaces():
    """Scratch of every method for one thread: (dop853, radau, symplectic, y, p, q, v)."""
    return (dop853.workspace(2), radau.workspace(2), symplectic.workspace(1), np.empty(2), np.empty(N_P),
            np.empty(1), np.empty(1))




def relative_error(value, reference):
    return np.abs(value - reference) / np.abs(reference)
