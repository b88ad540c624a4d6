"""Auto-balancer outputs at and near the platform resonances and the first-approximation boundaries,
built the ways users build them (Omega typed equal to omega_j, or computed from c_j and M), one ulp
either side, and over random parameter sets (Hypothesis): an undamped resonance is SINGULAR, a P_approx
given is right against 50-digit arithmetic on the same float inputs, and no verdict is set by the sign
of a rounding error. Also the mass matrix near singular (M I_B -> 2 m^2 a^2): INFEASIBLE or
ILL_CONDITIONED, never a number with status ok. The rules: models/autobalancer.py, "Resonances and
boundaries within rounding" and "Mass matrix"."""
import math

import mpmath as mp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as hs

import mechsweep
from mechsweep import status as st
from mechsweep.models import autobalancer as ab

from tests import evaluating

CLOSED = ("stable_first_approx", "P_approx", "stable_damped_approx")
BASE = dict(m=0.05, a=0.1, I_B=6e-4, A0=5e-3, h=1e-3)  # feasible pendulums; only the platform varies


def rows(**params):
    """Parameter rows (broadcast) in the model's order; absent parameters at their defaults."""
    return evaluating.rows(ab.SPEC, **params)


def closed(**params):
    """(outputs, status) of the first-approximation outputs (one compiled closed-form kernel)."""
    out, status, _, _ = evaluating.evaluate(ab.SPEC, rows(**(BASE | params)), ab.SPEC.closure(CLOSED), quiet=True)
    return out, status


def ulps(x):
    """x and its neighbours one ulp below and above."""
    return [np.nextafter(x, -np.inf), x, np.nextafter(x, np.inf)]


def built(c, M):
    """Omega = sqrt(c / M) the ways a user computes it (numpy, math, a power, the ratio of roots),
    each with its neighbours one ulp either side."""
    ways = {float(np.sqrt(c / M)), math.sqrt(c / M), (c / M) ** 0.5, math.sqrt(c) / math.sqrt(M),
            float(np.sqrt(np.float64(c) / np.float64(M)))}
    return sorted({float(v) for w in ways for v in ulps(w)})


def axis_mp(M, omega=None, c=None, zeta=None, b=None):
    """(c_j, b_j) in 50-digit arithmetic from the float inputs, as the model defines them:
    c = M omega^2, b = 2 zeta M omega, omega = sqrt(c / M)."""
    with mp.workdps(50):
        M = mp.mpf(M)
        c = M * mp.mpf(omega) ** 2 if c is None else mp.mpf(c)
        w = mp.mpf(omega) if omega is not None else mp.sqrt(c / M)
        b = 2 * mp.mpf(zeta) * M * w if b is None else mp.mpf(b)
        return c, b


def receptance_mp(Om, M, axes):
    """(Re(H_xi + H_eta), |H_xi| + |H_eta|) in 50-digit arithmetic; axes = [(c, b), (c, b)]."""
    with mp.workdps(50):
        Om, M = mp.mpf(Om), mp.mpf(M)
        total, size = mp.mpf(0), mp.mpf(0)
        for c, b in axes:
            H = 1 / mp.mpc(c - M * Om**2, b * Om)
            total += H.real
            size += abs(H)
        return total, size


masses = hs.floats(0.5, 500.0)
stiffness = hs.floats(1.0, 1e6)


# ----------------------------------------------------------------------------- undamped resonances
@settings(max_examples=60, deadline=None)
@given(c=stiffness, M=masses, ratio=hs.floats(1.2, 4.0), which=hs.sampled_from(["xi", "eta"]))
def test_an_undamped_resonance_built_from_c_and_M_is_singular_to_an_ulp(c, M, ratio, which):
    other = "eta" if which == "xi" else "xi"
    Om = np.array(built(c, M))
    # the resonant axis given by its stiffness, undamped; the other stiffer (or softer) and damped
    p = {f"c_{which}": c, f"b_{which}": 0.0, f"c_{other}": c * ratio, f"zeta_{other}": 0.05}
    out, status = closed(Omega=Om, M=M, **p)
    assert (status == st.SINGULAR).all(), (Om, status, out["P_approx"])
    assert np.isnan(out["P_approx"]).all() and np.isnan(out["stable_damped_approx"]).all()
    # the frequency boundary of the source's rule: on it, within rounding (strict inequality: 0)
    assert (out["stable_first_approx"] == 0.0).all()
    # the same Omega values with omega_j typed as that Omega (omega and zeta parametrisation)
    for w in Om:
        q = {f"omega_{which}": w, f"zeta_{which}": 0.0, f"omega_{other}": w * math.sqrt(ratio),
             f"zeta_{other}": 0.05}
        out, status = closed(Omega=ulps(w), M=M, **q)
        assert (status == st.SINGULAR).all(), (w, status, out["P_approx"])
        assert (out["stable_first_approx"] == 0.0).all()


