"""Explicit symplectic fixed-step integrators for q'' = a(q) in numba.

For separable second-order systems whose force does not depend on the velocity
(the undamped Duffing oscillator x'' = -c1 x - c3 x^3, conservative linkages,
n-body problems), the velocity Verlet / Stoermer-Verlet method and its symmetric
compositions are explicit, symplectic and time-reversible. Backward error
analysis: the numerical solution is the exact flow of a modified Hamiltonian
H~ = H + O(h^p), so the energy error stays bounded, O(h^p), and oscillates
without drift over exponentially long times (e.g. 1e5 periods of the undamped
Duffing oscillator), while a non-symplectic method such as classical RK4 lets
it grow linearly in t. The phase (period) error still grows linearly, as for
any method, but like h^p.

Methods (``order``):

- 2: velocity Verlet, kick-drift-kick: v += h/2 a(q); q += h v; v += h/2 a(q).
  The force at the step end is reused at the next step start (first same as
  last), so one force evaluation per step.
- 4, 6, 8: symmetric compositions Phi_h = V_{w_s h} o ... o V_{w_1 h} of Verlet
  steps V (w_{s+1-i} = w_i, sum w_i = 1); adjacent half kicks of consecutive
  stages merge, so s force evaluations per step:

  - order 4, s = 5: Suzuki, "Fractal decomposition of exponential operators
    with applications to many-body theories and Monte Carlo simulations",
    Phys. Lett. A 146 (1990) 319-323: w1 = w2 = w4 = w5 = 1 / (4 - 4^(1/3)),
    w3 = 1 - 4 w1 (closed form, exact to round-off). At equal force count it was
    measured 2-4x more accurate on the Duffing oscillator than McLachlan's
    (1995) 5-stage method (w1 = 0.28) and 6-20x more than the 3-stage
    Yoshida / Forest-Ruth triple jump.
  - order 6, s = 7: Yoshida, "Construction of higher order symplectic
    integrators", Phys. Lett. A 150 (1990) 262-268, solution A; 20-digit values
    as tabulated by Leimkuhler & Reich, Simulating Hamiltonian Dynamics (2004),
    Table 6.2 (also Hairer, Lubich & Wanner, Geometric Numerical Integration,
    Sect. V.3.2).
  - order 8, s = 15: McLachlan, "On the numerical integration of ordinary
    differential equations by symmetric composition methods", SIAM J. Sci.
    Comput. 16 (1995) 151-168; 20-digit values from Leimkuhler & Reich,
    Table 6.2 (also HLW Sect. V.3.2). Measured on the Duffing oscillator
    (40 steps per period): 50-2000x more accurate than Yoshida's (1990)
    15-stage solutions A and D.

  ``tests/ode/test_symplectic.py`` checks sum w = 1, sum w^3 = 0 (and w^5, w^7 for
  orders 6, 8) and measures the convergence order on the Duffing oscillator.

Usage::

    @jit
    def accel(t, q, p, a):           # writes q'' into a (n components)
        a[0] = -p[0] * q[0] - p[1] * q[0] ** 3

    @jit
    def event(t, q, v, p):           # root wanted where this goes from > 0 to <= 0
        return q[0]

    solve = make_solver(accel, 6)
    work = workspace(1)              # once per block of points, reused
    status, n_steps, n_accel = solve(0.0, q, v, p, t_end, 1000, work)

    find = make_event_solver(accel, event, 6)
    status, t_root, n_steps, n_accel = find(0.0, q, v, p, h, t_max, max_steps, work)

Conventions (as :mod:`mechsweep.ode.dop853`):

- The factories are memoised (functools.cache) and return jitted closures over
  the user's jitted functions; callable from Python and from numba code,
  including ``prange`` loops with one ``work`` array per thread or block.
- ``work`` must be ``workspace(q.size)``; not checked (numba does no bounds
  checking). Its contents on return are scratch. The solve functions never
  allocate.
- Forward integration only (h > 0, t_end >= t0). The force is evaluated at the
  stage times t + c_k h (c_k the summed drift fractions); an autonomous system
  ignores t.
- Statuses are the ints of :mod:`mechsweep.status`; nothing raises inside numba.
- ``n_accel`` counts force evaluations honestly: 1 at the start, then s per
  step (the step-end force is reused, FSAL).

Event location: the event is tested at step ends. In the step where it goes
from > 0 to <= 0, the quintic Hermite interpolant of q through (q, v, a) at both
step ends (a = q'' from the force, so it costs nothing extra) is exact for
quintic polynomials, so it is accurate to O(h^6) locally (its derivative, used
for v, to O(h^5)); the root of event(t, q(t), v(t), p) on it is found by
Brent's method (as dop853). The event time therefore has error
O(h^min(order, 6)): the interpolant limits the 8th-order method. Two roots
within one step are missed.
"""
from __future__ import annotations

