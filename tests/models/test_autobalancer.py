"""Autobalancer model: the equations against an independent Lagrange derivation, the analytic
Jacobian against finite differences, Floquet against direct simulation on both sides of every
stability boundary, the classic isotropic result, the light-pendulum limit of the first
approximation, the unbalanceable case and the statuses of stiff corners."""
import math

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

import mechsweep
from mechsweep import models, status as st
from tests.reference import autobalancer_kernels as K  # the hand-written kernels: rhs, Jacobian, variational system
from mechsweep.models import autobalancer as ab
from mechsweep.scene import SceneError, Solver, load_scene
from tests import evaluating

TAUS = (0.0, 0.37, 1.9, 3.3, 5.1)


def solver(**kw):
    return Solver.for_model(ab.SPEC, **kw)


def evaluate(outputs, slv=None, **params):
    """Run SPEC.evaluate on the broadcast parameters; returns (outputs dict, status, n_steps)."""
    P = evaluating.rows(ab.SPEC, **params)
    out, status, ns, _ = evaluating.evaluate(ab.SPEC, P, ab.SPEC.closure(outputs), slv or solver())
    return out, status, ns


def light(eps, zeta=0.02, omega_eta=1.5, kappa=1.0, alpha0=1.0):
    """Pendulum mass ratio 2 m / M = eps; A0 = alpha0 m a and h = kappa m a^2 (1 rad/s) scale with m."""
    m = eps / 2
    return dict(M=1.0, m=m, a=0.1, I_B=m * 0.01, A0=alpha0 * m * 0.1, h=kappa * m * 0.01,
                omega_xi=1.0, omega_eta=omega_eta, zeta_xi=zeta, zeta_eta=zeta)


def random_p(rng, A1=True):
    """Scaled parameters of a random mechanism (SI values drawn, then scaled like evaluate does)."""
    m, a = rng.uniform(0.05, 0.3), rng.uniform(0.05, 0.2)
    return K.scaled_parameters(
        Omega=rng.uniform(0.5, 3), M=rng.uniform(2.5, 10) * m, m=m, a=a, I_B=m * a * a * rng.uniform(1, 2),
        A0=rng.uniform(0, 2) * m * a, A1=rng.uniform(-1, 1) * m * a if A1 else 0.0,
        lam=rng.uniform(0.1, 0.6) if A1 else 0.0, c_xi=rng.uniform(1, 50), c_eta=rng.uniform(1, 50),
        b_xi=rng.uniform(0, 2), b_eta=rng.uniform(0, 2), h=rng.uniform(0, 0.05) * m * a * a, th1=0.0, th2=0.0)


# ----------------------------------------------------------------------------- the equations
@pytest.mark.parametrize("alpha0", [0.3, 1.0, 1.9])
def test_exact_balanced_state_satisfies_the_equations(alpha0):
    """Platform at rest, gamma_i = tau + Theta_i, Theta = arccos(-A0 / 2 m a), A1 = 0: eq. (4), (5), (8)."""
    theta = math.acos(-alpha0 / 2)
    p = np.zeros(ab.NP)
    p[[ab.IP_MU, ab.IP_ALPHA0, ab.IP_IOTA, ab.IP_KX, ab.IP_KY, ab.IP_DX, ab.IP_DY, ab.IP_EH]] = (
        12.0, alpha0, 1.3, 7.0, 3.0, 0.4, 0.2, 0.8)
    dz = np.empty(8)
    for tau in TAUS + (1234.5,):
        z = np.array([0, 0, tau + theta, tau - theta, 0, 0, 1, 1], float)
        K.rhs(tau, z, p, dz)
        # every term of the equations is O(alpha0) ~ O(1) in scaled units
        assert np.abs(dz[4:]).max() < 1e-14 * max(1.0, tau / 10), (tau, dz[4:])
        assert (dz[:4] == z[4:]).all()
    # and a wrong angle does not
    z = np.array([0, 0, theta + 0.1, -theta, 0, 0, 1, 1], float)
    K.rhs(0.0, z, p, dz)
    assert np.abs(dz[4:]).max() > 1e-3


