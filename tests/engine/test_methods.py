"""solver.method: every method of every integrated model gives the same answer within its
tolerance; auto hands stiff points to radau; scenes refuse a method a model does not offer."""
import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.models import MODELS
from tests.reference import autobalancer_kernels as ab  # the hand-written kernels (reference implementation)
from mechsweep.models import torsional_circuit as tc
from mechsweep.scene import SceneError, load_scene
from tests import evaluating


def evaluate(model, P, outputs, **solver):
    spec = MODELS[model]
    return evaluating.evaluate(spec, P, spec.closure(outputs), **solver)


def duffing_period_error(P, **solver):
    """(outputs with period_error, status, n_steps, n_rhs): period_error as the model defines it,
    |T - T_exact| / T_exact, from the period integrated alone and the closed form computed alone:
    the kernels of `mechsweep bench workprecision duffing` (tests/bench/test_workprecision.py), one
    per method, rather than kernels of their own with the closed forms."""
    out, status, ns, nr = evaluate("duffing", P, ("period",), **solver)
    exact = evaluate("duffing", P, ("period_exact",), **solver)[0]["period_exact"]
    out["period_error"] = np.abs(out["period"] - exact) / np.abs(exact)
    return out, status, ns, nr


DUFFING_EPS = np.array([-0.99, -0.9, -0.5, 0.0, 0.01, 1.0, 10.0, 1e2, 1e3, 1e4])


@pytest.mark.parametrize("method", MODELS["duffing"].methods)
@pytest.mark.parametrize("rtol", [1e-6, 1e-10])
def test_duffing_period_of_every_method_meets_its_tolerance(method, rtol):
    P = np.column_stack([np.ones(DUFFING_EPS.size), DUFFING_EPS, np.ones(DUFFING_EPS.size)])
    out, status, ns, nr = duffing_period_error(P, method=method, rtol=rtol, atol=rtol * 1e-2)
    assert (status == st.OK).all()
    assert np.nanmax(out["period_error"]) < 2 * rtol
    assert (ns > 0).all() and (nr > ns).all()


def test_torsional_exact_moment_slope_is_the_derivative_of_the_moment():
    rng = np.random.default_rng(3)
    for _ in range(20):
        sigma = rng.choice([-1.0, 1.0])
        lam1, lam2, s = rng.uniform(0.2, 1.5), rng.uniform(0.1, 2.0), rng.uniform(-0.3, 0.3)
        D0 = (1 - sigma * lam1) ** 2 + lam2**2
        L0 = math.sqrt(D0) - sigma * s
        phi, h = rng.uniform(-2, 2), 1e-6
        fd = (tc.exact_moment(phi + h, sigma, lam1, D0, L0) - tc.exact_moment(phi - h, sigma, lam1, D0, L0)) / (2 * h)
        assert tc.exact_moment_slope(phi, sigma, lam1, D0, L0) == pytest.approx(fd, rel=1e-7, abs=1e-9)


def test_torsional_methods_agree_on_the_exact_moment_period():
    scene = load_scene({"scene": {"name": "t", "model": "torsional_circuit", "outputs": ["period_exact_moment"]},
                        "axes": {"A": {"start": 0.05, "stop": 1.4, "num": 6}},
                        "fixed": {"spring": "tension", "lambda1": 0.8, "lambda2": 1.0, "s0_over_r": 0.1,
                                  "R": 0.05, "c": 2000.0, "I": 2e-3}})
    from mechsweep.grid import ParameterMatrix
    P = ParameterMatrix(scene)(0, scene.n_points)
    periods = {}
    for method in MODELS["torsional_circuit"].methods:
        out, status, _, _ = evaluate("torsional_circuit", P, ("period_exact_moment",), method=method, rtol=1e-10,
                                     atol=1e-12)
        assert (status == st.OK).all(), method
        periods[method] = out["period_exact_moment"]
    for method, T in periods.items():
        np.testing.assert_allclose(T, periods["dop853"], rtol=3e-10, err_msg=method)


