"""Status STIFF: plain dop853 says why it spent its step budget.

Every dop853 route (the one-point kernel, the lanes, the shared trajectory, Floquet's variational
integration, the sampled trajectories one at a time and in lanes) runs Hairer's stiffness test on
the last STIFF_WINDOW attempts of its budget and reports STIFF instead of MAX_STEPS where the test
fired there; auto and radau compute those points. The points: x'' + 2 zeta w x' + w^2 x = F cos(W t)
started on its steady motion (tests/user_models/stiff_oscillator.py: closed forms for every output),
zeta = 5 under a slow forcing (stiff), and the auto-balancer with pendulum damping h / (m a^2 Omega)
of 1e3 and 1e4 (slow; against scipy's LSODA)."""
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from mechsweep import status as st
from mechsweep.engine import kernels as mc
from mechsweep.model import user
from mechsweep.engine import sampling as tr
from mechsweep.models import MODELS
from tests import evaluating

USER = Path(__file__).resolve().parents[1] / "user_models" / "stiff_oscillator.py"

# (w, zeta, F, W): stiff (the step held at the fast mode's stability limit for the whole slow period;
# the budget runs out at t ~ 6.5e4); zeta = 5 with a faster forcing (done within the budget, the steps
# below the limit: the test stays quiet); lightly damped, forced near resonance (not stiff)
P = np.array([[1.0, 5.0, 1.0, 1e-5], [1.0, 5.0, 1.0, 1e-3], [1.0, 0.05, 1.0, 0.5]])
STIFF_POINT = 0


def _spec():
    return user.resolve(f"{USER}:STIFF_OSCILLATOR")


def evaluate(spec, P, wanted, lanes=False, monkeypatch=None, **solver):
    """(outputs, status, n_steps, n_rhs); ``lanes`` switches both lane routes (first events, trajectories)."""
    if monkeypatch is not None:
        monkeypatch.setattr(mc, "USE_LANES", lanes)
        monkeypatch.setattr(tr, "USE_LANES", lanes)
    return evaluating.evaluate(spec, P, wanted, **solver)


def steady(P, t):
    """x(t) = A cos(W t - phi) of each point (rows of P) at the times t (per point, or one for all)."""
    w, zeta, F, W = P.T
    A = F / np.hypot(w * w - W * W, 2 * zeta * w * W)
    phi = np.arctan2(2 * zeta * w * W, w * w - W * W)
    return A * np.cos(W * t - phi)


def t_down(P):
    """The first downward zero of x = A cos(W t - phi): W t - phi = pi / 2."""
    w, zeta, F, W = P.T
    return (math.pi / 2 + np.arctan2(2 * zeta * w * W, w * w - W * W)) / W


def names(status):
    return [st.MEANINGS[int(c)] for c in status]


def test_one_point_kernel_says_stiff_where_the_budget_ends_at_the_stability_limit(monkeypatch):
    spec = _spec()
    out, status, ns, _ = evaluate(spec, P, ("t_down",), monkeypatch=monkeypatch, method="dop853")
    assert names(status) == ["stiff", "ok", "ok"]  # was max_steps: the stiff point spent its 100,000 steps
    assert np.isnan(out["t_down"][STIFF_POINT]) and 0 < ns[STIFF_POINT] <= 100_000
    np.testing.assert_allclose(out["t_down"][1:], t_down(P[1:]), rtol=1e-9)
    # a budget too small for 15 steps at the limit, or for a point that is not stiff: max_steps
    _, status, ns, _ = evaluate(spec, P, ("t_down",), monkeypatch=monkeypatch, method="dop853", max_steps=8)
    assert names(status) == ["max_steps"] * 3 and (ns <= 8).all()


def test_radau_computes_the_stiff_point(monkeypatch):
    out, status, ns, _ = evaluate(_spec(), P, ("t_down",), monkeypatch=monkeypatch, method="radau")
    assert names(status) == ["ok"] * 3
    np.testing.assert_allclose(out["t_down"], t_down(P), rtol=1e-9)
    assert ns[STIFF_POINT] < 1000  # against more than 100,000 explicit steps