@pytest.fixture(scope="module")
def lagrange():
    """Equations of motion derived by sympy from the positions of every mass (module docstring)."""
    t = sp.symbols("t")
    names = "Om Mp m3 S3 m4 S4 J4 m5 mk Sk l3 l4 m a JP cx cy bx by h".split()
    S = dict(zip(names, sp.symbols(names)))
    q = [sp.Function(n)(t) for n in ("xi", "eta", "g1", "g2")]
    xi, eta, g1, g2 = q
    phi = S["Om"] * t
    psi = -sp.asin(S["l3"] / S["l4"] * sp.sin(phi))  # counter-clockwise, cos psi > 0
    e = lambda ang: sp.Matrix([sp.cos(ang), sp.sin(ang)])  # noqa: E731
    B = sp.Matrix([xi, eta])
    D = B + S["l3"] * e(phi)
    bodies = [(S["Mp"], B), (S["m3"], B + S["S3"] * e(phi)), (S["m4"], D + S["S4"] * e(psi)),
              (S["m5"], D + S["l4"] * e(psi)), (S["mk"], D - S["Sk"] * e(psi)),
              (S["m"], B + S["a"] * e(g1)), (S["m"], B + S["a"] * e(g2))]
    T = sum(mass * (r.diff(t).T * r.diff(t))[0] for mass, r in bodies) / 2
    T += S["J4"] * psi.diff(t) ** 2 / 2 + S["JP"] * (g1.diff(t) ** 2 + g2.diff(t) ** 2) / 2
    V = (S["cx"] * xi**2 + S["cy"] * eta**2) / 2
    R = (S["bx"] * xi.diff(t) ** 2 + S["by"] * eta.diff(t) ** 2
         + S["h"] * ((g1.diff(t) - S["Om"]) ** 2 + (g2.diff(t) - S["Om"]) ** 2)) / 2
    L = T - V
    eqs = [sp.diff(L.diff(qi.diff(t)), t) - L.diff(qi) + R.diff(qi.diff(t)) for qi in q]
    qs, qd, qdd = sp.symbols("xi eta g1 g2"), sp.symbols("xid etad g1d g2d"), sp.symbols("xidd etadd g1dd g2dd")
    sub = [(q[i].diff(t, 2), qdd[i]) for i in range(4)] + [(q[i].diff(t), qd[i]) for i in range(4)]
    sub += [(q[i], qs[i]) for i in range(4)]
    eqs = [sp.expand(eq.subs(sub)) for eq in eqs]
    mass = sp.Matrix([[eq.diff(x) for x in qdd] for eq in eqs])
    force = sp.Matrix([eq.subs({x: 0 for x in qdd}) for eq in eqs])
    args = [t, *qs, *qd, *[S[n] for n in names]]
    return names, sp.lambdify(args, mass, "numpy"), sp.lambdify(args, force, "numpy")


def test_rhs_against_independent_lagrange_derivation(lagrange):
    """Accelerations at random states and random mechanisms (A1 != 0 included, which checks
    the sign of the A1 term in the eta equation) against sympy's Lagrange equations."""
    names, mass, force = lagrange
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(40):
        v = dict(Om=rng.uniform(0.5, 20), Mp=rng.uniform(1, 10), m3=rng.uniform(0, 1), S3=rng.uniform(0, 0.1),
                 m4=rng.uniform(0, 1), S4=rng.uniform(0, 0.3), J4=rng.uniform(0, 0.01), m5=rng.uniform(0, 1),
                 mk=rng.uniform(0, 1), Sk=rng.uniform(0, 0.2), l3=rng.uniform(0.02, 0.1), l4=rng.uniform(0.15, 0.4),
                 m=rng.uniform(0.01, 0.5), a=rng.uniform(0.02, 0.2), JP=rng.uniform(0, 0.01), cx=rng.uniform(10, 1e4),
                 cy=rng.uniform(10, 1e4), bx=rng.uniform(0, 50), by=rng.uniform(0, 50), h=rng.uniform(0, 1))
        t = rng.uniform(0, 10)
        q = np.r_[rng.normal(0, 0.05, 2), rng.uniform(-7, 7, 2)]
        qd = np.r_[rng.normal(0, 0.5, 2), v["Om"] * rng.uniform(0.5, 1.5, 2)]
        args = [t, *q, *qd, *[v[n] for n in names]]
        ref = np.linalg.solve(np.array(mass(*args), float), -np.array(force(*args), float).ravel())
        # our parameters from the same mechanism
        M = v["Mp"] + v["m3"] + v["m4"] + v["m5"] + v["mk"] + 2 * v["m"]
        A0 = v["m3"] * v["S3"] + (v["m4"] + v["m5"] + v["mk"]) * v["l3"]
        A1 = v["m4"] * v["S4"] + v["m5"] * v["l4"] - v["mk"] * v["Sk"]
        I_B = v["JP"] + v["m"] * v["a"] ** 2
        Om, a = v["Om"], v["a"]
        p = K.scaled_parameters(Om, M, v["m"], a, I_B, A0, A1, v["l3"] / v["l4"], v["cx"], v["cy"], v["bx"],
                                 v["by"], v["h"], 0.0, 0.0)
        z = np.r_[q[:2] / a, q[2:], qd[:2] / (a * Om), qd[2:] / Om]
        dz = np.empty(8)
        K.rhs(Om * t, z, p, dz)
        ours = np.r_[dz[4:6] * a * Om**2, dz[6:] * Om**2]
        scale = np.abs(ref).max()
        worst = max(worst, np.abs(ours - ref).max() / scale)
    assert worst < 1e-11, f"largest relative difference {worst:.3g}"