def test_two_hundred_undamped_resonances_are_all_singular():
    # Omega == omega_xi with zeta_xi = 0 over random masses and frequencies: every one singular
    # (the plain difference c - M Omega^2 leaves a few ulps there: P of 1e13 .. 1e15 with a
    # verdict set by their sign, unless the tolerance decides)
    rng = np.random.default_rng(26)
    Om, M = rng.uniform(0.5, 50.0, 200), rng.uniform(1.0, 100.0, 200)
    out, status = closed(Omega=Om, M=M, omega_xi=Om, zeta_xi=0.0, omega_eta=1.7 * Om, zeta_eta=0.05)
    assert (status == st.SINGULAR).all() and np.isnan(out["stable_damped_approx"]).all()
    c = rng.uniform(1.0, 1e4, 200)
    out, status = closed(Omega=np.sqrt(c / M), M=M, c_xi=c, b_xi=0.0, c_eta=3.0 * c, b_eta=1.0)
    assert (status == st.SINGULAR).all() and np.isnan(out["stable_damped_approx"]).all()


def test_a_damping_below_the_resolution_of_the_detuning_is_still_singular():
    # zeta = 1e-20 at resonance: b Omega is far below what c - M Omega^2 can resolve (16 ulps of its
    # terms), so Re H is any number within +-1 / (2 b Omega): singular, not 1e20-sized noise
    out, status = closed(Omega=20.0, M=20.0, omega_xi=20.0, zeta_xi=1e-20, omega_eta=30.0, zeta_eta=0.05)
    assert status[0] == st.SINGULAR and math.isnan(out["P_approx"][0])


# ----------------------------------------------------------------------------- damped resonances, near ones
@settings(max_examples=60, deadline=None)
@given(c=stiffness, M=masses, ratio=hs.floats(1.2, 4.0), zeta=hs.floats(1e-6, 0.5),
       which=hs.sampled_from(["xi", "eta"]))
def test_a_damped_resonance_gives_the_other_axis_term_and_a_verdict_no_rounding_sets(c, M, ratio, zeta, which):
    other = "eta" if which == "xi" else "xi"
    Om = np.array(built(c, M))
    p = {f"c_{which}": c, f"zeta_{which}": zeta, f"c_{other}": c * ratio, f"zeta_{other}": 0.05}
    out, status = closed(Omega=Om, M=M, **p)
    assert (status == st.OK).all()
    # at the resonance Re H_j = 0: P is the other axis' term, to 1e-13 of |H_xi| + |H_eta|
    for k, w in enumerate(Om):
        axes = [axis_mp(M, c=c, zeta=zeta), axis_mp(M, c=c * ratio, zeta=0.05)]
        with mp.workdps(50):
            axes[0] = (M * mp.mpf(w) ** 2, axes[0][1])  # c_j = M Omega^2 exactly: the resonance meant
        ref, size = receptance_mp(w, M, axes)
        assert abs(out["P_approx"][k] - ref) <= 1e-13 * size, (w, out["P_approx"][k], ref)
    # every Omega of the resonance gives the same verdict (the other axis decides it)
    assert len(set(out["stable_damped_approx"].tolist())) == 1
    assert (out["stable_first_approx"] == 0.0).all()


@settings(max_examples=80, deadline=None)
@given(c=stiffness, M=masses, ratio=hs.floats(1.2, 4.0), log_r=hs.floats(-14.0, -6.5),
       sign=hs.sampled_from([-1.0, 1.0]), typed=hs.booleans(), which=hs.sampled_from(["xi", "eta"]))
