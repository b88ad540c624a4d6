"""Tests of the symplectic fixed-step integrators (mechsweep.ode.symplectic).

One force and one event function for every test on purpose: each (function,
order, solver kind) is a separate JIT compilation. Reference: the undamped
Duffing oscillator x'' = -a x - b x^3 from x(0) = 1, x'(0) = 0, whose period is
known in closed form, T = 4 K(m) / sqrt(a + b), m = b / (2 (a + b)); after
exactly one period the state is (1, 0) again, and the first zero of x is at T/4.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from mechsweep import status
from mechsweep._jit import jit, pjit, prange
from mechsweep.ode import symplectic
from mechsweep.ode.symplectic import (
    ORDERS,
    WEIGHTS,
    WORK_ROWS,
    make_event_solver,
    make_solver,
    workspace,
)
from mechsweep.special import ellipk

# A NumbaWarning (e.g. "cannot cache") fails the test that triggers it.
pytestmark = pytest.mark.filterwarnings("error::numba.NumbaWarning")

INF = math.inf
STAGES = {2: 1, 4: 5, 6: 7, 8: 15}


@jit
def duffing(t, q, p, a):
    """x_i'' = -p0 x_i - p1 x_i^3 for every component; the force is NaN once t > p[2]."""
    for i in range(q.size):
        a[i] = -p[0] * q[i] - p[1] * q[i] * q[i] * q[i]
    if t > p[2]:
        a[0] = math.nan


@jit
def level_crossing(t, q, v, p):
    """q[0] comes down to the level p[3]."""
    return q[0] - p[3]


def params(a, b, t_nan=INF, level=0.0):
    return np.array([a, b, t_nan, level])


def period(a, b):
    return 4.0 * ellipk(b / (2.0 * (a + b))) / math.sqrt(a + b)


def energy(q, v, a, b):
    return 0.5 * v * v + 0.5 * a * q * q + 0.25 * b * q**4


def slope(h, err):
    return np.polyfit(np.log(h), np.log(err), 1)[0]


# --------------------------------------------------------------------------- coefficients


@pytest.mark.parametrize("order", ORDERS)
def test_weights_satisfy_the_necessary_order_conditions(order):
    w = WEIGHTS[order]
    assert w.size == STAGES[order]
    np.testing.assert_array_equal(w, w[::-1])  # symmetric: even order, time-reversible
    assert abs(w.sum() - 1.0) < 1e-15
    for k in range(3, order, 2):  # sum w^k = 0 for k = 3, 5, ..., order - 1
        assert abs(np.sum(w**k)) < 1e-14, k


def test_workspace_and_bad_order():
    assert workspace(3).shape == (WORK_ROWS, 3)
    with pytest.raises(ValueError):
        make_solver(duffing, 3)
    with pytest.raises(ValueError):
        make_event_solver(duffing, level_crossing, 5)


# --------------------------------------------------------------------------- convergence

# Steps per period over which the error is well above round-off (~1e-14) and in
# the asymptotic regime; measured, see the assertion on the smallest error.
STEP_COUNTS = {
    2: [20, 40, 80, 160, 320],
    4: [20, 40, 80, 160, 320],
    6: [10, 14, 20, 28, 40, 56, 80],
    8: [28, 40, 56, 80],  # coarser: slope ~8.5, h^10 term still visible; floor ~1e-15 from n ~ 160
}


@pytest.mark.parametrize("order", ORDERS)
def test_measured_order_over_one_period(order):
    a, b = 0.5, 0.5
    p = params(a, b)
    T = period(a, b)
    solve = make_solver(duffing, order)
    work = workspace(1)
    hs, errors = [], []
    for n in STEP_COUNTS[order]:
        q = np.array([1.0])
        v = np.array([0.0])
        code, n_done, n_accel = solve(0.0, q, v, p, T, n, work)
        assert code == status.OK
        assert n_done == n
        assert n_accel == 1 + STAGES[order] * n  # FSAL: s forces per step
        hs.append(T / n)
        errors.append(math.hypot(q[0] - 1.0, v[0]))
    errors = np.array(errors)
    assert errors.min() > 1e-13  # the fit is not polluted by round-off (floor ~1e-15)
    assert abs(slope(hs, errors) - order) < 0.3, errors
    # Every local slope too: a weight perturbed by 1e-5 (sum w^3 ~ 7e-5 instead of 0)
    # leaves the fitted slope of order 6 near 6 but flattens the last local slope to ~1.
    local = np.diff(np.log(errors)) / np.diff(np.log(hs))
    assert np.all(np.abs(local - order) < 0.5), local


def test_zero_steps_and_exact_step_end():
    solve = make_solver(duffing, 6)
    q = np.array([1.0])
    v = np.array([0.0])
    assert solve(0.0, q, v, params(0.5, 0.5), 1.0, 0, workspace(1)) == (status.OK, 0, 0)
    assert q[0] == 1.0 and v[0] == 0.0


# --------------------------------------------------------------------------- long-time energy


def _energy_samples(order, a, b, n_periods, steps_per_period, chunk):
    """Relative energy error sampled every ``chunk`` steps (chunk prime to
    steps_per_period, so the samples wander through all phases)."""
    p = params(a, b)
    h = period(a, b) / steps_per_period
    solve = make_solver(duffing, order)
    work = workspace(1)
    q = np.array([1.0])
    v = np.array([0.0])
    e0 = energy(1.0, 0.0, a, b)
    n_samples = n_periods * steps_per_period // chunk
    out = np.empty(n_samples)
    t = 0.0
    for k in range(n_samples):
        code, _, _ = solve(t, q, v, p, t + chunk * h, chunk, work)
        assert code == status.OK
        t += chunk * h
        out[k] = abs(energy(q[0], v[0], a, b) - e0) / e0
    return out


@jit
def rk4_energy_errors(a, b, h, n_samples, chunk):
    """Classical RK4 on the same oscillator (non-symplectic), same sampling."""
    x, y = 1.0, 0.0
    e0 = 0.5 * a + 0.25 * b
    out = np.empty(n_samples)
    for k in range(n_samples):
        for _ in range(chunk):
            k1x, k1y = y, -a * x - b * x**3
            x2, y2 = x + 0.5 * h * k1x, y + 0.5 * h * k1y
            k2x, k2y = y2, -a * x2 - b * x2**3
            x3, y3 = x + 0.5 * h * k2x, y + 0.5 * h * k2y
            k3x, k3y = y3, -a * x3 - b * x3**3
            x4, y4 = x + h * k3x, y + h * k3y
            k4x, k4y = y4, -a * x4 - b * x4**3
            x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x)
            y += h / 6.0 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y)
        out[k] = abs(0.5 * y * y + 0.5 * a * x * x + 0.25 * b * x**4 - e0) / e0
    return out


def _first_last_tenth(errors):
    m = errors.size // 10
    return errors[:m].max(), errors[-m:].max()


@pytest.mark.parametrize("order", [4, 6])
def test_energy_error_stays_bounded_over_1e5_periods(order):
    # 20 steps per period: energy error ~2e-4 (order 4) / 1e-5 (order 6), far
    # above the accumulated round-off, so boundedness is not trivially true.
    errors = _energy_samples(order, 0.5, 0.5, 100_000, 20, 397)
    first, last = _first_last_tenth(errors)
    assert 1e-12 < first < 1e-3
    assert last <= 2.0 * first, (first, last)


def test_rk4_energy_error_grows_linearly():
    a, b = 0.5, 0.5
    steps, chunk, n_periods = 40, 97, 10_000
    errors = rk4_energy_errors(a, b, period(a, b) / steps, n_periods * steps // chunk, chunk)
    first, last = _first_last_tenth(errors)
    assert last > 5.0 * first, (first, last)  # ~10x for linear growth over 10x the time
    assert last < 0.5  # still in the linear (not saturated) regime


# --------------------------------------------------------------------------- reversibility


@pytest.mark.parametrize("order", ORDERS)
def test_time_reversible(order):
    p = params(0.5, 0.5)
    solve = make_solver(duffing, order)
    work = workspace(2)
    q0 = np.array([1.0, -0.3])
    v0 = np.array([0.0, 0.7])
    q, v = q0.copy(), v0.copy()
    # 500 steps there and back: round-off alone leaves ~1e-14 (~1e-13 after 1000).
    assert solve(0.0, q, v, p, 50.0, 500, work)[0] == status.OK
    assert np.max(np.abs(q - q0)) > 0.1  # it went somewhere
    v *= -1.0
    assert solve(0.0, q, v, p, 50.0, 500, work)[0] == status.OK
    v *= -1.0
    assert np.max(np.abs(q - q0)) < 2e-13
    assert np.max(np.abs(v - v0)) < 2e-13


# --------------------------------------------------------------------------- events

CASES = [(1.0, 0.0), (0.5, 0.5), (0.02, 0.98), (0.7, -0.3)]  # linear, hard, very hard, soft


def _quarter_period_errors(order, a, b, counts, level=0.0, t_exact=None):
    """Relative error of the event time with h = t_exact / (n + 1/2): the root
    in the middle of a step, where the interpolant matters most."""
    p = params(a, b, level=level)
    if t_exact is None:
        t_exact = period(a, b) / 4.0
    solve = make_event_solver(duffing, level_crossing, order)
    work = workspace(1)
    hs, errors = [], []
    for n in counts:
        h = t_exact / (n + 0.5)
        q = np.array([1.0])
        v = np.array([0.0])
        code, t_root, n_steps, n_accel = solve(0.0, q, v, p, h, 100.0, 10_000, work)
        assert code == status.OK
        assert n_steps == n + 1
        assert n_accel == 1 + STAGES[order] * n_steps
        assert abs(q[0] - level) < 1e-15 + 1e-3 * h**2  # the returned state is at the root
        v_exact = -math.sqrt(2.0 * (energy(1.0, 0.0, a, b) - energy(level, 0.0, a, b)))
        assert abs(v[0] - v_exact) < 10.0 * h ** min(order, 5)
        hs.append(h)
        errors.append(abs(t_root - t_exact) / t_exact)
    return np.array(hs), np.array(errors)


EVENT_COUNTS = {2: [4, 8, 16, 32, 64], 4: [4, 8, 16, 32, 64], 6: [4, 8, 16, 32], 8: [2, 4, 8]}


@pytest.mark.parametrize("order", ORDERS)
@pytest.mark.parametrize("a, b", CASES)
def test_quarter_period_matches_closed_form(order, a, b):
    hs, errors = _quarter_period_errors(order, a, b, EVENT_COUNTS[order])
    assert errors.min() > 1e-13
    assert errors[-1] < {2: 1e-3, 4: 1e-7, 6: 1e-8, 8: 1e-8}[order]
    measured = slope(hs, errors)
    if order <= 6:
        assert abs(measured - order) < 0.3, errors
    else:
        # The O(h^6) interpolant limits the event to order 6 in general; at the
        # zero of this odd oscillator x^(6) = 0, so here it is better still.
        assert measured > 5.7, errors


def test_level_crossing_is_limited_by_the_quintic_interpolant():
    # Linear oscillator, x = cos t reaches 1/2 at pi/3 (x^(6) != 0 there): the
    # 8th-order steps are more accurate than the interpolant, so the event
    # converges at order 6 (at the step ends the error is ~h^8).
    hs, errors = _quarter_period_errors(8, 1.0, 0.0, [4, 8, 16], level=0.5, t_exact=math.pi / 3)
    assert errors.min() > 1e-13
    assert abs(slope(hs, errors) - 6.0) < 0.4, errors


def test_hermite_interpolant_is_exact_for_quintics():
    rng = np.random.default_rng(7)
    poly = np.polynomial.Polynomial(rng.normal(size=(6,)))
    d1, d2 = poly.deriv(1), poly.deriv(2)
    t0, h = 0.3, 0.7
    t1 = t0 + h
    q_out, v_out = np.empty(1), np.empty(1)
    for x in (0.0, 0.1, 0.5, 0.77, 1.0):
        symplectic._hermite(
            x, h, np.array([poly(t0)]), np.array([d1(t0)]), np.array([d2(t0)]),
            np.array([poly(t1)]), np.array([d1(t1)]), np.array([d2(t1)]), q_out, v_out,
        )
        assert abs(q_out[0] - poly(t0 + x * h)) < 1e-14
        assert abs(v_out[0] - d1(t0 + x * h)) < 1e-13


# --------------------------------------------------------------------------- statuses


def test_nonfinite_force():
    solve = make_solver(duffing, 6)
    work = workspace(1)
    q, v = np.array([1.0]), np.array([0.0])
    code, n_done, n_accel = solve(0.0, q, v, params(0.5, 0.5, t_nan=1.0), 3.0, 30, work)
    assert code == status.NONFINITE
    assert n_done in (10, 11)  # the step whose stage times pass t = 1
    assert n_accel == 1 + 7 * n_done
    assert not (np.isfinite(q[0]) and np.isfinite(v[0]))
    # Non-finite at the start: no step.
    q, v = np.array([1.0]), np.array([0.0])
    assert solve(0.0, q, v, params(math.nan, 0.5), 3.0, 30, work) == (status.NONFINITE, 0, 1)

    find = make_event_solver(duffing, level_crossing, 6)
    q, v = np.array([1.0]), np.array([0.0])
    code, t, n_steps, n_accel = find(0.0, q, v, params(0.5, 0.5, t_nan=1.0, level=-2.0), 0.1, 3.0, 100, work)
    assert code == status.NONFINITE
    assert abs(t - 0.1 * (n_steps - 1)) < 1e-12  # time of the last finite state...
    assert np.isfinite(q[0]) and np.isfinite(v[0])  # ...which is left in q, v
    assert 0.9 <= t <= 1.0 + 1e-12


def test_no_event_and_max_steps():
    find = make_event_solver(duffing, level_crossing, 4)
    work = workspace(1)
    a, b = 0.5, 0.5
    p = params(a, b, level=-2.0)  # x never reaches -2
    q, v = np.array([1.0]), np.array([0.0])
    code, t, n_steps, n_accel = find(0.0, q, v, p, 0.1, 10.05, 1000, work)
    assert code == status.NO_EVENT
    assert t == 10.05  # the last step is shortened to end at t_max
    assert n_steps == 101
    assert n_accel == 1 + 5 * 101
    assert abs(energy(q[0], v[0], a, b) - energy(1.0, 0.0, a, b)) < 1e-6

    q, v = np.array([1.0]), np.array([0.0])
    code, t, n_steps, n_accel = find(0.0, q, v, p, 0.1, 10.05, 7, work)
    assert code == status.MAX_STEPS
    assert n_steps == 7
    assert abs(t - 0.7) < 1e-15
    assert n_accel == 1 + 5 * 7

    # Event already <= 0 at t0: not a crossing from above, runs on to t_max.
    q, v = np.array([1.0]), np.array([0.0])
    code, t, _, _ = find(0.0, q, v, params(a, b, level=1.0), 0.1, 1.0, 1000, work)
    assert code == status.NO_EVENT and t == 1.0


# --------------------------------------------------------------------------- prange

BLOCK = 4
quarter_period_solver = make_event_solver(duffing, level_crossing, 6)


@pjit
def quarter_periods_kernel(a, b, h, out):
    """One workspace per block of points, strided points per block (as the models)."""
    n = a.size
    n_blocks = (n + BLOCK - 1) // BLOCK
    for blk in prange(n_blocks):
        work = workspace(1)
        q = np.empty(1)
        v = np.empty(1)
        p = np.empty(4)
        for i in range(blk, n, n_blocks):
            p[0] = a[i]
            p[1] = b[i]
            p[2] = np.inf
            p[3] = 0.0
            q[0] = 1.0
            v[0] = 0.0
            code, t_root, _, _ = quarter_period_solver(0.0, q, v, p, h, 100.0, 10_000, work)
            out[i] = t_root if code == status.OK else np.nan


def test_usable_in_prange_loop():
    rng = np.random.default_rng(3)
    a = rng.uniform(0.1, 1.0, 37)
    b = rng.uniform(-0.05, 1.0, 37)
    out = np.empty(37)
    quarter_periods_kernel(a, b, 0.05, out)
    work = workspace(1)
    for i in range(a.size):
        q, v = np.array([1.0]), np.array([0.0])
        code, t_root, _, _ = quarter_period_solver(0.0, q, v, params(a[i], b[i]), 0.05, 100.0, 10_000, work)
        assert code == status.OK
        assert out[i] == t_root  # bitwise: same code, same arithmetic
        assert abs(t_root - period(a[i], b[i]) / 4.0) < 1e-8