def test_scan_sign_of_A1_term_matters(lagrange):
    """The scan's opposite A1 sign in the eta equation would fail the comparison above."""
    names, mass, force = lagrange
    v = dict(Om=5.0, Mp=2.0, m3=0.0, S3=0.0, m4=0.5, S4=0.1, J4=0.0, m5=1.0, mk=0.0, Sk=0.1, l3=0.05, l4=0.2,
             m=0.1, a=0.1, JP=0.0, cx=100.0, cy=100.0, bx=0.0, by=0.0, h=0.0)
    args = [0.3, 0, 0, 1.0, -1.0, 0, 0, 5.0, 5.0, *[v[n] for n in names]]
    ref = np.linalg.solve(np.array(mass(*args), float), -np.array(force(*args), float).ravel())
    M = 2.0 + 1.5 + 0.2
    A1 = 0.5 * 0.1 + 1.0 * 0.2
    A0 = 1.5 * 0.05
    for sign, expect_match in ((1.0, True), (-1.0, False)):
        p = K.scaled_parameters(5.0, M, 0.1, 0.1, 0.001, A0, A1, sign * 0.25, 100.0, 100.0, 0, 0, 0, 0, 0)
        dz = np.empty(8)
        K.rhs(5.0 * 0.3, np.array([0, 0, 1.0, -1.0, 0, 0, 1, 1.0]), p, dz)
        assert np.allclose(dz[5] * 0.1 * 25, ref[1], rtol=1e-10) == expect_match


def test_docstring_equations_match_the_lagrange_derivation(lagrange):
    """The module docstring's xi and eta equations, read with the sign they print before
    d^2/dt^2 [...], against sympy's Lagrange equations at random states and accelerations."""
    import re

    names, mass, force = lagrange
    doc = ab.__doc__
    signs = {}
    for q, trig in (("xi", "cos"), ("eta", "sin")):
        found = re.search(rf"^\s*{q}:\s+M {q}'' ([+-]) d\^2/dt\^2 \[A0 {trig} phi \+ A1 {trig} psi \+ m a sum "
                          rf"{trig} gamma_i\] = -c_{q} {q} - b_{q} {q}'$", doc, re.M)
        assert found, f"the docstring's {q} equation is not in the form the test reads"
        signs[q] = 1.0 if found.group(1) == "+" else -1.0
    rng = np.random.default_rng(3)
    for _ in range(20):
        v = dict(Om=rng.uniform(0.5, 20), Mp=rng.uniform(1, 10), m3=rng.uniform(0, 1), S3=rng.uniform(0, 0.1),
                 m4=rng.uniform(0, 1), S4=rng.uniform(0, 0.3), J4=rng.uniform(0, 0.01), m5=rng.uniform(0, 1),
                 mk=rng.uniform(0, 1), Sk=rng.uniform(0, 0.2), l3=rng.uniform(0.02, 0.1), l4=rng.uniform(0.15, 0.4),
                 m=rng.uniform(0.01, 0.5), a=rng.uniform(0.02, 0.2), JP=rng.uniform(0, 0.01), cx=rng.uniform(10, 1e4),
                 cy=rng.uniform(10, 1e4), bx=rng.uniform(0, 50), by=rng.uniform(0, 50), h=rng.uniform(0, 1))
        t = rng.uniform(0, 10)
        q, qd, qdd = rng.normal(0, 0.05, 4), rng.normal(0, 0.5, 4), rng.normal(0, 5.0, 4)
        q[2:], qd[2:] = rng.uniform(-7, 7, 2), v["Om"] * rng.uniform(0.5, 1.5, 2)
        args = [t, *q, *qd, *[v[n] for n in names]]
        residual = np.array(mass(*args), float) @ qdd + np.array(force(*args), float).ravel()  # Lagrange: = 0
        M = v["Mp"] + v["m3"] + v["m4"] + v["m5"] + v["mk"] + 2 * v["m"]
        A0 = v["m3"] * v["S3"] + (v["m4"] + v["m5"] + v["mk"]) * v["l3"]
        A1 = v["m4"] * v["S4"] + v["m5"] * v["l4"] - v["mk"] * v["Sk"]
        Om, lam, ma = v["Om"], v["l3"] / v["l4"], v["m"] * v["a"]
        phi = Om * t
        spsi = -lam * math.sin(phi)
        cpsi = math.sqrt(1 - spsi * spsi)
        dpsi = -lam * Om * math.cos(phi) / cpsi
        ddpsi = (lam * Om**2 * math.sin(phi) + dpsi**2 * spsi) / cpsi
        g, dg, ddg = q[2:], qd[2:], qdd[2:]
        # d^2/dt^2 of the bracket: A0 e(phi) + A1 e(psi) + m a sum e(gamma_i), e = (cos, sin)
        dd_cos = (-A0 * Om**2 * math.cos(phi) - A1 * (ddpsi * spsi + dpsi**2 * cpsi)
                  - ma * np.sum(ddg * np.sin(g) + dg**2 * np.cos(g)))
        dd_sin = (-A0 * Om**2 * math.sin(phi) + A1 * (ddpsi * cpsi - dpsi**2 * spsi)
                  + ma * np.sum(ddg * np.cos(g) - dg**2 * np.sin(g)))
        xi_doc = M * qdd[0] + signs["xi"] * dd_cos + v["cx"] * q[0] + v["bx"] * qd[0]
        eta_doc = M * qdd[1] + signs["eta"] * dd_sin + v["cy"] * q[1] + v["by"] * qd[1]
        scale = M * np.abs(qdd[:2]).max() + abs(dd_cos) + abs(dd_sin)
        assert xi_doc - residual[0] == pytest.approx(0.0, abs=1e-12 * scale), "xi"
        assert eta_doc - residual[1] == pytest.approx(0.0, abs=1e-12 * scale), "eta"