@pytest.mark.slow  # the auto kernel (dop853 with the test and radau): about a minute cold
def test_auto_hands_what_dop853_calls_stiff_to_radau(monkeypatch):
    spec = _spec()
    auto, s_auto, ns_auto, _ = evaluate(spec, P, ("t_down",), monkeypatch=monkeypatch, method="auto")
    radau, _, ns_radau, _ = evaluate(spec, P, ("t_down",), monkeypatch=monkeypatch, method="radau")
    plain, s_plain, ns_plain, _ = evaluate(spec, P, ("t_down",), monkeypatch=monkeypatch, method="dop853")
    assert names(s_auto) == ["ok"] * 3
    np.testing.assert_allclose(auto["t_down"], t_down(P), rtol=1e-9)
    stiff = s_plain == st.STIFF
    # what plain dop853 calls stiff, auto integrates again by radau (the same pass: the same value)
    assert auto["t_down"][stiff] == radau["t_down"][stiff]
    assert (ns_auto[stiff] > ns_radau[stiff]).all() and (ns_auto[stiff] < ns_plain[stiff]).all()
    assert (auto["t_down"][~stiff] == plain["t_down"][~stiff]).all()  # the others: dop853's own steps


@pytest.mark.slow  # the lane kernel: about a minute cold
def test_lanes_say_stiff_as_the_one_point_kernel(monkeypatch):
    spec = _spec()
    one = evaluate(spec, P, ("t_down",), lanes=False, monkeypatch=monkeypatch, method="dop853")
    monkeypatch.setattr(mc, "_KERNELS", {})
    lan = evaluate(spec, P, ("t_down",), lanes=True, monkeypatch=monkeypatch, method="dop853")
    assert any(isinstance(k, mc._Recorded) for k in mc._KERNELS.values())  # a lane kernel ran
    np.testing.assert_array_equal(one[0]["t_down"], lan[0]["t_down"])
    for a, b in zip(one[1:], lan[1:]):  # status, n_steps, n_rhs
        np.testing.assert_array_equal(a, b)
    assert names(lan[1]) == ["stiff", "ok", "ok"]


@pytest.mark.slow  # three kernels (shared trajectory with Floquet, sampled trajectory; radau)
def test_shared_floquet_and_sampled_routes_say_stiff(monkeypatch):
    spec = _spec()
    wanted = ("x_at", "mu", "x_hist")
    out, status, _, _ = evaluate(spec, P, wanted, monkeypatch=monkeypatch, method="dop853")
    assert status[STIFF_POINT] == st.STIFF
    for k in wanted:
        assert np.isnan(out[k][STIFF_POINT]).all(), k
    for k in ("x_at", "mu", "x_hist"):  # each route alone
        _, s, _, _ = evaluate(spec, P[:1], (k,), monkeypatch=monkeypatch, method="dop853")
        assert names(s) == ["stiff"], k
    # radau (Floquet and the sampled trajectory offer it): ok, and the closed forms
    out, status, _, _ = evaluate(spec, P, ("mu", "x_hist"), monkeypatch=monkeypatch, method="radau")
    assert names(status) == ["ok"] * 3
    w, zeta, F, W = P.T
    T = 2 * np.pi / W
    s = np.array([0.0, 0.25, 0.5])  # History: 3 samples over half a forcing period
    for i in range(P.shape[0]):
        np.testing.assert_allclose(out["x_hist"][i], steady(P[i], T[i] * s), rtol=1e-7, atol=1e-9)
    mu = np.where(zeta >= 1, np.exp(-w * (zeta - np.sqrt(np.maximum(zeta**2 - 1, 0))) * T), np.exp(-zeta * w * T))
    np.testing.assert_allclose(out["mu"], mu, rtol=1e-6, atol=1e-9)


@pytest.mark.slow  # the sampled trajectory's lanes: about a minute cold
def test_trajectory_lanes_say_stiff_as_one_trajectory_at_a_time(monkeypatch):
    # 16 points of one forcing period (the lanes take a period shared by at least LANE_GROUP_MIN points)
    Q = np.array([[w, z, 1.0, 1e-4] for w in (0.5, 1.0, 2.0, 4.0) for z in (0.05, 1.0, 5.0, 20.0)])
    assert Q.shape[0] >= tr.LANE_GROUP_MIN
    one = evaluate(_spec(), Q, ("x_hist",), lanes=False, monkeypatch=monkeypatch, method="dop853")
    lan = evaluate(_spec(), Q, ("x_hist",), lanes=True, monkeypatch=monkeypatch, method="dop853")
    np.testing.assert_array_equal(one[0]["x_hist"], lan[0]["x_hist"])
    for a, b in zip(one[1:], lan[1:]):
        np.testing.assert_array_equal(a, b)
    assert {st.OK, st.STIFF} <= set(lan[1].tolist())