def test_near_an_undamped_resonance_P_is_right_to_its_own_ulps(c, M, ratio, log_r, sign, typed, which):
    # Omega = omega_j (1 + r), 1e-14 <= |r| <= 3e-7 (within NEAR_RESONANCE): c_j - M Omega^2 cancels all
    # but 2 |r| of its terms; P is right against 50 digits on the same inputs (the plain difference
    # loses about 1e-16 / |r|: 1e-2 at r = 1e-14)
    other = "eta" if which == "xi" else "xi"
    w = math.sqrt(c / M)
    Om = w * (1.0 + sign * 10.0 ** log_r)
    if typed:  # omega_j given: c_j = M omega_j^2
        p = {f"omega_{which}": w, f"zeta_{which}": 0.0, f"omega_{other}": w * math.sqrt(ratio), f"zeta_{other}": 0.0}
        axes = [axis_mp(M, omega=w, zeta=0.0), axis_mp(M, omega=w * math.sqrt(ratio), zeta=0.0)]
    else:
        p = {f"c_{which}": c, f"b_{which}": 0.0, f"c_{other}": c * ratio, f"b_{other}": 0.0}
        axes = [axis_mp(M, c=c, b=0.0), axis_mp(M, c=c * ratio, b=0.0)]
    out, status = closed(Omega=Om, M=M, **p)
    ref, size = receptance_mp(Om, M, axes)
    assert status[0] == st.OK
    assert abs(out["P_approx"][0] - ref) <= 1e-13 * size, (Om, out["P_approx"][0], ref)
    if out["stable_damped_approx"][0] == 1.0:
        assert ref < 0


# ----------------------------------------------------------------------------- boundaries of the rules
@settings(max_examples=60, deadline=None)
@given(cx=stiffness, ratio=hs.floats(1.05, 4.0), M=masses)
def test_on_omega_p_to_an_ulp_neither_undamped_verdict_is_set_by_rounding(cx, ratio, M):
    # Omega = omega_p = sqrt((omega_xi^2 + omega_eta^2) / 2), undamped: P = 0 there; computed the ways
    # a user computes it and one ulp either side, both verdicts are 0 (the boundary: strict rules)
    cy = cx * ratio
    wx, wy = math.sqrt(cx / M), math.sqrt(cy / M)
    ways = {math.sqrt(0.5 * (wx * wx + wy * wy)), math.sqrt((cx + cy) / (2.0 * M)), math.hypot(wx, wy) / math.sqrt(2.0),
            float(np.sqrt((wx**2 + wy**2) / 2))}
    Om = sorted({v for w in ways for v in ulps(w)})
    for p in (dict(c_xi=cx, c_eta=cy, b_xi=0.0, b_eta=0.0), dict(omega_xi=wx, omega_eta=wy, zeta_xi=0.0, zeta_eta=0.0)):
        out, status = closed(Omega=Om, M=M, **p)
        assert (status == st.OK).all()
        assert (out["stable_first_approx"] == 0.0).all(), (Om, out["stable_first_approx"])
        assert (out["stable_damped_approx"] == 0.0).all(), (Om, out["P_approx"], out["stable_damped_approx"])


@settings(max_examples=60, deadline=None)
@given(cx=stiffness, ratio=hs.floats(1.05, 4.0), M=masses, x=hs.floats(0.2, 2.5), zeta=hs.sampled_from([0.0, 0.02]))
def test_a_verdict_given_agrees_with_the_sign_of_P_in_50_digits(cx, ratio, M, x, zeta):
    # anywhere on the Omega axis: stable_damped_approx = 1 only where the exact P < 0, 0 only where
    # it is >= 0 or within rounding of 0; undamped, both rules give the same verdict
    cy = cx * ratio
    wx, wy = math.sqrt(cx / M), math.sqrt(cy / M)
    Om = x * wy
    out, status = closed(Omega=Om, M=M, omega_xi=wx, omega_eta=wy, zeta_xi=zeta, zeta_eta=zeta)
    if status[0] == st.SINGULAR:
        return
    ref, size = receptance_mp(Om, M, [axis_mp(M, omega=wx, zeta=zeta), axis_mp(M, omega=wy, zeta=zeta)])
    # the error bound the verdict uses does bound the error (it is 16 ulps of the terms over |D|^2)
    bound = ab._receptance(rows(Omega=Om, M=M, omega_xi=wx, omega_eta=wy, zeta_xi=zeta, zeta_eta=zeta)[0])[1]
    assert abs(out["P_approx"][0] - ref) <= bound <= 1e-8 * size
    if out["stable_damped_approx"][0] == 1.0:
        assert ref < 0
    elif ref < -1e-12 * size:
        pytest.fail(f"P = {float(ref)} < 0 beyond rounding, verdict 0")
    if zeta == 0.0:
        assert out["stable_damped_approx"][0] == out["stable_first_approx"][0]


