"""Torsional circuit: coefficients against the series of the exact moment (sympy, exact
arithmetic), the exact-moment period against quadrature, the truncation error's order."""
import math

import mpmath as mp
import numpy as np
import pytest
import scipy.integrate as si
import sympy as sy

from mechsweep import status as st
from mechsweep.models import torsional_circuit as tc
from mechsweep.scene import Solver
from tests import evaluating

from .test_extreme_scenes import exact_moment_rhs, first_zero_crossing

PARAMS = [("tension", 0.8, 0.5, 0.1), ("tension", 0.8, 1.5, 0.3), ("tension", 0.3, 0.05, 0.0),
          ("compression", 0.8, 0.5, 0.1), ("compression", 1.7, 0.2, 0.6), ("tension", 1.2, 0.9, -0.05)]


def evaluate(rows, outputs, solver=None):
    solver = solver or Solver.for_model(tc.SPEC)
    P = np.array([[0.0 if r[0] == "tension" else 1.0, *r[1:]] for r in rows], dtype=float)
    out, status, _, _ = evaluating.evaluate(tc.SPEC, P, tc.SPEC.closure(outputs), solver)
    return out, status


def series_coefficients(spring, lam1, lam2, s):
    """M'(0)/(c R^2) and M'''(0)/(6 c R^2) of the exact moment, by exact symbolic expansion."""
    phi = sy.symbols("phi")
    sig = 1 if spring == "tension" else -1
    l1, l2, s_ = (sy.nsimplify(x) for x in (lam1, lam2, s))
    base = 1 + l1**2 + l2**2
    L0 = sy.sqrt(base - 2 * sig * l1) - sig * s_
    moment = sig * l1 * sy.sin(phi) * (1 - L0 / sy.sqrt(base - 2 * sig * l1 * sy.cos(phi)))
    ser = sy.series(moment, phi, 0, 5).removeO()
    return float(ser.coeff(phi, 1).evalf(30)), float(ser.coeff(phi, 3).evalf(30))


@pytest.mark.parametrize("spring,lam1,lam2,s", PARAMS)
def test_chi_xi_equal_series_of_exact_moment(spring, lam1, lam2, s):
    cols, status = evaluate([(spring, lam1, lam2, s, 1.0, 1.0, 1.0, math.nan)], ("chi", "xi"))
    chi_ref, xi_ref = series_coefficients(spring, lam1, lam2, s)
    assert status[0] == st.OK
    assert cols["chi"][0] == pytest.approx(chi_ref, rel=1e-14, abs=1e-15)
    assert cols["xi"][0] == pytest.approx(xi_ref, rel=1e-13, abs=1e-15)


def test_dimensional_outputs_scale_with_R2c_over_I():
    R, c, I = 0.05, 2000.0, 2e-3
    cols, _ = evaluate([("tension", 0.8, 0.5, 0.1, R, c, I, math.nan)], ("chi", "xi", "omega2", "mu"))
    k = R * R * c / I
    assert cols["omega2"][0] == pytest.approx(k * cols["chi"][0], rel=1e-15)
    assert cols["mu"][0] == pytest.approx(k * cols["xi"][0], rel=1e-15)


def test_singular_and_infeasible_points():
    rows = [("tension", 1.0, 0.0, 0.1, 1, 1, 1, math.nan),   # D0 = 0: spring of zero length
            ("tension", 0.8, 0.1, 0.5, 1, 1, 1, math.nan),   # S0/R beyond sqrt(D0): free length <= 0
            ("tension", 0.8, 0.5, -0.1, 1, 1, 1, 0.5)]       # omega^2 < 0: no oscillation about 0
    cols, status = evaluate(rows, ("chi", "xi", "period_exact"))
    assert list(status) == [st.SINGULAR, st.INFEASIBLE, st.INFEASIBLE]
    assert np.isnan(cols["chi"][:2]).all() and np.isnan(cols["period_exact"]).all()
    assert cols["chi"][2] < 0  # chi itself is well defined; only the motion is not


