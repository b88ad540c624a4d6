"""Torsional circuit: coefficients against the series of the exact moment (sympy, exact
arithmetic), the exact-moment period against quadrature, the truncation error's order."""
import math

import numpy as np
import pytest
import scipy.integrate as si
import sympy as sy

from mechsweep import status as st
from mechsweep.models import torsional_circuit as tc
from mechsweep.scene import Solver

PARAMS = [("tension", 0.8, 0.5, 0.1), ("tension", 0.8, 1.5, 0.3), ("tension", 0.3, 0.05, 0.0),
          ("compression", 0.8, 0.5, 0.1), ("compression", 1.7, 0.2, 0.6), ("tension", 1.2, 0.9, -0.05)]


def evaluate(rows, outputs, solver=None):
    solver = solver or Solver.for_model(tc.SPEC)
    P = np.array([[0.0 if r[0] == "tension" else 1.0, *r[1:]] for r in rows], dtype=float)
    wanted = tc.SPEC.closure(outputs)
    out = {name: np.full(len(rows), np.nan) for name in wanted}
    status = np.zeros(len(rows), np.int8)
    ns = np.zeros(len(rows), np.int64)
    nr = np.zeros(len(rows), np.int64)
    tc.evaluate(P, wanted, solver, out, status, ns, nr)
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