# ----------------------------------------------------------------------------- through a scene
def scene(axes, fixed):
    return {"scene": {"name": "resonance", "model": "autobalancer", "outputs": list(CLOSED)},
            "axes": axes, "fixed": BASE | fixed}


def test_a_scene_at_an_undamped_resonance_is_singular_as_axis_values_and_as_fixed(in_tmp):
    c, M = 7919.0, 13.7
    w = math.sqrt(c / M)
    Om = ulps(w)
    # Omega on an axis, c_xi and M fixed (omega_xi = sqrt(c_xi / M) inside the model)
    ds = mechsweep.run(scene({"Omega": Om}, dict(M=M, c_xi=c, b_xi=0.0, c_eta=2 * c, zeta_eta=0.05)),
                       output="data/runs/a.h5")
    assert (ds["status"].values == st.SINGULAR).all() and np.isnan(ds["P_approx"].values).all()
    assert (ds["stable_first_approx"].values == 0).all()
    # Omega fixed, the stiffness on an axis: c_xi = M Omega^2 computed, and its neighbours
    cs = ulps(M * w * w)
    ds = mechsweep.run(scene({"c_xi": cs}, dict(Omega=w, M=M, b_xi=0.0, c_eta=2 * c, zeta_eta=0.05)),
                       output="data/runs/b.h5")
    assert (ds["status"].values == st.SINGULAR).all() and np.isnan(ds["stable_damped_approx"].values).all()
    # omega_xi on an axis equal to the fixed Omega, and Omega on an axis equal to a fixed omega_xi
    ds = mechsweep.run(scene({"omega_xi": Om}, dict(Omega=w, M=M, zeta_xi=0.0, omega_eta=2 * w, zeta_eta=0.05)),
                       output="data/runs/c.h5")
    assert (ds["status"].values == st.SINGULAR).all()
    ds = mechsweep.run(scene({"Omega": Om}, dict(omega_xi=w, M=M, zeta_xi=0.0, omega_eta=2 * w, zeta_eta=0.05)),
                       output="data/runs/d.h5")
    assert (ds["status"].values == st.SINGULAR).all()


# ----------------------------------------------------------------------------- the mass matrix
def accelerations_mp(z, p, tau):
    """x'', y'' of the scaled equations (module docstring of models/autobalancer.py), A1 = 0, in 50 digits."""
    with mp.workdps(50):
        x, y, g1, g2, xd, yd, w1, w2 = (mp.mpf(v) for v in z)
        mu, al0, iota, kx, ky, dx, dy, eh = (mp.mpf(p[i]) for i in (ab.IP_MU, ab.IP_ALPHA0, ab.IP_IOTA, ab.IP_KX,
                                                                     ab.IP_KY, ab.IP_DX, ab.IP_DY, ab.IP_EH))
        inv = 1 / iota
        s1, k1, s2, k2 = mp.sin(g1), mp.cos(g1), mp.sin(g2), mp.cos(g2)
        q1, q2 = -eh * (w1 - 1), -eh * (w2 - 1)
        rx = -kx * x - dx * xd + al0 * mp.cos(tau) + w1**2 * k1 + w2**2 * k2 + inv * (s1 * q1 + s2 * q2)
        ry = -ky * y - dy * yd + al0 * mp.sin(tau) + w1**2 * s1 + w2**2 * s2 - inv * (k1 * q1 + k2 * q2)
        k11, k12, k22 = mu - inv * (s1**2 + s2**2), inv * (s1 * k1 + s2 * k2), mu - inv * (k1**2 + k2**2)
        det = k11 * k22 - k12**2
        return (k22 * rx - k12 * ry) / det, (k11 * ry - k12 * rx) / det