def exact_period_by_quadrature(spring, lam1, lam2, s, R, c, I, A):
    """T = 4 int_0^A dphi / sqrt(2 k (V(A) - V(phi))), V/(cR^2) = (l(phi) - L0)^2 / 2.

    V(A) - V(phi) is written without cancellation (small amplitudes lose every digit otherwise):
    V(A) - V(phi) = (l_A - l_phi)(l_A + l_phi - 2 L0) / 2 with
    l_A - l_phi = 4 sigma lambda1 sin((A + phi)/2) sin((A - phi)/2) / (l_A + l_phi).
    """
    sig = 1.0 if spring == "tension" else -1.0
    base = 1 + lam1**2 + lam2**2
    L0 = math.sqrt(base - 2 * sig * lam1) - sig * s
    ell = lambda p: math.sqrt(base - 2 * sig * lam1 * math.cos(p))  # noqa: E731
    k = R * R * c / I

    def energy_drop(p):
        la, lp = ell(A), ell(p)
        diff = 4 * sig * lam1 * math.sin(0.5 * (A + p)) * math.sin(0.5 * (A - p)) / (la + lp)
        return 0.5 * diff * (la + lp - 2 * L0)

    def integrand(theta):  # phi = A sin(theta) removes the endpoint singularity
        p = A * math.sin(theta)
        return A * math.cos(theta) / math.sqrt(2 * k * energy_drop(p))
    val, _ = si.quad(integrand, 0.0, math.pi / 2, epsabs=0, epsrel=1e-13, limit=400)
    return 4 * val


@pytest.mark.parametrize("A", [0.05, 0.4, 1.2])
def test_exact_moment_period_against_quadrature(A):
    row = ("tension", 0.8, 0.5, 0.1, 0.05, 2000.0, 2e-3, A)
    cols, status = evaluate([row], ("period_exact_moment",), Solver.for_model(tc.SPEC, rtol=1e-12, atol=1e-14))
    assert status[0] == st.OK
    assert cols["period_exact_moment"][0] == pytest.approx(exact_period_by_quadrature(*row), rel=1e-10)


def test_truncation_error_is_fourth_order_in_amplitude():
    """The two-term model matches the moment through phi^3, so the period error is O(A^4)."""
    A = np.geomspace(0.02, 0.16, 5)
    rows = [("tension", 0.8, 0.7, 0.1, 1, 1, 1, a) for a in A]
    cols, status = evaluate(rows, ("truncation_error",), Solver.for_model(tc.SPEC, rtol=1e-13, atol=1e-15))
    assert (status == st.OK).all()
    slope = np.polyfit(np.log(A), np.log(cols["truncation_error"]), 1)[0]
    assert 3.8 < slope < 4.2, slope


def test_truncation_error_without_dimensional_parameters():
    """truncation_error is a ratio: it must not depend on R, c, I (time scale)."""
    a, _ = evaluate([("tension", 0.8, 0.7, 0.1, 1, 1, 1, 0.6)], ("truncation_error",))
    b, _ = evaluate([("tension", 0.8, 0.7, 0.1, 0.05, 2000.0, 2e-3, 0.6)], ("truncation_error",))
    assert a["truncation_error"][0] == pytest.approx(b["truncation_error"][0], rel=1e-7)


def test_hardness_sign():
    cols, _ = evaluate([("tension", 0.8, 0.5, 0.0, 1, 1, 1, math.nan), ("tension", 0.8, 0.5, 0.3, 1, 1, 1, math.nan)],
                       ("hardness", "xi"))
    assert list(cols["hardness"]) == list(np.sign(cols["xi"]))