# ----------------------------------------------------------------------------- the auto-balancer
AB_FIXED = dict(M=20.0, m=1.0, a=0.1, I_B=0.012, A0=0.1, omega_xi=20.0, omega_eta=30.0, zeta_xi=0.05, zeta_eta=0.05,
                Omega=25.0)  # sweeps/extreme/autobalancer_damping_range.toml; m a^2 Omega = 0.25 N m s/rad


def _autobalancer(h):
    spec = MODELS["autobalancer"]
    names_ = [p.name for p in spec.params]
    Q = np.array([[p.default for p in spec.params]], dtype=float)
    for k, v in {**AB_FIXED, "h": h}.items():
        Q[0, names_.index(k)] = v
    return spec, Q


def _phase_error_lsoda(h, revolutions):
    """The final phase error by scipy's LSODA on the model's scaled equations (the reference kernels'
    scaled parameters: c = M omega^2, b = 2 zeta M omega)."""
    from tests.reference import autobalancer_kernels as ab

    f = AB_FIXED
    th = math.acos(-f["A0"] / (2 * f["m"] * f["a"]))
    p = ab.scaled_parameters(f["Omega"], f["M"], f["m"], f["a"], f["I_B"], f["A0"], 0.0, 0.0,
                             f["M"] * f["omega_xi"] ** 2, f["M"] * f["omega_eta"] ** 2,
                             2 * f["zeta_xi"] * f["M"] * f["omega_xi"], 2 * f["zeta_eta"] * f["M"] * f["omega_eta"],
                             h, th, -th)
    z0 = np.empty(8)
    ab.initial_state(p, 0.1, z0)  # the default perturbation
    dz = np.empty(8)

    def fun(t, z):
        ab.rhs(t, z, p, dz)
        return dz.copy()

    tau = 2 * math.pi * revolutions
    sol = solve_ivp(fun, (0.0, tau), z0, method="LSODA", rtol=1e-12, atol=1e-14)
    assert sol.success
    e1, e2 = ab.phase_errors(tau, sol.y[2, -1], sol.y[3, -1], p[ab.IP_TH1], p[ab.IP_TH2])
    return max(abs(e1), abs(e2))


@pytest.mark.slow  # the auto-balancer's sampled kernels by dop853, radau and auto: minutes cold
@pytest.mark.parametrize("ratio, revolutions", [(1e3, 100.0), (1e4, 20.0)])
def test_autobalancer_pendulum_damping_is_stiff_for_dop853_and_ok_for_radau_and_auto(monkeypatch, ratio,
                                                                                        revolutions):
    """h / (m a^2 Omega) = ratio: the pendulums locked to the crank by a stiff damper. dop853 spends its
    100,000 steps before the horizon (at 1e3 after about 72 revolutions, 1e4 after 11.5) and says stiff;
    radau and auto finish, and the final phase error agrees with LSODA."""
    spec, Q = _autobalancer(ratio * 0.25)
    kw = dict(horizon_revolutions=revolutions, reproducibility_factor=0.0)
    _, status, ns, _ = evaluate(spec, Q, ("phase_error",), monkeypatch=monkeypatch, method="dop853", **kw)
    assert names(status) == ["stiff"] and ns[0] <= 100_000  # was max_steps
    reference = _phase_error_lsoda(ratio * 0.25, revolutions)
    for method in ("radau", "auto"):
        out, status, _, _ = evaluate(spec, Q, ("phase_error",), monkeypatch=monkeypatch, method=method, **kw)
        assert status[0] in (st.OK, st.UNDECIDED), (method, names(status))  # the pendulums stay where they were kicked
        np.testing.assert_allclose(out["phase_error"][0], reference, rtol=1e-7, err_msg=method)