def test_autobalancer_jacobians_are_consistent():
    """The 8x8 Jacobian against finite differences of the rhs; the variational system is linear,
    so its rhs equals its Jacobian times the state."""
    rng = np.random.default_rng(5)
    p = ab.scaled_parameters(1.3, 10.0, 1.0, 0.1, 0.012, 0.1, 0.0, 0.0, 400.0, 900.0, 4.0, 6.0, 0.02, 2.0, -2.0)
    z = rng.normal(size=8)
    J = np.empty((8, 8))
    ab.jacobian(0.4, z, p, J)
    f0, f1 = np.empty(8), np.empty(8)
    for c in range(8):
        dz = np.zeros(8)
        dz[c] = 1e-6
        ab.rhs(0.4, z + dz, p, f1)
        ab.rhs(0.4, z - dz, p, f0)
        np.testing.assert_allclose(J[:, c], (f1 - f0) / 2e-6, rtol=1e-6, atol=1e-7)
    Y = rng.normal(size=64)
    JV = np.empty((64, 64))
    ab.variational_jacobian(0.9, Y, p, JV)
    dY = np.empty(64)
    ab.variational_rhs(0.9, Y, p, dY)
    np.testing.assert_allclose(JV @ Y, dY, rtol=1e-12, atol=1e-12)


def stiff_platform(n=3):
    """Platform natural frequencies 10^4 x the crank speed, heavily damped: an explicit step is
    held at the stability limit ~ 1 / (10^4 Omega) while the solution changes on the scale 1 / Omega."""
    names = ab.PARAM_NAMES
    P = np.full((n, len(names)), np.nan)
    for j, prm in enumerate(MODELS["autobalancer"].params):
        P[:, j] = prm.default
    values = dict(Omega=np.linspace(1.0, 1.5, n), M=10.0, m=1.0, a=0.1, I_B=0.012, A0=0.1, h=0.02,
                  omega_xi=1e4, omega_eta=1.5e4, zeta_xi=0.5, zeta_eta=0.5)
    for k, v in values.items():
        P[:, names.index(k)] = v
    return P


def test_auto_hands_a_stiff_autobalancer_to_radau_and_agrees_with_a_long_explicit_run():
    P = stiff_platform()
    tight, s_ref, ns_ref, _ = evaluate("autobalancer", P, ("floquet_max",), method="dop853", rtol=1e-9, atol=1e-11,
                                       max_steps=10**6)
    assert (s_ref == st.OK).all()
    auto, s_auto, ns_auto, _ = evaluate("autobalancer", P, ("floquet_max",), method="auto", rtol=1e-9, atol=1e-11)
    assert (s_auto == st.OK).all()
    np.testing.assert_allclose(auto["floquet_max"], tight["floquet_max"], atol=1e-6)
    radau_only, _, ns_radau, _ = evaluate("autobalancer", P, ("floquet_max",), method="radau", rtol=1e-9, atol=1e-11)
    assert (ns_auto > ns_radau).all()  # auto = a few explicit steps until the test fires, then radau
    assert (ns_auto < ns_ref).all()


def test_scene_refuses_a_method_the_model_does_not_offer():
    base = {"scene": {"name": "x", "model": "autobalancer", "outputs": ["floquet_max"]},
            "axes": {"Omega": {"start": 1.0, "stop": 2.0, "num": 2}},
            "fixed": {"M": 10.0, "m": 1.0, "a": 0.1, "I_B": 0.012, "A0": 0.1, "h": 0.02, "omega_xi": 1.0,
                      "omega_eta": 1.5, "zeta_xi": 0.02, "zeta_eta": 0.02},
            "solver": {"method": "symplectic"}}
    with pytest.raises(SceneError, match=r"solver.method.*'symplectic'.*dop853, radau, auto"):
        load_scene(base)
    base["solver"]["method"] = "radau"
    assert load_scene(base).solver.method == "radau"


# ----------------------------------------------------------------------------- usable ranges of the tolerances
@pytest.mark.parametrize("method", ["dop853", "radau", "auto"])
def test_atol_below_the_floor_gives_nonfinite_everywhere_and_is_refused(method):
    """The floor is where the adaptive methods' error norm, (rate / atol)^2 at a state that starts
    at zero, overflows: at ATOL_FLOOR every point is ok and within its tolerance, far below it
    (evaluated past the scene's check) every point is nonfinite, and a scene asking it is refused
    naming the key, the value and the range."""
    from mechsweep.scene import ATOL_FLOOR

    P = np.column_stack([np.ones(DUFFING_EPS.size), DUFFING_EPS, np.ones(DUFFING_EPS.size)])
    out, status, _, _ = duffing_period_error(P, method=method, rtol=1e-10, atol=ATOL_FLOOR)
    assert (status == st.OK).all(), status
    assert np.nanmax(out["period_error"]) < 2e-10
    _, status, _, _ = duffing_period_error(P, method=method, rtol=1e-10, atol=1e-300)
    assert (status == st.NONFINITE).all(), status
    scene = {"scene": {"name": "t", "model": "duffing", "outputs": ["period_error"]},
             "axes": {"mu": list(DUFFING_EPS)}, "fixed": {"omega": 1.0, "A": 1.0},
             "solver": {"method": method, "atol": 1e-300}}
    with pytest.raises(SceneError, match=rf"solver.atol: 1e-300 is below the usable range of method '{method}', "
                                         r"\[1e-150, 1\]"):
        load_scene(scene)
    scene["solver"]["atol"] = ATOL_FLOOR
    assert load_scene(scene).solver.atol == ATOL_FLOOR