import functools

import numpy as np

from .._jit import jit, jit_noalloc
from ._common import ROOT_RTOL, _all_finite, _copy, make_brent
from ..status import MAX_STEPS, NO_EVENT, NONFINITE, OK

__all__ = [
    "ORDERS",
    "WEIGHTS",
    "WORK_ROWS",
    "make_event_solver",
    "make_solver",
    "workspace",
]

# ---------------------------------------------------------------------------
# Composition weights w_1..w_s of Verlet steps (symmetric, sum 1).
# ---------------------------------------------------------------------------


def _palindrome(half, centre):
    return np.array(list(half) + [centre] + list(reversed(half)), dtype=np.float64)


_SUZUKI = 1.0 / (4.0 - float(np.cbrt(4.0)))

WEIGHTS = {
    2: np.array([1.0]),
    # Suzuki (1990), 5 stages, order 4: 4 w^3 + (1 - 4 w)^3 = 0.
    4: _palindrome([_SUZUKI, _SUZUKI], 1.0 - 4.0 * _SUZUKI),
    # Yoshida (1990), solution A, 7 stages, order 6.
    6: _palindrome(
        [0.78451361047755726382, 0.23557321335935813368, -1.17767998417887100695],
        1.31518632068391121888,
    ),
    # McLachlan (1995), 15 stages, order 8 (Leimkuhler & Reich, Table 6.2).
    8: _palindrome(
        [
            0.74167036435061295345,
            -0.40910082580003159400,
            0.19075471029623837995,
            -0.57386247111608226666,
            0.29906418130365592384,
            0.33462491824529818378,
            0.31529309239676659663,
        ],
        -0.79688793935291635398,
    ),
}
ORDERS = tuple(sorted(WEIGHTS))


def _kick_drift(order):
    """Kick fractions (s + 1: merged half kicks), drift fractions (s) and the
    stage times c_k (fraction of h after drift k) of the composition."""
    w = WEIGHTS[order]
    s = w.size
    kick = np.empty(s + 1)
    kick[0] = 0.5 * w[0]
    for k in range(1, s):
        kick[k] = 0.5 * (w[k - 1] + w[k])
    kick[s] = 0.5 * w[s - 1]
    drift = w.copy()
    c = np.cumsum(w)
    c[-1] = 1.0  # the last force is at the step end exactly
    return kick, drift, c



# Rows of the workspace (each of length n).
ACC = 0  # a(q) at the current state (FSAL)
Q_OLD = 1  # state and force at the start of the last step (event solver)
V_OLD = 2
A_OLD = 3
Q_AT = 4  # interpolated state (event solver)
V_AT = 5
WORK_ROWS = 6


@jit
def workspace(n):
    """Scratch array for a state of n coordinates (n velocities): the current
    force, the previous step's state and force, the interpolated state.

    Jitted so that numba code (e.g. one workspace per block in a ``prange``)
    can allocate it too.
    """
    return np.zeros((WORK_ROWS, n), dtype=np.float64)


# ---------------------------------------------------------------------------
# Helpers that do not depend on the force.
# ---------------------------------------------------------------------------




@jit_noalloc
def _state_finite(q, v):
    """q and v finite. A non-finite force needs no check of its own: the step
    ends with a kick v += (w_s h / 2) a (w_s != 0), which carries it into v."""
    return _all_finite(q) and _all_finite(v)