@pytest.mark.parametrize("gap", [1e-4, 1e-8, 1e-12, 1e-14])
def test_the_accelerations_round_off_near_a_singular_mass_matrix_is_within_MASS_ERROR_u_over_gap(gap):
    # the constant behind ILL_CONDITIONED: pendulums aligned or opposite (the smallest eigenvalue)
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(60):
        iota = rng.uniform(1.0, 3.0)
        p = np.zeros(ab.NP)
        p[[ab.IP_MU, ab.IP_IOTA, ab.IP_ALPHA0, ab.IP_KX, ab.IP_KY, ab.IP_DX, ab.IP_DY, ab.IP_EH]] = (
            2.0 / iota * (1.0 + gap), iota, rng.uniform(0, 2), rng.uniform(0, 5), rng.uniform(0, 5), 0.1, 0.1,
            rng.uniform(0, 1))
        g = rng.uniform(0, 2 * math.pi)
        z = np.array([rng.normal(), rng.normal(), g, g + rng.choice([0.0, math.pi]), rng.normal(), rng.normal(),
                      1 + 0.1 * rng.normal(), 1 + 0.1 * rng.normal()])
        tau = rng.uniform(0, 6)
        got = ab.accelerations(tau, *z, p)[:2]
        ref = accelerations_mp(z, p, tau)
        err = max(abs(float(got[0] - ref[0])), abs(float(got[1] - ref[1]))) / float(max(abs(ref[0]), abs(ref[1])))
        # the exact gap of these float inputs
        true_gap = float(1 - 2 / (mp.mpf(p[ab.IP_MU]) * mp.mpf(p[ab.IP_IOTA])))
        worst = max(worst, err * true_gap / ab.UNIT_ROUNDOFF)
    assert worst <= ab.MASS_ERROR, worst
    assert worst >= 1.0  # the bound is not loose by orders: the error does grow like 1 / gap


def test_a_mass_matrix_singular_within_rounding_is_infeasible_and_near_it_ill_conditioned():
    m, a = 1.0, 0.1
    base = dict(Omega=25.0, m=m, a=a, A0=0.19, h=0.02, omega_xi=20.0, omega_eta=30.0, zeta_xi=0.05, zeta_eta=0.05)
    # M > 2 m and I_B >= m a^2 within its slack, yet M I_B < 2 m^2 a^2 (indefinite) or equal to rounding
    P = rows(**base, M=[2.0 * (1 + 1e-12), 2.0 * (1 + 1e-15)], I_B=[m * a * a * (1 - 1e-10), m * a * a])
    out, status, _, _ = evaluating.evaluate(ab.SPEC, P, ab.SPEC.closure(("theta", "floquet_max")), quiet=True,
                                        rtol=1e-8, atol=1e-10)
    assert (status == st.INFEASIBLE).all(), status
    assert all(np.isnan(v).all() for v in out.values())
    # positive definite but the accelerations' round-off 4 u / gap above rtol: no integration
    gaps = np.array([1e-9, 3e-8, 1e-6])  # 4 u / gap: 4e-7, 1.5e-8 (above rtol), 4e-10
    P = rows(**base, M=2.0 * (1 + gaps), I_B=m * a * a)
    out, status, ns, _ = evaluating.evaluate(ab.SPEC, P, ab.SPEC.closure(("theta", "floquet_max")), quiet=True,
                                         rtol=1e-8, atol=1e-10)
    assert status.tolist()[:2] == [st.ILL_CONDITIONED] * 2 and status[2] == st.OK, status
    assert np.isnan(out["floquet_max"][:2]).all() and (ns[:2] == 0).all() and np.isfinite(out["floquet_max"][2])
    np.testing.assert_allclose(out["theta"], math.acos(-0.19 / 0.2))  # the closed forms are kept


def test_m_k_without_its_parameters_leaves_the_points_status_to_the_other_outputs():
    # m4, S4, m5, S_k absent (NaN, as the evaluate API leaves them; a scene asking for m_k must give
    # them): m_k is NaN and says nothing of the point, which keeps the status theta gives it
    P = rows(**BASE, Omega=[10.0, 30.0, 0.5], M=2.0, omega_xi=20.0, omega_eta=25.0, zeta_xi=0.05, zeta_eta=0.05)
    alone, status_alone, _, _ = evaluating.evaluate(ab.SPEC, P, ab.SPEC.closure(("theta",)), quiet=True)
    both, status_both, _, _ = evaluating.evaluate(ab.SPEC, P, ab.SPEC.closure(("theta", "m_k")), quiet=True)
    assert np.isnan(both["m_k"]).all()
    assert np.array_equal(both["theta"], alone["theta"], equal_nan=True)
    assert status_both.tolist() == status_alone.tolist()
    assert st.OUT_OF_RANGE not in status_both.tolist()