# ----------------------------------------------------------------------------- oscillation by the exact moment
def quadrature_period(spring, lam1, lam2, s, R, c, I, A, dps=30):
    """Independent reference: T = 4 int_0^A dphi / sqrt(2 k (V(A) - V(phi))), V = (l - L0)^2 / 2, in
    30-digit mpmath (tanh-sinh on 8 pieces), phi = A sin(theta), V(A) - V(phi) without cancellation.
    NaN where V(A) - V(phi) <= 0 somewhere on (0, A): the lever does not reach phi = 0."""
    sig = 1 if spring == "tension" else -1
    with mp.workdps(dps):
        l1, l2, S, a = (mp.mpf(x) for x in (lam1, lam2, s, A))
        k = mp.mpf(R) ** 2 * mp.mpf(c) / mp.mpf(I)
        D0 = (1 - sig * l1) ** 2 + l2**2
        L0 = mp.sqrt(D0) - sig * S
        ell = lambda p: mp.sqrt(D0 + 4 * sig * l1 * mp.sin(p / 2) ** 2)  # noqa: E731
        lA = ell(a)

        def drop(p):  # (V(A) - V(p)) / (A - p) > 0 is required on [0, A)
            lp = ell(p)
            return 2 * sig * l1 * mp.sin((a + p) / 2) / (lA + lp) * (lA + lp - 2 * L0)
        if min(drop(a * mp.mpf(j) / 64) for j in range(64)) <= 0:
            return math.nan

        def f(th):
            p = a * mp.sin(th)
            lp = ell(p)
            dl = 4 * sig * l1 * mp.sin((a + p) / 2) * mp.sin(a * mp.sin(mp.pi / 4 - th / 2) ** 2) / (lA + lp)
            return a * mp.cos(th) / mp.sqrt(k * dl * (lA + lp - 2 * L0))
        return float(4 * mp.quad(f, mp.linspace(0, mp.pi / 2, 9)))


def reaches_zero(spring, lam1, lam2, s, R, c, I, A):
    """Second, integration-based opinion: does phi reach 0 within 5 s (scipy DOP853; the periods
    here are below 3 s, and a lever that stays in its well keeps swinging inside it)?"""
    f = exact_moment_rhs(spring, lam1, lam2, s, R, c, I)
    return not math.isnan(first_zero_crossing(f, A, 5.0, 1e-10, 1e-12))


ISSUE_POINT = ("tension", 0.3, 1.5, 1.6, 0.11, 530.0, 2.2e-3, 2.5)


def test_issue_point_exact_moment_oscillates_past_the_cubic_separatrix():
    """Issue 12 item 3: the two-term model is past its soft separatrix (epsilon < -1), the exact
    moment brings the lever back: T = 0.354280 s."""
    ref = quadrature_period(*ISSUE_POINT)
    assert ref == pytest.approx(0.354280, abs=5e-7)
    cols, status = evaluate([ISSUE_POINT], ("period_exact_moment",))
    assert status[0] == st.OK
    assert cols["period_exact_moment"][0] == pytest.approx(ref, rel=1e-10)
    # asked together with two-term outputs: those are NaN and say why; the exact period is still given
    cols, status = evaluate([ISSUE_POINT], ("period_exact_moment", "truncation_error", "period", "chi", "xi"))
    assert status[0] == st.NOT_OSCILLATORY
    assert cols["xi"][0] * ISSUE_POINT[-1] ** 2 / cols["chi"][0] < -1.0  # epsilon: past the cubic's separatrix
    assert np.isnan(cols["period"][0]) and np.isnan(cols["period_exact"][0]) and np.isnan(cols["truncation_error"][0])
    assert cols["period_exact_moment"][0] == pytest.approx(ref, rel=1e-10)


CLASS_ROWS = [(spring, lam1, lam2, s, 0.11, 530.0, 2.2e-3, A)
              for spring, lam1, lam2 in (("tension", 0.3, 1.5), ("tension", 0.8, 0.3), ("compression", 0.8, 0.5),
                                         ("compression", 1.7, 0.2))
              for s in (-0.5, -0.1, 0.0, 1.6)
              for A in (0.3, 1.0, 2.5)
              if math.sqrt((1 - (1 if spring == "tension" else -1) * lam1) ** 2 + lam2**2)
              - (1 if spring == "tension" else -1) * s > 0]  # free length > 0