def test_analytic_jacobian_against_finite_differences():
    rng = np.random.default_rng(3)
    J = np.empty((8, 8))
    fp, fm = np.empty(8), np.empty(8)
    for k in range(20):
        p = random_p(rng, A1=k % 2 == 0)
        tau = rng.uniform(0, 7)
        z = np.r_[rng.normal(0, 0.3, 2), rng.uniform(-4, 4, 2), rng.normal(0, 0.5, 2), rng.uniform(0, 2, 2)]
        K.jacobian(tau, z, p, J)
        fd = np.empty((8, 8))
        for c in range(8):
            h = 1e-6 * max(1.0, abs(z[c]))
            zp, zm = z.copy(), z.copy()
            zp[c] += h
            zm[c] -= h
            K.rhs(tau, zp, p, fp)
            K.rhs(tau, zm, p, fm)
            fd[:, c] = (fp - fm) / (2 * h)
        assert np.abs(J - fd).max() <= 1e-7 * max(1.0, np.abs(J).max()), (k, np.abs(J - fd).max())
    # the variational rhs applies the same Jacobian at the balanced state, column by column
    p[ab.IP_TH1], p[ab.IP_TH2], p[ab.IP_ALPHA1] = 2.0, -2.0, 0.0
    Phi = rng.normal(size=(8, 8))
    dY = np.empty(64)
    K.variational_rhs(0.7, Phi.T.ravel().copy(), p, dY)
    K.jacobian(0.7, np.array([0, 0, 2.7, -1.3, 0, 0, 1, 1.0]), p, J)
    np.testing.assert_allclose(dY.reshape(8, 8).T, J @ Phi, rtol=1e-13, atol=1e-13)


def test_jitted_equals_python():
    rng = np.random.default_rng(5)
    a, b = np.empty(8), np.empty(8)
    for _ in range(10):
        p = random_p(rng)
        z = rng.normal(size=8)
        tau = rng.uniform(0, 10)
        K.rhs(tau, z, p, a)
        K.rhs.py_func(tau, z, p, b)
        np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-15)
        assert ab.conrod_terms(math.sin(tau), math.cos(tau), 0.3) == pytest.approx(ab.conrod_terms.py_func(math.sin(tau), math.cos(tau), 0.3), rel=1e-14)
        assert ab.wrap(tau * 7) == pytest.approx(ab.wrap.py_func(tau * 7), abs=1e-14)


