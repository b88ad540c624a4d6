"""Undamped Duffing oscillator phi'' + omega^2 phi + mu phi^3 = 0, phi(0) = A, phi'(0) = 0.

Source: Klyuchkovskyi, torsional oscillating circuits, equation (3); closed forms from
../shared/physics.md section 1 (amplitude-period relation and kinematic invariants).

Numerics: the period is integrated on the scaled equation x = phi / A, tau = w t with
w^2 = omega^2 + |mu| A^2, so that rtol/atol mean the same thing for A = 1e-8 rad and for
A = 10 rad:  x'' = -a x - b x^3,  a = omega^2 / w^2,  b = mu A^2 / w^2,  |a| + |b| = 1.
By symmetry of the motion the first zero of x is a quarter period: T = 4 tau_q / w.
Within 2e-3 of the soft separatrix the same quarter period is integrated in coordinates centred on
the saddle, and points whose period is too sensitive to the inputs for rtol are ILL_CONDITIONED
(see integrate_period).
"""
from __future__ import annotations

import math

import numpy as np

from .. import status as st
from .._jit import call_with_literal, compile_time_switch, jit, jit_noalloc, literally, pjit, prange
from ..ode import AUTO, DOP853, METHOD_CODES, RADAU, SYMPLECTIC, dop853, radau, symplectic
from ..special import ellipk
from ._spec import ModelSpec, Output, Param, Setting

# Integration horizon of the period event, in linearised periods 2 pi / w (w^2 = omega^2 + |mu| A^2):
# near the soft separatrix T grows like log(1 / distance), so 100 is reached only ~e^-200 from it.
T_MAX_PERIODS = Setting("t_max_periods", 100.0, "1", "integration horizon in linearised periods", 1e-3, 1e9)

# Full output layout of this model's kernels (column k of the internal table).
OUTPUTS = ("period", "period_exact", "period_error", "v_max", "a_max", "kv", "ka", "epsilon")
K_PERIOD, K_PERIOD_EXACT, K_PERIOD_ERROR, K_VMAX, K_AMAX, K_KV, K_KA, K_EPS = range(8)

# sum over the inputs (omega, mu, A) of |d ln omega^2 / d ln p| and |d ln(mu A^2) / d ln p|
K_OMEGA2 = 2.0
K_Q = 3.0

BLOCK = 16  # points per scratch-space allocation inside the parallel loop

# method "symplectic": McLachlan's 8th-order composition with ceil(SYMPLECTIC_C rtol^(-1/8)) fixed
# steps per linearised period 2 pi of the scaled equation
SYMPLECTIC_ORDER = 8
SYMPLECTIC_C = 3.0


# --------------------------------------------------------------------------- closed forms
@jit
def classify(omega2, mu, A):
    """Status of a Duffing point before any computation (shared by every stage)."""
    if A == 0.0:
        return st.NO_MOTION
    if not omega2 > 0.0:
        return st.INFEASIBLE  # no stable equilibrium at phi = 0 to oscillate about
    if not omega2 + mu * A * A > 0.0:
        return st.NOT_OSCILLATORY  # at or beyond the soft separatrix |mu| A^2 = omega^2
    return st.OK


@jit
def period_closed_form(omega2, mu, A):
    """T = 4 K(m) / sqrt(omega^2 + mu A^2), m = mu A^2 / (2 (omega^2 + mu A^2)).

    One formula for both signs of mu (K accepts m < 0). physics.md section 1.
    """
    s = omega2 + mu * A * A
    return 4.0 * ellipk(mu * A * A / (2.0 * s)) / math.sqrt(s)


@jit
def v_max_closed_form(omega2, mu, A):
    """Energy: v_max^2 = omega^2 A^2 + mu A^4 / 2 (velocity at phi = 0), both signs of mu."""
    return A * math.sqrt(omega2 + 0.5 * mu * A * A)


@jit
def a_max_closed_form(omega2, mu, A):
    """max |phi''| over the stroke; for omega^2/3 < |mu| A^2 < omega^2 (soft) it lies inside."""
    if mu >= 0.0 or 3.0 * (-mu) * A * A <= omega2:
        return A * (omega2 + mu * A * A)
    return 2.0 * omega2 * math.sqrt(omega2) / (3.0 * math.sqrt(-3.0 * mu))


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


@jit_noalloc
def symplectic_step(rtol):
    """Fixed step (scaled time) of the symplectic method for a tolerance: SYMPLECTIC_STEPS(rtol)
    steps per linearised period 2 pi, calibrated so that the period error stays below rtol over
    epsilon in [-0.99, 1e4] (measured by `mechsweep bench workprecision duffing`)."""
    return 2.0 * math.pi / math.ceil(SYMPLECTIC_C * rtol ** (-1.0 / SYMPLECTIC_ORDER))


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