def test_exact_moment_oscillation_decided_by_the_exact_moment():
    """A sweep over A and s0_over_r, both springs, where the cubic is past its separatrix or has
    omega^2 <= 0: period_exact_moment is ok and right (quadrature) wherever the exact moment
    oscillates, and not_oscillatory exactly where it does not (quadrature impossible, and scipy
    never sees phi reach 0)."""
    cols, status = evaluate(CLASS_ROWS, ("period_exact_moment",))
    two_term, _ = evaluate(CLASS_ROWS, ("period_exact", "chi"))
    cubic_fails = np.isnan(two_term["period_exact"])
    n_saved = n_truly_not = 0
    for row, T, code, fails in zip(CLASS_ROWS, cols["period_exact_moment"], status, cubic_fails):
        ref = quadrature_period(*row, dps=20)
        if np.isfinite(ref):
            assert code == st.OK, (row, code)
            assert T == pytest.approx(ref, rel=1e-10), row
            n_saved += bool(fails)
        else:
            assert code == st.NOT_OSCILLATORY and np.isnan(T), (row, code)
            assert not reaches_zero(*row), row
            n_truly_not += 1
    assert n_saved >= 15 and n_truly_not >= 8  # both kinds of point are in the sweep


def _near(rows_of, gaps):
    return [r for g in gaps for r in rows_of(g)]


def test_exact_moment_near_its_humps_is_right_or_ill_conditioned():
    """Released next to the top phi = pi (pi - A from 1e-1 to 1e-9, and A = math.pi itself), and
    swinging over the hump at phi = 0 with a small energy excess (s0_over_r < 0; A / A* - 1 from 1e-1
    to 1e-8, V(A*) = V(0)), also both at once: ok points within
    rtol of the quadrature (phi / A integration once gave 4e5 rtol there with status ok), the
    others ill_conditioned."""
    from scipy.optimize import brentq

    rows = [(spring, 0.8, 0.5, s, 0.11, 530.0, 2.2e-3, math.pi - g)
            for spring, s in (("tension", 1.6 - 1.3), ("compression", 0.1)) for g in np.geomspace(1e-1, 1e-9, 9)]
    rows.append(("tension", 0.8, 0.5, 0.1, 0.11, 530.0, 2.2e-3, math.pi))
    # the last: A* = 1.87 > pi / 2, integrated from the top and crawling over phi = 0 at the end
    for spring, lam1, lam2, s in (("tension", 0.8, 0.3, -0.1), ("compression", 0.8, 0.5, -0.1),
                                  ("compression", 1.7, 0.2, -0.5)):
        sig = 1 if spring == "tension" else -1
        D0 = (1 - sig * lam1) ** 2 + lam2**2
        L0 = math.sqrt(D0) - sig * s

        def gap(A, D0=D0, L0=L0, sig=sig, lam1=lam1):  # V(A) - V(0), up to a positive factor
            return abs(math.sqrt(D0 + 4 * sig * lam1 * math.sin(A / 2) ** 2) - L0) - abs(math.sqrt(D0) - L0)
        A_star = brentq(gap, 1e-3, 3.0, xtol=1e-15)  # V(A*) = V(0): beyond it the lever crawls over phi = 0
        rows += [(spring, lam1, lam2, s, 0.11, 530.0, 2.2e-3, A_star * (1 + g)) for g in np.geomspace(1e-1, 1e-8, 8)]
    refs = {}
    for rtol in (5e-11, 1e-9):
        cols, status = evaluate(rows, ("period_exact_moment",), Solver.for_model(tc.SPEC, rtol=rtol, atol=rtol / 50))
        ok = status == st.OK
        assert (status[~ok] == st.ILL_CONDITIONED).all(), status
        assert status[18] == st.ILL_CONDITIONED  # A = math.pi: 1.2e-16 below the top
        for i in np.nonzero(ok)[0]:
            if i not in refs:
                refs[i] = quadrature_period(*rows[i])
            ref = refs[i]
            T = cols["period_exact_moment"][i]
            assert abs(T - ref) <= rtol * ref, (rtol, rows[i], abs(T - ref) / ref / rtol)
        assert ok.sum() >= 24 and (~ok).sum() >= 8