# ----------------------------------------------------------------------------- stability
def test_floquet_and_simulation_agree_on_both_sides_of_every_boundary():
    """Light pendulums (2 m / M = 0.005): points on either side of omega_xi, omega_p, omega_eta
    (zeta = 0.02, where P = 0 lies within 0.1 % of them), and, with zeta = 0.1, on either side
    of the damped roots P = 0 (1.0163, 1.3136, 1.4324 rad/s), where the undamped rule is wrong at
    Omega = 1.47 (between the P root and omega_eta = 1.5). Floquet boundaries for this case:
    1.0299, 1.2769, 1.5643 rad/s (zeta 0.02) and 1.022, 1.3169, 1.4431 rad/s (zeta 0.1)."""
    cases = [(0.02, [0.9, 1.1, 1.2, 1.36, 1.45, 1.7], [0, 1, 1, 0, 0, 1]),
             (0.1, [0.95, 1.1, 1.36, 1.47, 1.7], [0, 1, 0, 1, 1])]
    outs = ("stable_floquet", "stable_sim", "stable_damped_approx", "stable_first_approx")
    for zeta, Om, expect in cases:
        out, status, ns = evaluate(outs, solver(horizon_revolutions=1000.0), Omega=Om, **light(0.005, zeta))
        msg = f"zeta={zeta}: Omega={Om} " + str({k: v.tolist() for k, v in out.items()})
        assert out["stable_floquet"].tolist() == expect, msg
        assert out["stable_sim"].tolist() == expect, msg
        assert out["stable_damped_approx"].tolist() == expect, msg
        assert (ns > 0).all()
        assert set(status.tolist()) <= {st.OK, st.NO_EVENT}  # no_event: settling_time not asked
    # the undamped first approximation misses the damped case's 1.47 rad/s point
    out, _, _ = evaluate(("stable_first_approx",), Omega=1.47, **light(0.005, 0.1))
    assert out["stable_first_approx"][0] == 0.0
    # ... where the multiplier is 0.9948: too slow to settle in the default 300 revolutions,
    # the simulation says so instead of guessing
    out, status, _ = evaluate(("stable_sim", "floquet_max"), Omega=1.47, **light(0.005, 0.1))
    assert status[0] == st.UNDECIDED and np.isnan(out["stable_sim"][0])
    assert out["floquet_max"][0] == pytest.approx(0.9948, abs=1e-4)


def test_isotropic_platform_stable_above_natural_frequency_only():
    """The classic auto-balancer result (omega_xi = omega_eta = 1 rad/s, zeta = 0.05)."""
    Om = np.array([0.5, 0.8, 1.3, 2.0, 5.0])
    out, status, _ = evaluate(("stable_floquet", "stable_sim", "residual_amplitude", "floquet_max"),
                              Omega=Om, **light(0.01, zeta=0.05, omega_eta=1.0))
    assert out["stable_floquet"].tolist() == [0, 0, 1, 1, 1], out["floquet_max"]
    assert out["stable_sim"].tolist() == [0, 0, 1, 1, 1]
    assert (status == st.OK).all()
    # balanced: the platform comes to rest; unstable: it keeps vibrating
    assert out["residual_amplitude"][2:].max() < 1e-8 < 1e-5 < out["residual_amplitude"][:2].min()


# The docstring's example of a finite basin of attraction (models/autobalancer.py, "What the kick
# verdict means"): 2 m / M = 0.087, zeta_eta = 0, omega_xi < Omega < omega_eta.
FINITE_BASIN = dict(Omega=22.28, M=23.0, m=1.0, a=0.1, I_B=0.01553, A0=0.01257, h=0.2665, omega_xi=20.0,
                    omega_eta=24.86, zeta_xi=0.0364, zeta_eta=0.0)


def test_kick_verdict_is_the_fate_of_one_kick_in_a_finite_basin():
    """Floquet says stable (multiplier 0.99881) and stable_sim = 0 with status ok: not a contradiction.
    The 0.1 rad kick leaves the basin for a coexisting steady motion (the platform keeps vibrating
    at 0.074 m, the pendulums far from their balanced angles) and stays there; a 0.01 rad kick
    comes back, given a horizon long enough for a multiplier this close to 1 (undecided at the
    default 300 revolutions, 0.9988^300 = 0.70)."""
    import re

    # the point the module docstring describes is this one
    doc = " ".join(ab.__doc__.split())
    example = doc[doc.index("What the kick verdict means"):]
    for name, value in FINITE_BASIN.items():
        assert float(re.search(rf"\b{name} = ([0-9.]+)", example).group(1)) == value, name
    assert "floquet_max = 0.99881" in example
    outs = ("stable_floquet", "stable_sim", "residual_amplitude", "floquet_max")  # the kernel the tests above compile
    verdict = {}
    for kick in (0.1, 0.01):
        for horizon in (300.0, 2000.0):
            slv = solver(rtol=1e-8, atol=1e-10, perturbation=kick, horizon_revolutions=horizon)
            out, status, _ = evaluate(outs, slv, **FINITE_BASIN)
            verdict[kick, horizon] = (out["stable_sim"][0], int(status[0]), out["residual_amplitude"][0])
            assert out["stable_floquet"][0] == 1.0
            assert out["floquet_max"][0] == pytest.approx(0.99881, abs=1e-5)
    # the 0.1 rad kick: left and stayed away, at the default horizon and at 2000 revolutions, status ok
    for horizon in (300.0, 2000.0):
        sim, status, residual = verdict[0.1, horizon]
        assert sim == 0.0 and status == st.OK, verdict
        assert residual == pytest.approx(0.074, rel=0.01)  # a steady vibration, not the balanced state
    # the 0.01 rad kick: came back (the platform at rest to 1e-4 m), undecided within 300 revolutions
    assert np.isnan(verdict[0.01, 300.0][0]) and verdict[0.01, 300.0][1] == st.UNDECIDED, verdict
    sim, status, residual = verdict[0.01, 2000.0]
    assert sim == 1.0 and status == st.OK and residual < 1e-4, verdict