@jit_noalloc
def _hermite(x, h, q0, v0, a0, q1, v1, a1, q_out, v_out):
    """Quintic Hermite interpolant at fraction x of a step of size h through
    (q, v = q', a = q'') at both ends: q_out = q(x), v_out = q'(x).

    Written as q0 + (q1 - q0) H(x) + h (...) + h^2 (...) so that it returns
    q0, q1 exactly at x = 0, 1 (up to round-off of the increment). q_out and
    v_out must not alias the inputs.
    """
    x2 = x * x
    x3 = x2 * x
    x4 = x3 * x
    x5 = x4 * x
    # Basis on [0, 1]: value at 1, slope at 0 / 1, curvature at 0 / 1.
    h_q1 = 10.0 * x3 - 15.0 * x4 + 6.0 * x5
    h_v0 = x - 6.0 * x3 + 8.0 * x4 - 3.0 * x5
    h_v1 = -4.0 * x3 + 7.0 * x4 - 3.0 * x5
    h_a0 = 0.5 * x2 - 1.5 * x3 + 1.5 * x4 - 0.5 * x5
    h_a1 = 0.5 * x3 - x4 + 0.5 * x5
    # Their derivatives d/dx.
    d_q1 = 30.0 * x2 - 60.0 * x3 + 30.0 * x4
    d_v0 = 1.0 - 18.0 * x2 + 32.0 * x3 - 15.0 * x4
    d_v1 = -12.0 * x2 + 28.0 * x3 - 15.0 * x4
    d_a0 = x - 4.5 * x2 + 6.0 * x3 - 2.5 * x4
    d_a1 = 1.5 * x2 - 4.0 * x3 + 2.5 * x4
    hh = h * h
    for i in range(q0.size):
        dq = q1[i] - q0[i]
        q_out[i] = q0[i] + (
            dq * h_q1 + h * (v0[i] * h_v0 + v1[i] * h_v1) + hh * (a0[i] * h_a0 + a1[i] * h_a1)
        )
        v_out[i] = (
            dq * d_q1 / h + v0[i] * d_v0 + v1[i] * d_v1 + h * (a0[i] * d_a0 + a1[i] * d_a1)
        )


# ---------------------------------------------------------------------------
# Factories of force-dependent pieces (memoised: one compiled copy per accel).
# ---------------------------------------------------------------------------


def _check_order(order):
    if order not in WEIGHTS:
        raise ValueError(f"order must be one of {ORDERS}, not {order!r}")


@functools.cache
def _make_step(accel, order):
    _check_order(order)
    kick, drift, c = _kick_drift(order)
    n_stages = drift.size

    @jit_noalloc
    def step(t, q, v, h, p, a):
        """One step of size h from (t, q, v); a = accel(t, q) on entry and
        accel(t + h, q_new) on return. Costs n_stages force evaluations."""
        n = q.size
        for k in range(n_stages):
            b = kick[k] * h
            for i in range(n):
                v[i] += b * a[i]
            d = drift[k] * h
            for i in range(n):
                q[i] += d * v[i]
            accel(t + c[k] * h, q, p, a)
        b = kick[n_stages] * h
        for i in range(n):
            v[i] += b * a[i]

    return step, n_stages


@functools.cache
def _make_root_locator(event):
    @jit_noalloc
    def event_on_interpolant(t, ctx):
        """event at t on the quintic Hermite interpolant of the last step (state into Q_AT, V_AT)."""
        t_old, h, q, v, p, work = ctx
        q_at = work[Q_AT]
        v_at = work[V_AT]
        _hermite((t - t_old) / h, h, work[Q_OLD], work[V_OLD], work[A_OLD],
                 q, v, work[ACC], q_at, v_at)
        return event(t, q_at, v_at, p)

    brent = make_brent(event_on_interpolant)

    @jit_noalloc
    def locate_root(t_old, h, g_old, t_new, g_new, q, v, p, work):
        """Root of event(t, interpolant(t)) in [t_old, t_new] where g_old > 0 >= g_new."""
        return brent(t_old, g_old, t_new, g_new, ROOT_RTOL * abs(h), (t_old, h, q, v, p, work))

    return event_on_interpolant, locate_root


# ---------------------------------------------------------------------------
# Public factories.
# ---------------------------------------------------------------------------