# Near the soft separatrix (delta = (omega^2 + mu A^2) / w^2 -> 0) the motion starts next to the
# saddle x_s = sqrt(a / -b) = 1 + O(delta) and lingers there for a time ~ log(1 / delta). In x = phi/A
# the distance to the saddle, u = x_s - x ~ delta / 2, is carried as a difference of two numbers
# near 1: every local error (rtol |x|) and every rounding of x is an error of u of relative size
# rtol / delta, and the period's error grew like (2e-3 / delta)^0.85 times rtol (measured; the old
# tightening of rtol by that fitted factor missed points by up to 2.85x). Below SADDLE_DELTA the
# period is therefore integrated in saddle coordinates z = (x_s - x) / u0, u0 = x_s - 1:
#     z'' = 2 a z + 3 b x_s u0 z^2 - b u0^2 z^3,  z(0) = 1, z'(0) = 0,  event z = x_s / u0 (x = 0),
# exact (a x_s + b x_s^3 = 0 is used analytically, no constant term is left to cancel); u0 and x_s
# are formed from delta without cancellation, so the tolerance is relative to the distance from the
# saddle and the integration error no longer grows as delta -> 0.
# What cannot be helped is the data: s = omega^2 + mu A^2 is a difference, and its inputs are known
# to a unit of round-off u at best. The condition number of the period with respect to the inputs,
# kappa = sum_p |d ln T / d ln p|, follows from d ln T = -S (omega^2/s) d ln omega^2
# + (S omega^2/s - 1/2) d ln(mu A^2), S = -d ln T / d ln s at fixed mu A^2 (period_log_sensitivity);
# it grows like 1 / ((1 + epsilon) ln(1 / (1 + epsilon))). Where kappa u > rtol, a perturbation of the
# inputs by one unit of round-off moves the period by more than rtol: no double-precision computation
# from these inputs can promise rtol, and the point is ILL_CONDITIONED (the closed form is still
# given; it carries the same sensitivity). The test depends on rtol, not on a fixed distance.
SADDLE_DELTA = 2e-3
UNIT_ROUNDOFF = 2.0 ** -53


@jit_noalloc
def period_log_sensitivity(m):
    """S = -d ln T / d ln s of T = 4 K(m) / sqrt(s), m = mu A^2 / (2 s), s = omega^2 + mu A^2, for
    m <= 0 (soft springs): S = E(m') / (2 K(m')) with m' = m / (m - 1) in [0, 1) (Jacobi's imaginary
    modulus transformation), from the AGM: E / K = 1 - sum_n 2^(n-1) c_n^2, c_0^2 = m'. 1/2 for the
    linear spring, ~1 / (2 ln(4 sqrt(1 - m))) towards the separatrix (m -> -inf)."""
    b = 1.0 / math.sqrt(1.0 - m)  # sqrt(1 - m'), free of the rounding of m' near 1
    a = 1.0
    acc = 0.5 * (1.0 - b * b)  # 2^-1 c_0^2
    pw = 0.5
    for _ in range(64):
        c = 0.5 * (a - b)
        pw *= 2.0
        acc += pw * c * c
        if abs(a - b) <= 2.220446049250313e-16 * a:
            break
        a, b = 0.5 * (a + b), math.sqrt(a * b)
    return 0.5 * (1.0 - acc)


@jit_noalloc
def period_condition(omega2, mu, A, k_omega2, k_q):
    """Condition number kappa of the period with respect to the model's inputs p, bounded by
    S (omega^2/s) k_omega2 + |S omega^2/s - 1/2| k_q, where k_omega2 = sum_p |d ln omega^2 / d ln p|
    and k_q = sum_p |d ln(mu A^2) / d ln p| (duffing: 2 and 3). Soft springs only (0 for mu >= 0:
    there s >= omega^2 and kappa stays of order k_omega2 + k_q; no separatrix to approach)."""
    if mu >= 0.0:
        return 0.0
    q = mu * A * A
    s = omega2 + q
    f = period_log_sensitivity(q / (2.0 * s)) * omega2 / s
    return f * k_omega2 + abs(f - 0.5) * k_q


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


# --------------------------------------------------------------------------- chunk kernels
@pjit
def algebraic_kernel(omega, mu, A, want, table, status):
    for i in prange(omega.shape[0]):
        code = classify(omega[i] * omega[i], mu[i], A[i])
        if code != st.OK:
            status[i] = code
            continue
        fill_closed_forms(omega[i] * omega[i], mu[i], A[i], want, table[i])