def floquet_boundaries(eps, zeta=0.02):
    grid = np.linspace(0.6, 2.6, 101)

    def f(Om):
        return evaluate(("floquet_max",), Omega=Om, **light(eps, zeta))[0]["floquet_max"] - 1.0

    values = f(grid)
    assert np.isfinite(values).all()
    idx = np.nonzero(np.diff(np.sign(values)))[0]
    return np.array([brentq(lambda x: f(x)[0], grid[i], grid[i + 1], xtol=1e-9) for i in idx])


def test_light_pendulum_limit_of_the_floquet_boundaries():
    """As 2 m / M -> 0 (A0 = m a, h = m a^2 x 1 rad/s, zeta = 0.02, omega_xi = 1, omega_eta = 1.5)
    the Floquet boundaries approach the first approximation's P = 0 roots 1.00064, 1.27579,
    1.49783 rad/s (omega_xi, omega_p, omega_eta = 1, 1.27475, 1.5). Measured relative distances
    (lower, omega_p, upper boundary), each shifted upwards, about linear in the mass ratio:
      2m/M = 0.05   : 0.246,  0.0093, 0.409   (boundaries 1.2466, 1.2877, 2.1101 rad/s)
      2m/M = 0.02   : 0.124,  0.0036, 0.187
      2m/M = 0.01   : 0.062,  0.0018, 0.093
      2m/M = 0.005  : 0.029,  0.0009, 0.044
      2m/M = 0.002  : 0.0103, 0.00036, 0.0155
      2m/M = 0.0005 : 0.0024, 0.00009, 0.0036
    so the source's rule is good to ~5 eps (lower) and ~9 eps (upper) for a mass ratio eps."""
    def P(Om):
        return K.receptance_sum(Om, 1.0, 1.0, 2.25, 0.04, 0.06)

    roots = np.array([brentq(P, lo, hi, xtol=1e-12) for lo, hi in ((0.9, 1.1), (1.2, 1.35), (1.4, 1.55))])
    np.testing.assert_allclose(roots, [1.00064, 1.27579, 1.49783], atol=1e-5)
    dist = {}
    for eps in (0.02, 0.002, 0.0005):
        b = floquet_boundaries(eps)
        assert b.size == 3, (eps, b)
        dist[eps] = (b - roots) / roots
    msg = {k: np.round(v, 5).tolist() for k, v in dist.items()}
    assert (dist[0.0005] > 0).all() and np.abs(dist[0.0005]).max() < 0.005, msg
    assert np.allclose(dist[0.02], [0.1244, 0.0036, 0.1866], atol=0.002), msg
    # linear approach: 40x lighter -> about 40x closer (between 30x and 60x)
    ratio = dist[0.02] / dist[0.0005]
    assert ((ratio > 30) & (ratio < 60)).all(), (ratio, msg)


def test_unbalanceable_pendulums_settle_opposite_the_unbalance():
    """A0 = 3 m a > 2 m a, isotropic platform, above resonance: gamma_i - Omega t -> pi and the
    residual is the response to the reduced unbalance (A0 - 2 m a) Omega^2 |H|."""
    params = light(0.01, zeta=0.05, omega_eta=1.0, alpha0=3.0)
    Om = np.array([2.0, 5.0])
    outs = ("balanceable", "theta", "stable_sim", "floquet_max", "residual_amplitude",
            "phase_error1_history", "phase_error2_history")
    out, status, _ = evaluate(outs, Omega=Om, **params)
    assert (status == st.NOT_BALANCEABLE).all()
    assert (out["balanceable"] == 0).all()
    for k in ("theta", "stable_sim", "floquet_max"):
        assert np.isnan(out[k]).all()
    for k in ("phase_error1_history", "phase_error2_history"):  # measured from pi when A0 > 2 m a
        late = np.abs(out[k][:, -60:]).max(axis=1)
        assert (late < 0.03).all(), late  # the damping lag 2 zeta Omega / (Omega^2 - 1) stays
        assert np.abs(out[k][:, 0]).min() == pytest.approx(0.1)
    m, a = params["m"], params["a"]
    expect = (params["A0"] - 2 * m * a) * Om**2 / np.abs(1.0 - Om**2 + 1j * 0.1 * Om)
    np.testing.assert_allclose(out["residual_amplitude"], expect, rtol=2e-3)
    # the residual alone needs no balanced state: status ok
    out, status, _ = evaluate(("residual_amplitude", "balanceable"), Omega=Om, **params)
    assert (status == st.OK).all() and np.isfinite(out["residual_amplitude"]).all()


