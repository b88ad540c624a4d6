"""mechsweep.balancing: the plain functions (numpy in, numpy out) and their argument checks."""
import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

from mechsweep import balancing as B
from mechsweep import status as st


def brute_front(F):
    n = F.shape[0]
    keep = np.zeros(n, bool)
    for i in range(n):
        if np.isnan(F[i]).any():
            continue
        dominated = False
        for j in range(n):
            if j != i and not np.isnan(F[j]).any() and np.all(F[j] <= F[i]) and np.any(F[j] < F[i]):
                dominated = True
                break
        keep[i] = not dominated
    return keep


# ----------------------------------------------------------------------------- Pareto front
def test_pareto_front_of_a_known_set():
    F = np.array([[1, 5], [2, 3], [3, 4], [4, 1], [2, 3], [5, 5], [1, 6], [np.nan, 0], [3, 1]], float)
    # (3, 4) is dominated by (2, 3); (4, 1) by (3, 1); (5, 5) and (1, 6) by (1, 5); the duplicate (2, 3) stays
    assert B.pareto_front(F).tolist() == [True, True, False, False, True, False, False, False, True]


def test_pareto_front_of_points_on_a_circle_is_the_lower_left_arc():
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    F = np.stack([np.cos(t), np.sin(t)], axis=1)
    front = B.pareto_front(F)
    np.testing.assert_array_equal(front, (t >= np.pi) & (t <= 1.5 * np.pi))


@pytest.mark.parametrize("k", [1, 2, 3, 4])
def test_pareto_front_against_brute_force(k):
    rng = np.random.default_rng(k)
    F = rng.integers(0, 6, size=(300, k)).astype(float)  # many ties and duplicates
    F[rng.random(300) < 0.05, 0] = np.nan
    np.testing.assert_array_equal(B.pareto_front(F), brute_front(F))


@settings(max_examples=30, deadline=None)
@given(hs.lists(hs.tuples(hs.sampled_from([0.0, 1.0, 2.5]), hs.floats(-10, 10), hs.floats(-10, 10)), min_size=1,
                max_size=60))
def test_property_pareto_front(points):
    F = np.array(points)
    np.testing.assert_array_equal(B.pareto_front(F), brute_front(F))


def test_pareto_front_edge_cases():
    assert B.pareto_front(np.full((3, 2), np.nan)).tolist() == [False] * 3
    assert B.pareto_front(np.array([3.0, 1.0, 2.0, 1.0])).tolist() == [False, True, False, True]
    with pytest.raises(ValueError, match=r"\[n, k\]"):
        B.pareto_front(np.zeros((2, 2, 2)))


# ----------------------------------------------------------------------------- weighted optimum
def test_weighted_optimum_and_its_place_on_the_front():
    F = np.array([[1, 5], [2, 3], [3, 4], [4, 1], [np.nan, 0]], float)
    assert B.weighted_optimum(F, [1, 1]) == 1  # sums 6, 5, 7, 5 -> first of the ties
    assert B.weighted_optimum(F, [1, 0]) == 0
    assert B.weighted_optimum(F, [0, 1]) == 3  # the NaN row never wins
    rng = np.random.default_rng(5)
    G = rng.random((500, 4))
    front = B.pareto_front(G)
    for w in itertools.product([0.1, 1, 3], repeat=4):
        assert front[B.weighted_optimum(G, w)]
    with pytest.raises(ValueError, match="weights"):
        B.weighted_optimum(G, [1, 1])
    with pytest.raises(ValueError, match="no row"):
        B.weighted_optimum(np.full((2, 2), np.nan), [1, 1])


# ----------------------------------------------------------------------------- efficiency
def test_efficiency():
    phi = B.PHI
    static = 10 * np.sin(phi)
    assert B.efficiency(static, 2.5 * np.cos(phi)) == pytest.approx(75.0)
    assert B.efficiency(static, static) == 0.0
    assert B.efficiency(static, 20 * np.sin(phi)) == pytest.approx(-100.0)
    assert B.efficiency(-8.0, 2.0) == pytest.approx(75.0)  # maxima given directly
    r = B.efficiency(np.stack([static, 2 * static]), np.stack([static / 2, static / 2]))
    np.testing.assert_allclose(r, [50.0, 75.0])