@pjit
def period_kernel(method, omega, mu, A, rtol, atol, max_steps, t_max_periods, table, status, n_steps, n_rhs):
    literally(method)  # one cached kernel per method
    n = omega.shape[0]
    n_blocks = (n + BLOCK - 1) // BLOCK
    for b in prange(n_blocks):
        work, rwork, swork, y, p, q, v = workspaces()
        for i in range(b, n, n_blocks):  # strided: prange splits blocks statically, and cost varies along the grid
            if status[i] != st.OK:
                continue
            code = classify(omega[i] * omega[i], mu[i], A[i])
            if code != st.OK:
                status[i] = code
                continue
            code, T, ns, nr = integrate_period(
                method, omega[i] * omega[i], mu[i], A[i], rtol, atol, max_steps, t_max_periods, y, p, work,
                rwork, swork, q, v, K_OMEGA2, K_Q,
            )
            n_steps[i] += ns
            n_rhs[i] += nr
            status[i] = code
            table[i, K_PERIOD] = T


# --------------------------------------------------------------------------- engine entry point
def evaluate(P, wanted, solver, out, status, n_steps, n_rhs):
    omega, mu, A = (np.ascontiguousarray(P[:, j]) for j in range(3))
    table = np.full((P.shape[0], len(OUTPUTS)), np.nan)
    want = np.array([name in wanted for name in OUTPUTS])
    if want[[K_PERIOD_EXACT, K_VMAX, K_AMAX, K_KV, K_KA, K_EPS]].any():
        algebraic_kernel(omega, mu, A, want, table, status)
    if want[K_PERIOD]:
        call_with_literal(
            period_kernel, METHOD_CODES[solver.method], omega, mu, A, solver.rtol, solver.atol, solver.max_steps,
            solver.settings["t_max_periods"], table, status, n_steps, n_rhs,
        )
    if want[K_PERIOD_ERROR]:
        table[:, K_PERIOD_ERROR] = relative_error(table[:, K_PERIOD], table[:, K_PERIOD_EXACT])
    for name in wanted:
        out[name][:] = table[:, OUTPUTS.index(name)]


def relative_error(value, reference):
    return np.abs(value - reference) / np.abs(reference)


SPEC = ModelSpec(
    name="duffing",
    description="Undamped Duffing oscillator phi'' + omega^2 phi + mu phi^3 = 0 released from rest at phi = A",
    source="Klyuchkovskyi, torsional oscillating circuits, eq. (3); physics.md section 1",
    params=(
        Param("omega", "ω", "rad/s", "linear natural frequency", lo=0.0, lo_open=True),
        Param("mu", "μ", "1/(rad^2 s^2)", "cubic stiffness coefficient (>0 hard, <0 soft)"),
        Param("A", "A", "rad", "amplitude, phi(0) = A, phi'(0) = 0", lo=0.0),
    ),
    outputs=(
        Output("period", "T", "s", "period of the free oscillation", integrated=True),
        Output("period_exact", "T_exact", "s", "period (elliptic closed form)"),
        Output("period_error", "|T - T_exact| / T_exact", "1", "relative error of the integrated period",
               needs=("period", "period_exact")),
        Output("v_max", "v_max", "rad/s", "maximum angular velocity"),
        Output("a_max", "a_max", "rad/s^2", "maximum angular acceleration"),
        Output("kv", "k_v = v_max T / A", "1", "velocity coefficient v_max T / A (2 pi when linear)"),
        Output("ka", "k_a = a_max T^2 / A", "1", "acceleration coefficient a_max T^2 / A (4 pi^2 when linear)"),
        Output("epsilon", "ε = μ A² / ω²", "1", "nonlinearity parameter mu A^2 / omega^2"),
    ),
    evaluate=evaluate,
    settings=(T_MAX_PERIODS,),
    methods=("dop853", "radau", "symplectic", "auto"),
    statuses=(st.INFEASIBLE, st.NOT_OSCILLATORY, st.NO_MOTION, *st.INTEGRATION_FAILURES),
    status_notes={
        st.INFEASIBLE: "omega^2 <= 0: no stable equilibrium at phi = 0 to oscillate about",
        st.NOT_OSCILLATORY: "at or beyond the soft separatrix |mu| A^2 >= omega^2 (mu < 0)",
        st.NO_MOTION: "A = 0: no motion, ratios to A undefined",
        st.NO_EVENT: "the quarter-period crossing did not happen within the horizon",
        st.ILL_CONDITIONED: "the period below 1 + epsilon = 6.8e-7 at the default rtol (next to the soft "
                            "separatrix); the closed form period_exact is still given",
    },
)