def test_two_term_period_near_its_separatrix_is_right_or_ill_conditioned():
    """The torsional circuit's two-term period near the cubic's soft separatrix (1 + epsilon from
    1e-2 to 1e-10): ok points within 2 rtol (README: 1e-10 at the default 5e-11) of the elliptic
    closed form of chi, xi evaluated in 50 digits from the float inputs; the rest ill_conditioned,
    where the sensitivities of chi and xi to lambda1, lambda2, s0_over_r make the period too
    sensitive for rtol."""
    gaps = np.geomspace(1e-2, 1e-10, 9)
    rows, refs = [], []
    for lam1, lam2, s in ((0.3, 1.5, 1.6), (0.3, 0.8, 1.0)):
        with mp.workdps(50):
            l1, l2, S = mp.mpf(lam1), mp.mpf(lam2), mp.mpf(s)
            D0 = (1 - l1) ** 2 + l2**2
            chi = l1 * S / mp.sqrt(D0)
            xi = l1 * (3 * l1 - S * (D0 + 3 * l1) / mp.sqrt(D0)) / (6 * D0)
            assert xi < 0
            for g in gaps:
                A = float(mp.sqrt(-(1 - g) * chi / xi))
                k = mp.mpf(0.11) ** 2 * mp.mpf(530.0) / mp.mpf(2.2e-3)
                w2, mu, a = k * chi, k * xi, mp.mpf(A)
                s_ = w2 + mu * a * a
                rows.append(("tension", lam1, lam2, s, 0.11, 530.0, 2.2e-3, A))
                refs.append(float(4 * mp.ellipk(mu * a * a / (2 * s_)) / mp.sqrt(s_)))
    refs = np.array(refs)
    for rtol in (5e-11, 1e-9):
        cols, status = evaluate(rows, ("period",), Solver.for_model(tc.SPEC, rtol=rtol, atol=rtol / 50))
        ok = status == st.OK
        assert (status[~ok] == st.ILL_CONDITIONED).all() and np.isnan(cols["period"][~ok]).all()
        err = np.abs(cols["period"] - refs) / refs
        assert (err[ok] <= 2 * rtol).all(), (rtol, err[ok].max() / rtol)
        assert ok.sum() >= 6 and (~ok).sum() >= 2


# ----------------------------------------------------------------------------- the exact system's own time unit
def test_exact_moment_period_next_to_a_zero_rest_length():
    """Tension, lambda1 = 1, lambda2 = 2e-6, s0_over_r = 1e-6, A = 0.3: the spring nearly passes through
    the axis, xi ~ 1 / (2 D0) = 1.25e11 while the moment saturates like sin(phi). The two-term model's time
    unit was 1e5 times too fast and the horizon ended before the first quarter period (no_event, NaN):
    the period is 0.1263745 s (quadrature)."""
    row = ("tension", 1.0, 2e-6, 1e-6, 0.05, 2000.0, 2e-3, 0.3)
    ref = quadrature_period(*row)
    assert ref == pytest.approx(0.1263745, abs=5e-8)
    cols, status = evaluate([row], ("period_exact_moment",))
    assert status[0] == st.OK
    assert cols["period_exact_moment"][0] == pytest.approx(ref, rel=1e-10)


TINY_ROWS = ([("tension", lam1, lam2, s * math.sqrt((1 - lam1) ** 2 + lam2**2), 0.05, 2000.0, 2e-3, A)
              for lam1, lam2 in ((1.0, 3e-6), (1.0, 1e-4), (1.0 - 1e-4, 0.0), (1.0 - 1e-6, 1e-6))
              for s, A in ((0.5, 1e-3), (1e-3, 0.3), (0.0, 2.0), (-0.5, 3.0))]
             + [(spring, 0.8, 0.5, s, 0.05, 2000.0, 2e-3, A)
                for spring, s, A in (("tension", 0.0, 1e-5), ("compression", 0.0, 1e-3), ("tension", 1e-12, 1e-3),
                                     ("compression", 1e-9, 1e-5), ("tension", -1e-9, 0.3))])