def test_uncorrected_conrod_leaves_a_residual():
    """A1 != 0: no balanced state (NOT_BALANCEABLE for balanced-state outputs), and a balancing
    residual that grows in proportion to A1 (higher harmonics the pendulums cannot cancel)."""
    base = light(0.01, zeta=0.05, omega_eta=1.0) | dict(l3=0.05, l4=0.2)
    A1 = np.array([0.0, 2e-5, 4e-5])
    out, status, _ = evaluate(("residual_amplitude",), Omega=2.0, A1=A1, **base)
    assert (status == st.OK).all()
    r = out["residual_amplitude"]
    assert r[0] < 1e-9 < r[1]
    assert r[2] / r[1] == pytest.approx(2.0, rel=0.05)
    out, status, _ = evaluate(("residual_amplitude", "stable_sim", "theta"), Omega=2.0, A1=A1, **base)
    assert status.tolist() == [st.OK, st.NOT_BALANCEABLE, st.NOT_BALANCEABLE]
    assert np.isnan(out["stable_sim"][1:]).all() and np.isfinite(out["residual_amplitude"]).all()


def test_stiff_corners_end_with_a_status_not_a_wrong_verdict():
    """Platform 100x Omega, 2m/M = 2e-4, h up to 1e4: the explicit integrator spends its step budget
    at the stability limit (stiff) or cannot decide; a verdict it does give agrees with Floquet."""
    m = 1e-4
    h = np.array([m * 0.01, 1.0, 1e4])
    params = dict(M=1.0, m=m, a=0.1, I_B=m * 0.01, A0=m * 0.1, omega_xi=100.0, omega_eta=150.0,
                  zeta_xi=0.02, zeta_eta=0.02)
    out, status, ns = evaluate(("stable_floquet", "stable_sim"), solver(max_steps=20_000), Omega=1.0, h=h, **params)
    assert set(status.tolist()) <= {st.MAX_STEPS, st.STIFF, st.STEP_UNDERFLOW, st.UNDECIDED}, status
    assert (status[1:] == st.STIFF).all() and np.isnan(out["stable_sim"][1:]).all()  # was max_steps
    decided = np.isfinite(out["stable_sim"])
    assert (out["stable_sim"][decided] == out["stable_floquet"][decided]).all()
    assert (ns <= 3 * 20_000 + 10).all()  # Floquet, simulation, reproducibility check: each its budget


def test_degenerate_ends_are_not_balanceable_for_stability():
    """A0 = 0 (a family of balanced states) and A0 = 2 m a (Theta = pi, two solutions merge):
    theta is given, the stability outputs are NOT_BALANCEABLE."""
    params = light(0.01)
    ends = dict(A0=[0.0, 2.0 * params["m"] * params["a"]])
    out, status, _ = evaluate(("theta", "floquet_max"), Omega=2.0, **(params | ends))
    assert (status == st.NOT_BALANCEABLE).all()
    np.testing.assert_allclose(out["theta"], [math.pi / 2, math.pi])
    assert np.isnan(out["floquet_max"]).all()
    out, status, _ = evaluate(("theta", "balanceable"), Omega=2.0, **(params | ends))
    assert (status == st.OK).all() and (out["balanceable"] == 1).all()


# ----------------------------------------------------------------------------- closed forms, domain
def test_closed_forms_and_both_platform_parametrisations():
    M, Om = 2.0, np.array([0.5, 1.2, 1.45, 1.7, 2.5])
    a = dict(M=M, m=0.01, a=0.1, I_B=1e-4, A0=1e-3, h=1e-4)
    outs = ("omega_p", "stable_first_approx", "P_approx", "stable_damped_approx", "theta", "balanceable")
    o1, s1, _ = evaluate(outs, Omega=Om, omega_xi=1.0, omega_eta=1.5, zeta_xi=0.0, zeta_eta=0.0, **a)
    o2, s2, _ = evaluate(outs, Omega=Om, c_xi=M * 1.0, c_eta=M * 2.25, b_xi=0.0, b_eta=0.0, **a)
    o3, _, _ = evaluate(outs, Omega=Om, omega_xi=1.5, omega_eta=1.0, zeta_xi=0.0, zeta_eta=0.0, **a)  # swapped axes
    for k in outs:
        np.testing.assert_allclose(o1[k], o2[k], rtol=1e-14)
        np.testing.assert_allclose(o1[k], o3[k], rtol=1e-14)
    assert (s1 == st.OK).all() and (s2 == st.OK).all()
    np.testing.assert_allclose(o1["omega_p"], math.sqrt(1.625))
    assert o1["stable_first_approx"].tolist() == [0, 1, 0, 1, 1]
    np.testing.assert_allclose(o1["P_approx"], 1 / (M * (1 - Om**2)) + 1 / (M * (2.25 - Om**2)), rtol=1e-14)
    assert (o1["stable_damped_approx"] == o1["stable_first_approx"]).all()  # undamped: same boundaries
    np.testing.assert_allclose(o1["theta"], math.acos(-0.5))
    # damping ratio -> b = 2 zeta M omega
    o4, _, _ = evaluate(("P_approx",), Omega=1.3, omega_xi=1.0, omega_eta=1.5, zeta_xi=0.1, zeta_eta=0.2, **a)
    H = 1 / (M - M * 1.69 + 1j * 2 * 0.1 * M * 1.3) + 1 / (M * 2.25 - M * 1.69 + 1j * 2 * 0.2 * M * 1.5 * 1.3)
    assert o4["P_approx"][0] == pytest.approx(H.real, rel=1e-14)
    # undamped resonance: P is singular
    o5, s5, _ = evaluate(("P_approx", "stable_damped_approx"), Omega=1.0, omega_xi=1.0, omega_eta=1.5,
                         zeta_xi=0.0, zeta_eta=0.0, **a)
    assert s5[0] == st.SINGULAR and np.isnan(o5["P_approx"][0])
    # correcting mass, eq. (6)
    o6, _, _ = evaluate(("m_k",), Omega=1.0, omega_xi=1.0, omega_eta=1.5, zeta_xi=0, zeta_eta=0,
                        m4=0.5, S4=0.1, m5=1.0, l4=0.3, S_k=0.05, **a)
    assert o6["m_k"][0] == pytest.approx((0.05 + 0.3) / 0.05)