# ----------------------------------------------------------------------------- axis offset
def test_axis_moment_is_the_printed_formula_for_a_counterweight_opposite_the_crank():
    phi = np.linspace(0, 2 * np.pi, 50)
    w, al = 3 + np.sin(phi), 0.5 * np.cos(phi)
    S, x, y = 0.4, 0.1, -0.2
    printed = S * (w ** 2 * (y * np.cos(phi) - x * np.sin(phi)) + al * (x * np.cos(phi) + y * np.sin(phi)))
    np.testing.assert_allclose(B.axis_moment(phi, x, y, S, w, phi_dd=al), printed, rtol=1e-13, atol=1e-15)
    # a counterweight at angle beta acts like one opposite the crank at phi + beta - pi
    np.testing.assert_allclose(B.axis_moment(phi, x, y, S, w, phi_dd=al, cw_angle=1.0),
                               B.axis_moment(phi + 1.0 - np.pi, x, y, S, w, phi_dd=al), rtol=1e-12, atol=1e-15)


def test_rms_axis_offset_cancels_a_pure_first_harmonic():
    phi = B.PHI
    S, w, x0, y0 = 0.5, 12.0, 0.03, -0.07
    M = -B.axis_moment(phi, x0, y0, S, w)
    assert B.rms_axis_offset(phi, M, S, w) == pytest.approx((x0, y0), rel=1e-12)
    assert B.rms_axis_offset(phi, M, S, w, method="formula1") == pytest.approx((x0, y0), rel=1e-12)
    assert B.first_harmonic_axis_offset(phi, M, S, w) == pytest.approx((x0, y0), rel=1e-12)
    assert B.rms_axis_offset(phi, M, 0.0, w) == (0.0, 0.0)


def test_axis_argument_checks():
    phi = np.linspace(0, 6, 10)
    with pytest.raises(ValueError, match="one length"):
        B.rms_axis_offset(phi, np.ones(9), 1.0, 1.0)
    with pytest.raises(ValueError, match="S = -1"):
        B.rms_axis_offset(phi, np.ones(10), -1.0, 1.0)
    with pytest.raises(ValueError, match="constant speed"):
        B.rms_axis_offset(phi, np.ones(10), 1.0, np.ones(10), method="formula1")
    with pytest.raises(ValueError, match="method 'lsq'"):
        B.rms_axis_offset(phi, np.ones(10), 1.0, 1.0, method="lsq")
    with pytest.raises(ValueError, match="singular"):
        B.rms_axis_offset(phi, np.ones(10), 1.0, 0.0)
    with pytest.raises(ValueError, match="one turn"):
        B.first_harmonic_axis_offset(np.linspace(0, 7, 10), np.ones(10), 1.0, 1.0)
    np.testing.assert_allclose(B.periodic_trapezoid_weights(B.PHI), 2 * np.pi / 360)


# ----------------------------------------------------------------------------- mass substitution
def test_static_two_point_substitution_keeps_mass_and_centre():
    m, b, c = 3.0, 0.2, 0.5
    mB, mC = B.static_two_point(m, b, c)
    assert mB + mC == pytest.approx(m)
    assert mB * b == pytest.approx(mC * c)  # centre of mass at G
    assert mB * b ** 2 + mC * c ** 2 != pytest.approx(0.01)  # the inertia is not kept in general


@pytest.mark.parametrize("m,I_G,b", [(2.0, 0.03, 0.1), (0.5, 1e-3, 0.4)])
def test_dynamic_two_point_substitution_keeps_mass_centre_and_inertia(m, I_G, b):
    mB, mK, k = B.dynamic_two_point(m, I_G, b)
    assert mB + mK == pytest.approx(m, rel=1e-14)
    assert mB * b == pytest.approx(mK * k, rel=1e-14)
    assert mB * b ** 2 + mK * k ** 2 == pytest.approx(I_G, rel=1e-14)
    arr = B.dynamic_two_point(np.array([m, m]), np.array([I_G, 2 * I_G]), np.array([b, b]))
    assert arr[0].shape == (2,)


# ----------------------------------------------------------------------------- evaluate and curves
GEO = dict(a1=0.1, a2=0.35, a3=0.3, a4=0.4, m1=1.0, r1=0.05, I1=1e-3, m2=2.0, r2=0.175, I2=0.02,
           m3=1.5, r3=0.15, I3=0.011, omega=20.0)