def test_symplectic_does_not_read_atol():
    P = np.column_stack([np.ones(DUFFING_EPS.size), DUFFING_EPS, np.ones(DUFFING_EPS.size)])
    runs = [duffing_period_error(P, method="symplectic", rtol=1e-10, atol=atol)
            for atol in (1e-12, 1e-300)]
    for a, b in zip(runs[0], runs[1]):
        a = a["period_error"] if isinstance(a, dict) else a
        b = b["period_error"] if isinstance(b, dict) else b
        np.testing.assert_array_equal(a, b)
    scene = {"scene": {"name": "t", "model": "duffing", "outputs": ["period_error"]},
             "axes": {"mu": list(DUFFING_EPS)}, "fixed": {"omega": 1.0, "A": 1.0},
             "solver": {"method": "symplectic", "atol": 1e-300}}
    assert load_scene(scene).solver.atol == 1e-300


@pytest.mark.parametrize("method", ["radau", "auto"])
def test_radau_raises_rtol_below_100_eps_so_the_scene_warns(method):
    """What the warning says, proven: radau's points at rtol 1e-15 are bitwise those at 100 eps."""
    from mechsweep.scene import RADAU_MIN_RTOL, solver_warnings

    assert RADAU_MIN_RTOL == 100 * np.finfo(np.float64).eps
    P = np.column_stack([np.ones(4), np.array([0.5, 1.0, 10.0, 1e3]), np.ones(4)])
    low = duffing_period_error(P, method="radau", rtol=1e-15, atol=1e-14)
    raised = duffing_period_error(P, method="radau", rtol=RADAU_MIN_RTOL, atol=1e-14)
    np.testing.assert_array_equal(low[0]["period_error"], raised[0]["period_error"])
    np.testing.assert_array_equal(low[2], raised[2])
    scene = load_scene({"scene": {"name": "t", "model": "duffing", "outputs": ["period_error"]},
                        "axes": {"mu": [0.5, 1.0]}, "fixed": {"omega": 1.0, "A": 1.0},
                        "solver": {"method": method, "rtol": 1e-15}})
    (text,) = solver_warnings(scene)
    assert "solver.rtol = 1e-15 is below 2.22e-14" in text and "radau raises it" in text
    scene = load_scene({"scene": {"name": "t", "model": "duffing", "outputs": ["period_error"]},
                        "axes": {"mu": [0.5, 1.0]}, "fixed": {"omega": 1.0, "A": 1.0},
                        "solver": {"method": "dop853", "rtol": 1e-15}})
    assert solver_warnings(scene) == []  # dop853 takes rtol as given


def test_a_tiny_atol_warns_on_check_and_run(tmp_path, capsys, monkeypatch):
    """Accepted, but suspicious: atol below ATOL_WARN. `check` prints it, `run` warns (in one line
    on the command line), the shipped settings never do."""
    import warnings

    from mechsweep import cli
    from mechsweep.errors import SettingsWarning
    from mechsweep.scene import ATOL_WARN, solver_warnings

    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(
        '[scene]\nname = "s"\nmodel = "duffing"\noutputs = ["period_error"]\n[axes]\nmu = [0.5, 1.0]\n'
        f'[fixed]\nomega = 1.0\nA = 1.0\n[solver]\natol = {ATOL_WARN / 10:g}\n')
    assert cli.main(["check", "s.toml"]) == 0
    err = capsys.readouterr().err
    assert "s.toml: warning: solver.atol = 1e-21 is below 1e-20" in err and "step_underflow" in err, err
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        mechsweep_run("s.toml")
    assert [str(w.message)[:40] for w in seen if w.category is SettingsWarning] == [
        "solver.atol = 1e-21 is below 1e-20: near"]
    for path in sorted((Path(__file__).resolve().parents[2] / "sweeps").rglob("*.toml")):
        assert solver_warnings(load_scene(path)) == [], path


def mechsweep_run(path):
    import mechsweep

    return mechsweep.run(path, output=None, progress=False)