def test_infeasible_points():
    base = dict(Omega=1.0, M=1.0, m=0.01, a=0.1, I_B=1e-4, A0=1e-3, h=1e-4, omega_xi=1.0, omega_eta=1.5,
                zeta_xi=0.0, zeta_eta=0.0)
    bad = [dict(I_B=0.99e-4), dict(M=0.02), dict(A1=1e-3, l3=0.2, l4=0.2), dict(A1=1e-3, l3=0.3, l4=0.2)]
    for change in bad:
        out, status, _ = evaluate(("theta", "omega_p", "floquet_max"), **(base | change))
        assert status[0] == st.INFEASIBLE, change
        assert all(np.isnan(v).all() for v in out.values())
    for I_B in (1e-4, 0.1**2 * 0.01, 0.01 * 0.1 * 0.1):  # m a^2 in any rounding: a point-mass pendulum
        out, status, _ = evaluate(("theta",), **(base | dict(I_B=I_B)))
        assert status[0] == st.OK, I_B


def scene(**over):
    s = {"scene": {"name": "ab", "model": "autobalancer", "outputs": ["stable_floquet", "xi_history"]},
         "axes": {"Omega": [0.8, 1.2]},
         "fixed": dict(M=1.0, m=0.005, a=0.1, I_B=5e-5, A0=5e-4, h=5e-5, omega_xi=1.0, omega_eta=1.5,
                       zeta_xi=0.02, zeta_eta=0.02),
         "solver": {"horizon_revolutions": 20.0, "trajectory_samples": 11}}
    for k, v in over.items():
        s[k] = v
    return s


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(models.MODELS, "autobalancer", ab.SPEC)
    monkeypatch.setattr(mechsweep.scene.sections, "MODELS", models.MODELS)


def test_check_requires_exactly_one_of_each_pair(registered):
    load_scene(scene())
    both = scene()
    both["fixed"] = both["fixed"] | {"c_xi": 1.0}
    with pytest.raises(SceneError, match=r"c_xi: both omega_xi = 1 and c_xi = 1 are given; give exactly one"):
        load_scene(both)
    neither = scene()
    del neither["fixed"]["zeta_eta"]
    with pytest.raises(SceneError, match=r"zeta_eta: missing; give exactly one of zeta_eta .* or b_eta"):
        load_scene(neither)
    a1 = scene(axes={"Omega": [0.8, 1.2], "A1": [0.0, 1e-4]})
    with pytest.raises(SceneError, match=r"l3: missing; A1 = 0.0001 kg m is non-zero") as err:
        load_scene(a1)
    assert "l4: missing" in str(err.value)
    zero = scene()
    zero["fixed"] = zero["fixed"] | {"A1": 0.0}
    load_scene(zero)  # A1 = 0 needs no conrod lengths


def test_run_through_the_engine_stores_histories(registered, in_tmp):
    ds = mechsweep.run(scene(), output="data/runs/ab.h5")
    assert ds["xi_history"].dims == ("Omega", "revolution")
    np.testing.assert_allclose(ds["revolution"].values, np.linspace(0, 20, 11))
    assert ds["stable_floquet"].values.tolist() == [0.0, 1.0]
    assert ds["xi_history"].values[:, 0].tolist() == [0.0, 0.0]  # platform starts at rest
    assert ds.attrs["solver_horizon_revolutions"] == 20.0
    assert (ds["status"].values == st.OK).all()