def test_evaluate_broadcasts_parameters():
    out, status = B.evaluate("fourbar_balancing", ["R_axis", "M_static_phi"], **dict(
        GEO, a2=np.array([[0.33], [0.35]]), branch=["open", "crossed", "open"]))
    assert out["R_axis"].shape == status.shape == (2, 3)
    assert out["M_static_phi"].shape == (2, 3, 360)
    assert out["R_axis"][0, 0] == out["R_axis"][0, 2] != out["R_axis"][0, 1]
    one, _ = B.evaluate("fourbar_balancing", "R_axis", **dict(GEO, a2=0.33, branch="crossed"))
    assert one["R_axis"].shape == ()
    assert one["R_axis"] == out["R_axis"][0, 1]


def test_evaluate_checks_its_arguments():
    with pytest.raises(ValueError, match="unknown parameter"):
        B.evaluate("fourbar_balancing", ["R_axis"], **GEO, a5=1.0)
    with pytest.raises(ValueError, match="missing parameter I3"):
        B.evaluate("fourbar_balancing", ["R_axis"], **{k: v for k, v in GEO.items() if k != "I3"})
    with pytest.raises(ValueError, match="a1: -0.1 m is outside the physical range"):
        B.evaluate("fourbar_balancing", ["R_axis"], **dict(GEO, a1=-0.1))
    with pytest.raises(ValueError, match="branch: 'left' is not allowed"):
        B.evaluate("fourbar_balancing", ["R_axis"], **dict(GEO, branch="left"))
    with pytest.raises(ValueError, match="unknown output"):
        B.evaluate("fourbar_balancing", ["R_axes"], **GEO)
    with pytest.raises(ValueError, match="model 'fourbar'"):
        B.evaluate("fourbar", ["R_axis"], **GEO)
    with pytest.raises(ValueError, match="not both"):
        B.evaluate("slidercrank_balancing", ["F_max"], r=0.05, l=0.2, m1=1, r1=0, I1=0, m2=1, r2=0.1, I2=0.01,
                   m3=1, omega=10.0, k=0.5, **{"lambda": 0.25})


def test_counterweight_helpers_agree_with_the_models():
    cw = B.fourbar_counterweights(0.1, 0.35, 0.3, 1.0, 0.05, 2.0, 0.175, 1.5, 0.15, theta2=0.3)
    out, _ = B.evaluate("fourbar_balancing", ["cw1_mr_static", "cw1_angle_static", "cw3_mr_static",
                                              "cw3_angle_static"], **dict(GEO, theta2=0.3))
    for k in ("cw1_mr", "cw1_angle", "cw3_mr", "cw3_angle"):
        assert cw[k] == pytest.approx(float(out[k + "_static"]), rel=1e-14)
    sc = dict(r=0.05, l=0.2, m1=1.0, r1=0.02, I1=0.0, m2=0.8, r2=0.06, I2=3e-3, m3=0.6, k=0.3)
    cw = B.slidercrank_counterweight(**sc)
    out, _ = B.evaluate("slidercrank_balancing", ["m_A", "m_B", "cw_mr", "cw_angle"], **sc, omega=10.0)
    for k in cw:
        assert cw[k] == pytest.approx(float(out[k]), rel=1e-14)


def test_curves_report_a_status_instead_of_raising():
    c, code = B.fourbar_curves(np.linspace(0, 1, 5), 1.0, **dict(GEO, a1=0.3))
    assert code == st.INFEASIBLE and np.isnan(c["M"]).all()
    c, code = B.slidercrank_curves([0.0, 1.0], 10.0, r=0.05, l=0.04, m1=1, r1=0, I1=0, m2=1, r2=0.02,
                                   I2=1e-3, m3=1)
    assert code == st.INFEASIBLE and np.isnan(c["Fx"]).all()


def test_kernels_work_inside_user_parallel_numba_code():
    import numba

    from mechsweep.models import _linkage as L

    @numba.njit(parallel=True)
    def transmission(a2):
        out = np.empty(a2.size)
        for i in numba.prange(a2.size):
            code, s = L.fourbar_assembly(0.1, a2[i], 0.3, 0.4)
            out[i] = s if code == 0 else math.nan
        return out

    a2 = np.array([0.35, 0.05])
    res = transmission(a2)
    assert res[0] == pytest.approx(L.fourbar_assembly(0.1, 0.35, 0.3, 0.4)[1]) and np.isnan(res[1])