def test_exact_moment_period_for_tiny_D0_lambda2_and_s0_over_r():
    """A sweep of tiny rest lengths (D0 from 1e-8 to 1e-12, lambda2 down to 0) and mounting deformations
    (s0_over_r = 0, 1e-12, +-1e-9, and fractions of sqrt(D0)) at amplitudes from 1e-5 to 3 rad, both
    springs: every point oscillates (the energy says so), is ok and within 1e-10 of the quadrature.
    (The two-term time unit left D0 <= 1e-7 at A = 0.3 no_event; 1 - L0 / l lost 8 digits at s0_over_r = 0,
    A = 1e-5, where the moment is now formed as (l - L0) / l.)"""
    cols, status = evaluate(TINY_ROWS, ("period_exact_moment",))
    for row, T, code in zip(TINY_ROWS, cols["period_exact_moment"], status):
        ref = quadrature_period(*row)
        assert code == st.OK, (row, code)
        assert T == pytest.approx(ref, rel=1e-10), row


def test_exact_time_unit_is_the_two_term_one_where_they_agree():
    """Inside SCALE_BAND the exact system keeps the two-term model's time unit (the shipped scenes' bits),
    outside it takes the exact moment's own (v_max / A from the energy), which never makes the period in
    that unit shorter than 4 (the lever cannot be faster than v_max)."""
    k = 0.05**2 * 2000.0 / 2e-3
    for spring, lam1, lam2, s, A, kept in (("tension", 0.8, 0.5, 0.1, 0.3, True), ("tension", 0.8, 0.3, 0.1, 1.5, True),
                                           ("tension", 1.0, 2e-6, 1e-6, 0.3, False)):
        row = (spring, lam1, lam2, s, 0.05, 2000.0, 2e-3, A)
        p = np.array([0.0, *row[1:], 100.0] + [0.0] * len(tc.MODEL.internal))
        assert tc.exact_prepare(p, 1e-10) == st.OK  # plain Python: the declaration's own function
        _, chi, xi, _ = tc.coefficients(1.0, lam1, lam2, s)
        w2_two_term = k * (abs(chi) + abs(xi) * A * A)
        assert (p[tc.EW] ** 2 == pytest.approx(w2_two_term, rel=1e-14)) == kept
        assert quadrature_period(*row) * p[tc.EW] >= 4.0
    # sweeps/torsional_circuit_truncation.toml (lambda2 0.3 .. 2, A 0.02 .. 1.5): the two-term unit
    # everywhere, at most 9.2 times the exact one in w^2 (inside SCALE_BAND: the scene keeps its bits)
    ratios = []
    for lam2 in np.linspace(0.3, 2.0, 12):  # the scene's ends are on this grid
        for A in np.linspace(0.02, 1.5, 12):
            p = np.array([0.0, 0.8, lam2, 0.1, 0.05, 2000.0, 2e-3, A, 100.0] + [0.0] * len(tc.MODEL.internal))
            assert tc.exact_prepare(p, 1e-11) == st.OK
            D0 = tc.rest_length_squared(1.0, 0.8, lam2)
            exact = k * tc.exact_time_scale(1.0, 0.8, D0, 0.1, A)
            ratios.append(p[tc.EW] ** 2 / exact)
    assert max(ratios) == pytest.approx(9.2, abs=0.05) and max(ratios) < tc.SCALE_BAND
    assert min(ratios) > 1 / tc.SCALE_BAND


@pytest.mark.parametrize("method", tc.SPEC.methods)
def test_exact_moment_period_of_every_method_next_to_a_zero_rest_length(method):
    """Every method at rtol 1e-10 next to D0 -> 0 (every third point of the sweep above): right within
    1e-9 of the quadrature, or max_steps (the symplectic method's fixed steps must resolve the moment's
    turn within |phi| ~ sqrt(D0 / lambda1): they follow the faster of the two-term and the exact time
    units; in the exact one alone the period was 2e-7 off with status ok at D0 = 9e-12, A = 1e-3)."""
    rows = TINY_ROWS[::3]
    cols, status = evaluate(rows, ("period_exact_moment",), Solver.for_model(tc.SPEC, method=method, rtol=1e-10,
                                                                             atol=1e-12))
    for row, T, code in zip(rows, cols["period_exact_moment"], status):
        if code == st.MAX_STEPS and method == "symplectic":
            continue
        assert code == st.OK, (row, code)
        assert T == pytest.approx(quadrature_period(*row), rel=1e-9), row
    assert (status == st.OK).sum() >= 4