@functools.cache
def make_solver(accel, order):
    """Jitted ``solve(t0, q, v, p, t_end, n_steps, work) -> (status, n_steps_done, n_accel)``.

    n_steps fixed steps of h = (t_end - t0) / n_steps of the method of the given
    order (2, 4, 6, 8), q and v in place; step k ends at t0 + k h exactly.
    n_steps <= 0 takes no step and evaluates nothing: (OK, 0, 0).
    NONFINITE if the initial state or force is not finite (0 steps), or as soon
    as a step produces a non-finite q, v or force: it stops there, q and v hold
    that state, n_steps_done counts that step.
    n_accel = 1 + s n_steps_done (s = 1, 5, 7, 15 forces per step).
    """
    step, n_stages = _make_step(accel, order)

    @jit_noalloc
    def solve(t0, q, v, p, t_end, n_steps, work):
        if n_steps <= 0:
            return OK, 0, 0
        a = work[ACC]
        accel(t0, q, p, a)
        n_accel = 1
        if not (_state_finite(q, v) and _all_finite(a)):
            return NONFINITE, 0, n_accel
        h = (t_end - t0) / n_steps
        for k in range(n_steps):
            step(t0 + k * h, q, v, h, p, a)
            n_accel += n_stages
            if not _state_finite(q, v):
                return NONFINITE, k + 1, n_accel
        return OK, n_steps, n_accel

    return solve


@functools.cache
def make_event_solver(accel, event, order):
    """Jitted ``solve(t0, q, v, p, h, t_max, max_steps, work) -> (status, t, n_steps, n_accel)``.

    Fixed steps of size h (step k ends at t0 + k h; the last one is shortened
    to end at t_max) until event(t, q, v, p) goes from > 0 at one step end to
    <= 0 at the next; then the root is located on the quintic Hermite
    interpolant of that step (no extra force evaluation) and (OK, t_root, ...)
    returned with the interpolated q, v at t_root in q, v.

    Otherwise: (NO_EVENT, t_max, ...) with the state at t_max;
    (MAX_STEPS, t, ...) after max_steps steps without event, state at t;
    (NONFINITE, t, ...) if the initial state or force is not finite, or a step
    produced a non-finite q, v or force: q, v then hold the last finite state
    at t (n_steps counts the failed step). h <= 0 or t_max <= t0 takes no step:
    (NO_EVENT, t0, 0, 1).
    n_accel = 1 + s n_steps.
    """
    step, n_stages = _make_step(accel, order)
    event_on_interpolant, locate_root = _make_root_locator(event)

    @jit_noalloc
    def solve(t0, q, v, p, h, t_max, max_steps, work):
        a = work[ACC]
        q_old = work[Q_OLD]
        v_old = work[V_OLD]
        a_old = work[A_OLD]
        accel(t0, q, p, a)
        n_accel = 1
        n_steps = 0
        t = t0
        if not (_state_finite(q, v) and _all_finite(a)):
            return NONFINITE, t, n_steps, n_accel
        g_old = event(t, q, v, p)
        if not h > 0.0:
            return NO_EVENT, t, n_steps, n_accel
        while t < t_max:
            if n_steps >= max_steps:
                return MAX_STEPS, t, n_steps, n_accel
            t_new = min(t0 + (n_steps + 1) * h, t_max)
            h_step = t_new - t
            _copy(q, q_old)
            _copy(v, v_old)
            _copy(a, a_old)
            step(t, q, v, h_step, p, a)
            n_steps += 1
            n_accel += n_stages
            if not _state_finite(q, v):
                _copy(q_old, q)
                _copy(v_old, v)
                _copy(a_old, a)
                return NONFINITE, t, n_steps, n_accel
            g_new = event(t_new, q, v, p)
            if g_old > 0.0 and g_new <= 0.0:
                t_root = locate_root(t, h_step, g_old, t_new, g_new, q, v, p, work)
                if t_root != t_new:
                    event_on_interpolant(t_root, (t, h_step, q, v, p, work))
                    _copy(work[Q_AT], q)
                    _copy(work[V_AT], v)
                return OK, t_root, n_steps, n_accel
            t = t_new
            g_old = g_new
        return NO_EVENT, t, n_steps, n_accel

    return solve
