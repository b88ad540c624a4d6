"""The sampled-trajectory measurements of the model layer (Steady, Kick, History;
engine/sampling.py) against closed forms, on user models written as a user would
(tests/user_models/forced.py)."""
import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.model import user

USER = Path(__file__).resolve().parents[1] / "user_models" / "forced.py"
from tests.evaluating import evaluate as _evaluate


@pytest.fixture(scope="module")
def forced():
    return user.resolve(f"{USER}:FORCED")


@pytest.fixture(scope="module")
def decay():
    return user.resolve(f"{USER}:DECAY")


def _forced_closed(w, zeta, F, W):
    A = F / np.hypot(w * w - W * W, 2 * zeta * w * W)
    return A, np.arctan2(2 * zeta * w * W, w * w - W * W)


WANTED = ("amp", "amp_h1", "amp_phase", "speed_amp", "x_hist")  # one kernel for the FORCED tests


@pytest.mark.parametrize("method", ["dop853", pytest.param("radau", marks=pytest.mark.slow),
                                    pytest.param("auto", marks=pytest.mark.slow)])
def test_steady_amplitude_and_phase_of_a_forced_damped_oscillator(forced, method):
    # below, near and above resonance; damping 0.05 .. 0.3 (settled within 200 periods)
    P = np.array([[1.0, 0.1, 1.0, 0.5], [1.0, 0.05, 2.0, 0.97], [2.0, 0.3, 1.0, 5.0], [1.5, 0.2, -0.5, 1.5]])
    out, status, ns, nr = _evaluate(forced, P, WANTED, method=method,
                                    rtol=1e-10, atol=1e-12, max_steps=10**7)
    A, phi = _forced_closed(*P.T)
    assert (status == st.OK).all() and (ns > 0).all() and (nr > ns).all()
    np.testing.assert_allclose(out["amp_h1"], np.abs(A), rtol=2e-7)
    # F < 0 is the same motion shifted by half a period: the phase by pi
    expect = np.where(P[:, 2] < 0, np.angle(np.exp(1j * (phi + math.pi))), phi)
    np.testing.assert_allclose(out["amp_phase"], expect, atol=2e-7)
    # the sampled peak: below the amplitude by at most 1 - cos(pi / 64)
    assert ((out["amp"] <= np.abs(A) * (1 + 1e-7)) & (out["amp"] >= np.abs(A) * math.cos(math.pi / 64))).all()
    np.testing.assert_allclose(out["speed_amp_h1"] if "speed_amp_h1" in out else out["speed_amp"],
                               np.abs(A) * P[:, 3], rtol=math.pi ** 2 / 64 ** 2)
    # History: 11 samples over 200 periods, x(0) = 0 from rest; the last, steady, on the closed form
    assert out["x_hist"].shape == (4, 11)
    assert (out["x_hist"][:, 0] == 0.0).all()
    T = 2 * math.pi / P[:, 3]
    np.testing.assert_allclose(out["x_hist"][:, -1], A * np.cos(P[:, 3] * 200 * T - phi), atol=1e-7)


def test_steady_reports_no_event_when_the_transient_has_not_died_out(forced):
    # zeta = 0.001 near resonance: the beat decays over ~1/(zeta w) = 1000 s = 160 periods
    P = np.array([[1.0, 0.001, 1.0, 0.9], [1.0, 0.2, 1.0, 0.9]])
    out, status, _, _ = _evaluate(forced, P, WANTED, rtol=1e-9, atol=1e-12, horizon_periods=20.0)
    assert status.tolist() == [st.NO_EVENT, st.OK]
    assert np.isnan(out["amp"][0]) and np.isnan(out["amp_phase"][0]) and np.isfinite(out["amp"][1])
    # the peak without a settling check (speed_amp) is given where the other is not
    assert np.isfinite(out["speed_amp"]).all() and np.isfinite(out["x_hist"]).all()


def test_the_horizon_setting_moves_the_window(forced):
    P = np.array([[1.0, 0.1, 1.0, 0.5]])
    a, _, n1, _ = _evaluate(forced, P, WANTED, rtol=1e-10, atol=1e-12, horizon_periods=100.0)
    b, _, n2, _ = _evaluate(forced, P, WANTED, rtol=1e-10, atol=1e-12, horizon_periods=300.0)
    assert n2[0] > 2 * n1[0]
    np.testing.assert_allclose(a["amp_h1"], b["amp_h1"], rtol=1e-8)


@pytest.mark.parametrize("method", ["dop853", pytest.param("radau", marks=pytest.mark.slow)])
def test_kick_verdict_settling_time_and_history_of_an_exponential(decay, method):
    lam = np.array([0.5, 0.2, -0.05, 1e-6, 30.0])
    P = np.column_stack([lam, np.full(5, 0.1)])
    out, status, _, _ = _evaluate(decay, P, ("stable", "stable_settling", "stable_final", "y_hist"), method=method,
                                  rtol=1e-11, atol=1e-14, max_steps=10**7)
    assert out["stable"][:3].tolist() == [1.0, 1.0, 0.0]
    assert np.isnan(out["stable"][3]) and status[3] == st.UNDECIDED  # neither decays nor grows in 40 s
    t_s = np.log(0.1 / 0.01) / lam[:2]
    # linear interpolation between samples 1/8 s apart: relative error <= (lam / 8)^2 / 8
    np.testing.assert_allclose(out["stable_settling"][:2], t_s, rtol=(0.5 / 8) ** 2 / 8)
    assert np.isnan(out["stable_settling"][2]) and status[2] == st.NO_EVENT  # grows: never settles
    np.testing.assert_allclose(out["stable_final"][:3], 0.1 * np.exp(-lam[:3] * 40.0), rtol=1e-8, atol=1e-15)
    np.testing.assert_allclose(out["y_hist"], 0.1 * np.exp(-np.outer(lam, np.linspace(0, 40, 9))), rtol=1e-8,
                               atol=1e-12)  # lam = 30: at the noise floor of atol
    assert out["stable"][4] == 1.0 and status[4] == st.OK


def test_value_and_time_value_transform_the_sampled_outputs_per_point(decay):
    # DECAY's kick_rel / peak_rel / y_rel are stable / a peak / y_hist with value(p, x) = x / y0 and
    # time_value(p, t) = lam t: the transform of the measured value, per point, in the kernel
    lam = np.array([0.5, 0.2, -0.05, 0.3])
    P = np.column_stack([lam, np.array([0.1, 0.3, 0.1, 2.0])])
    wanted = ("stable", "stable_settling", "stable_final", "y_hist", "kick_rel", "kick_rel_settling", "kick_rel_final", "peak_rel",
              "y_rel")
    out, status, _, _ = _evaluate(decay, P, wanted, rtol=1e-11, atol=1e-14, max_steps=10**7)
    assert status.tolist() == [st.OK, st.OK, st.NO_EVENT, st.OK]
    # bitwise the plain outputs transformed (NaN stays NaN: lam < 0 never settles)
    np.testing.assert_array_equal(out["kick_rel_settling"], out["stable_settling"] * lam)
    np.testing.assert_array_equal(out["y_rel"], out["y_hist"] / P[:, 1:])
    assert out["kick_rel"].tolist()[:2] == [1.0, 1.0] and out["kick_rel"][2] == 0.0
    # closed forms: lam t_s = ln(y0 / thr) (to the interpolation error), peak over t in [36, 40]
    t_rel = np.log(P[[0, 1, 3], 1] / 0.01)
    np.testing.assert_allclose(out["kick_rel_settling"][[0, 1, 3]], t_rel, rtol=(0.5 / 8) ** 2 / 8)
    peak = np.where(lam > 0, np.exp(-lam * 36.0), np.exp(-lam * 40.0))
    np.testing.assert_allclose(out["peak_rel"], peak, rtol=1e-8, atol=1e-13)  # y ~ 1e-9: atol 1e-14
    # the error itself is not transformed
    np.testing.assert_array_equal(out["kick_rel_final"], out["stable_final"])


def _per_subset(spec, P, wanted, monkeypatch, **solver):
    """_evaluate by the model's one sampled-trajectory kernel, then by a kernel compiled for the
    asked-for measurements alone (trajectory.evaluate(per_subset=True), as before the one kernel)."""
    import functools

    from mechsweep.engine import sampling as trajectory
    a = _evaluate(spec, P, wanted, **solver)
    with monkeypatch.context() as m:
        m.setattr(trajectory, "evaluate", functools.partial(trajectory.evaluate, per_subset=True))
        b = _evaluate(spec, P, wanted, **solver)
    for x, y in zip(a[1:], b[1:]):  # status, n_steps, n_rhs
        assert np.array_equal(x, y)
    for k in wanted:
        assert np.array_equal(a[0][k], b[0][k], equal_nan=True), k
    return a


def test_one_kernel_per_model_serves_every_subset_of_its_sampled_outputs(decay):
    # DECAY: Kick, History, Kick (time_value), Steady (value), History (value), one horizon: every
    # subset runs on the model's one kernel (nothing more compiled), and a subset's values and
    # counts are bitwise those of the run that asks for everything (the same steps: the horizon
    # is the same; samples come from the dense output)
    from mechsweep.engine import sampling as trajectory
    lam = np.array([0.5, 0.2, -0.05, 1e-6, 30.0, 0.3])
    P = np.column_stack([lam, np.array([0.1, 0.3, 0.1, 0.1, 0.1, 2.0])])
    kw = dict(rtol=1e-11, atol=1e-14, max_steps=10**7)
    every = ("stable", "stable_settling", "stable_final", "y_hist", "kick_rel", "kick_rel_settling", "kick_rel_final",
             "peak_rel", "y_rel")
    before = set(trajectory._KERNELS)
    a = _evaluate(decay, P, every, **kw)
    for wanted in (("kick_rel_settling", "y_rel", "peak_rel"), ("stable_final",), ("y_hist", "stable")):
        b = _evaluate(decay, P, wanted, **kw)
        assert np.array_equal(a[2], b[2]) and np.array_equal(a[3], b[3])
        for k in wanted:
            assert np.array_equal(a[0][k], b[0][k], equal_nan=True), (wanted, k)
    assert len(set(trajectory._KERNELS) - before) <= 1  # the model's one kernel (none if compiled before)
    assert b[1].tolist() == [st.OK, st.OK, st.OK, st.UNDECIDED, st.OK, st.OK]  # lam < 0: unstable (0)


@pytest.mark.slow  # a kernel per subset (the comparison), about 15 s each cold
def test_the_one_kernel_gives_each_subset_what_its_own_kernel_gives(decay, monkeypatch):
    # a subset that skips DECAY's first two measurements: bitwise the values, statuses and counts
    # of a kernel compiled for it alone (as before the one kernel)
    lam = np.array([0.5, 0.2, -0.05, 1e-6, 30.0, 0.3])
    P = np.column_stack([lam, np.array([0.1, 0.3, 0.1, 0.1, 0.1, 2.0])])
    out, status, _, _ = _per_subset(decay, P, ("kick_rel_settling", "y_rel", "peak_rel"), monkeypatch, rtol=1e-11,
                                    atol=1e-14, max_steps=10**7)
    assert status.tolist() == [st.OK, st.OK, st.NO_EVENT, st.NO_EVENT, st.OK, st.OK] and np.isfinite(out["y_rel"]).all()
    # SEVERITY's amp (Steady) is SINGULAR where F < 0 (its classify), x_hist NOT_OSCILLATORY where
    # zeta >= 1: x_hist alone on the one kernel is what x_hist's own kernel gives, amp's rule unused
    severity = user.resolve(f"{USER.parent / 'severity.py'}:SEVERITY")
    P = np.array([[1.0, 0.1, -1.0, 0.5], [1.0, 1.5, 1.0, 0.9], [2.0, 0.2, 1.0, 1.0]])
    out, status, ns, _ = _per_subset(severity, P, ("x_hist",), monkeypatch, rtol=1e-9, atol=1e-12,
                                     horizon_periods=20.0)
    assert status.tolist() == [st.OK, st.NOT_OSCILLATORY, st.OK] and ns[1] == 0
    assert np.isfinite(out["x_hist"][[0, 2]]).all() and np.isnan(out["x_hist"][1]).all()


def test_a_value_that_is_not_a_function_is_refused():
    from mechsweep.model import Kick, Steady
    with pytest.raises(ValueError, match="value must be a function"):
        Steady("a", "x", value=2.0).validate(("x",))
    with pytest.raises(ValueError, match="time_value must be a function"):
        Kick("k", "x", time_value="lam").validate(("x",))


@pytest.mark.parametrize("kind, field, value, allowed", [
    ("Steady", "horizon", 0, "a number > 0"), ("Steady", "horizon", -5.0, "a number > 0"),
    ("Steady", "window", 0.7, "a number in (0, 0.5]"), ("Steady", "samples_per_period", 2, "a number >= 3"),
    ("Steady", "settle_rtol", -1e-3, "a number >= 0"), ("Steady", "settle_atol", -1.0, "a number >= 0"),
    ("Kick", "horizon", 0.0, "a number > 0"), ("Kick", "settle_threshold", 0.0, "a number > 0"),
    ("Kick", "decay_ratio", 1.5, "a number in (0, 1]"), ("Kick", "growth_ratio", 0.5, "a number >= 1"),
    ("Kick", "monitor_per_period", 0.5, "a whole number >= 1"), ("Kick", "dense_per_period", 0, "a whole number >= 1"),
    ("Kick", "late", 0.6, "a number in (0, 0.5]"), ("Kick", "growth_floor", -1e-9, "a number >= 0"),
    ("History", "horizon", -5, "a number > 0"), ("History", "samples", 1, "a whole number >= 2"),
    ("History", "samples", 10.5, "a whole number >= 2")])
def test_numeric_fields_of_sampled_measurements_are_checked(kind, field, value, allowed):
    """Each numeric field in its range when the model is declared: the message names the
    measurement, the field, the value and what is allowed (a file model: exit 2 when loaded)."""
    from mechsweep.model import History, Kick, OdeModel, Steady
    m = {"Steady": Steady, "Kick": Kick, "History": History}[kind]("m", "y", **{field: value})
    with pytest.raises(ValueError) as info:
        OdeModel(name="x", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
                 initial=lambda p, y: None, forcing_period=lambda p: 1.0, measurements=(m,))
    assert str(info.value) == f"{kind} 'm': {field} = {value!r} is not allowed; expected {allowed} (or the name of a setting)"


def test_each_sampled_measurement_reports_its_settings_functions_and_key():
    """What the kernels and the scene read of a declaration: the settings its fields name (in field
    order; Kick's late and early are plain numbers), the functions it calls by role (a state's name
    is no function) and its key."""
    from mechsweep.model import RMS, History, Kick, Steady

    def f(t, y, p):
        return 0.0

    def g(p, x):
        return x

    cases = [
        (Steady("a", "y", horizon="H", settle_rtol=None, settle_atol="A"), ("H", "A"), (), ("Steady", "a", "y")),
        (Steady("a", f, value=g), (), ("of", "value"), ("Steady", "a", None)),
        (Kick("k", f, response="y", growth_floor="G", time_value=g), ("G",), ("error", "value"),
         ("Kick", "k", None, "y", False, 0.1, 0.1)),
        (Kick("k", "y", horizon="H", late=0.2), ("H",), (), ("Kick", "k", "y", None, True, 0.2, 0.1)),
        (History("h", f, samples="N"), ("N",), ("of",), ("History", "h", None)),
        (RMS("r", "y", window="W", samples_per_period="S", value=g), ("W", "S"), ("value",), ("RMS", "r", "y")),
    ]
    for m, settings, roles, key in cases:
        assert m.setting_names() == settings, m
        assert tuple(role for role, _ in m.functions()) == roles, m
        assert m.key() == key, m


def test_a_field_naming_a_setting_is_checked_against_the_setting_range():
    from mechsweep.model import History, OdeModel, Setting
    kw = dict(name="x", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
              initial=lambda p, y: None)
    with pytest.raises(ValueError, match=r"History 'h': horizon = 'H' names the setting 'H', whose range \[0, 10\] "
                                         r"allows values outside what horizon accepts: a number > 0"):
        OdeModel(settings=(Setting("H", 5.0, "1", "horizon", 0.0, 10.0),),
                 measurements=(History("h", "y", horizon="H"),), **kw)
    with pytest.raises(ValueError, match=r"samples = 'n' names the setting 'n', whose range \[2, 10\] \(not "
                                         r"integer=True\)"):
        OdeModel(settings=(Setting("n", 5.0, "1", "samples", 2.0, 10.0),),
                 measurements=(History("h", "y", samples="n"),), **kw)
    OdeModel(settings=(Setting("n", 5, "1", "samples", 2, 10, integer=True),),
             measurements=(History("h", "y", samples="n"),), **kw)


def test_history_without_a_forcing_period_is_labelled_in_time(decay):
    """A model without forcing_period counts its horizons in time units (T = 1): a History with
    the default label says so instead of "forcing periods"."""
    from mechsweep.model import History, OdeModel
    kw = dict(name="x", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
              initial=lambda p, y: None, measurements=(History("h", "y"),))
    unforced = OdeModel(**kw).spec().output("h").extra_dims[0].long_name
    forced = OdeModel(forcing_period=lambda p: 1.0, **kw).spec().output("h").extra_dims[0].long_name
    assert unforced == "time t (the model declares no forcing period: T = 1)"
    assert forced == "time in forcing periods t / T"
    assert decay.output("y_hist").extra_dims[0].long_name == "time t"  # a label given is kept
    # Steady (allowed: e.g. a peak of an autonomous motion) says its T in every output's long name
    assert decay.output("peak_rel").long_name.endswith("(T = 1 time unit: the model declares no forcing period)")
    assert "T = 1 time unit" not in user.resolve(f"{USER}:FORCED").output("amp_h1").long_name


def test_kick_growth_floor_decides_an_error_at_its_noise_floor():
    """An error that decayed to a plateau (here 2e-5, read 4 % higher in the last window, as a
    finer sampling there reads it) is not "growing" when at most growth_floor; by default the floor
    is 1e-3 settle_threshold (the old rule, unchanged: 1e-5 here, so UNDECIDED)."""
    from mechsweep.model import Kick
    from mechsweep.model.sampled import kick_observe
    from mechsweep.engine.sampling import grid
    s, bits, K = grid((Kick("k", "y", horizon=20.0, settle_threshold=0.01),
                       Kick("f", "y", horizon=20.0, settle_threshold=0.01, growth_floor=1e-4)), {})
    assert K[0].tolist() == [0.01, 0.5, 2.0, 0.01 * 1e-3] and K[1, 3] == 1e-4
    e = np.where(s < 2.0, 1.0, 2e-5) * np.where(s >= 18.0, 1.04, 1.0)
    verdicts = []
    for k in range(2):
        out = np.full(3, np.nan)
        assert kick_observe(e, e, False, s, bits[:, k], K[k], out) == st.OK
        verdicts.append(out[0])
    assert np.isnan(verdicts[0]) and verdicts[1] == 1.0


def test_sampled_measurements_offer_the_trajectory_methods_only(forced, decay):
    assert forced.methods_for(("amp",)) == ("dop853", "radau", "auto")
    assert decay.output("y_hist").extra_dims[0].name == "time"


def test_floquet_alone_offers_radau_and_auto():
    cubic = user.resolve(f"{USER}:CUBIC")
    assert cubic.methods_for(("mu",)) == ("dop853", "radau", "auto")
    assert cubic.methods_for(("mu", "rest_stable")) == ("dop853", "radau", "auto")


@pytest.mark.slow  # about 30 s of compilation per method
@pytest.mark.parametrize("method", ["dop853", "radau", "auto"])
def test_floquet_by_every_method_and_about_its_own_orbit_start(method):
    cubic = user.resolve(f"{USER}:CUBIC")
    P = np.array([[0.5, 2.0], [2.0, 0.3], [1.0, 5.0]])
    out, status, ns, _ = _evaluate(cubic, P, ("mu", "mu_stable", "mu_rest", "rest_stable", "rest_kind"), method=method,
                                   rtol=1e-11, atol=1e-13)
    np.testing.assert_allclose(out["mu"], (1 + 2 * P[:, 0] ** 2 * P[:, 1]) ** -1.5, rtol=1e-8)
    assert (out["mu_stable"] == 1.0).all()
    # about rest (the measurement's own initial): exactly 1, undecided; the kind is +1 (real, positive)
    np.testing.assert_allclose(out["mu_rest"], 1.0, rtol=1e-12)
    assert np.isnan(out["rest_stable"]).all() and (status == st.UNDECIDED).all() and (out["rest_kind"] == 1.0).all()
    assert (ns > 0).all()


def test_a_sampled_user_model_runs_and_stores_its_history(in_tmp):
    import mechsweep

    scene = {"scene": {"name": "forced", "model": f"{USER}:FORCED", "outputs": list(WANTED)},
             "axes": {"W": [0.5, 0.97]}, "fixed": {"w": 1.0, "zeta": 0.1, "F": 1.0},
             "solver": {"rtol": 1e-10, "atol": 1e-12}}
    ds = mechsweep.run(scene, output="data/runs/forced.h5")
    assert ds["x_hist"].dims == ("W", "period")
    np.testing.assert_allclose(ds["period"].values, np.linspace(0, 200, 11))
    A, phi = _forced_closed(1.0, 0.1, 1.0, np.array([0.5, 0.97]))
    np.testing.assert_allclose(ds["amp_h1"].values, A, rtol=2e-7)
    assert (ds["status"].values == st.OK).all()


@pytest.mark.slow  # compiles the lane solver for two models (about a minute cold)
def test_lanes_give_the_one_trajectory_results_bitwise(forced, decay, monkeypatch):
    """User models that write no lane rhs (the engine rewrites theirs, model/lanes.py): FORCED's
    Steady and History over three forcing periods (one lane group each) and five periods of one
    point each (too few for lanes: one trajectory at a time), DECAY's Kick, Steady and
    History (with value/time_value transforms) in DOP853 lanes and one trajectory at a time: the
    same values, status, n_steps and n_rhs, bitwise."""
    from mechsweep.engine import sampling as trajectory

    calls = []
    run_lanes = trajectory._run_lanes
    monkeypatch.setattr(trajectory, "_run_lanes", lambda *a, **k: calls.append(1) or run_lanes(*a, **k))
    rng = np.random.default_rng(3)
    n = 70  # more points than lanes
    P = np.column_stack([rng.uniform(0.5, 2, n), rng.uniform(0.05, 0.3, n), rng.uniform(-1, 1, n),
                         rng.choice([0.5, 1.3, 4.0], n)])
    P[::14, 3] = [0.7, 0.9, 2.2, 3.1, 5.0]  # periods of one point each: one trajectory at a time among the lanes
    P2 = np.column_stack([rng.uniform(-0.3, 0.6, 40), rng.uniform(0.5, 2.0, 40)])  # decays and grows
    cases = [(forced, P, WANTED, dict(rtol=1e-9, atol=1e-12, horizon_periods=50.0)),
             (decay, P2, ("stable", "stable_settling", "stable_final", "y_hist", "kick_rel", "kick_rel_settling",
                          "peak_rel", "y_rel"), dict(rtol=1e-9, atol=1e-12))]
    for spec, points, wanted, kw in cases:
        res = []
        for use in (False, True):
            monkeypatch.setattr(trajectory, "USE_LANES", use)
            res.append(_evaluate(spec, points, wanted, **kw))
        for x, y in zip(res[0][1:], res[1][1:]):
            assert np.array_equal(x, y)
        for k in wanted:
            assert np.array_equal(res[0][0][k], res[1][0][k], equal_nan=True), (spec.name, k)
    assert calls == [1, 1]  # the lanes were taken once per model (USE_LANES True)


@pytest.mark.slow  # compiles a kernel (about 7 s)
def test_recheck_flags_a_chaotic_trajectory_and_keeps_the_first_values():
    lorenz = user.resolve(f"{USER}:LORENZ")
    assert st.NOT_REPRODUCIBLE in lorenz.possible_statuses()
    P = np.array([[10.0, 28.0, 8.0 / 3.0], [10.0, 0.5, 8.0 / 3.0]])  # chaotic; a stable focus
    on, s_on, n_on, r_on = _evaluate(lorenz, P, ("xpeak",), rtol=1e-8, atol=1e-10)
    off, s_off, n_off, r_off = _evaluate(lorenz, P, ("xpeak",), rtol=1e-8, atol=1e-10, reproducibility_factor=0.0)
    assert s_on.tolist() == [st.NOT_REPRODUCIBLE, st.OK] and s_off.tolist() == [st.OK, st.OK]
    np.testing.assert_array_equal(on["xpeak"], off["xpeak"])  # the first run's values are kept
    # both points integrated again at rtol / 100 (more steps); the focus's peak agrees
    assert (n_on > 2 * n_off).all() and (r_on > r_off).all()
    tight, _, _, _ = _evaluate(lorenz, P[1:], ("xpeak",), rtol=1e-10, atol=1e-10, reproducibility_factor=0.0)
    assert abs(tight["xpeak"][0] - off["xpeak"][1]) <= 1000 * (1e-8 * abs(tight["xpeak"][0]) + 1e-10)


@pytest.mark.slow  # compiles a kernel (about 12 s)
def test_recheck_skips_the_points_that_settled_early():
    checked = user.resolve(f"{USER}:DECAY_CHECKED")
    # settles at ln(10) / lam: 4.6 s (< 20 s, half the horizon: skipped), 23 s (integrated again)
    P = np.array([[0.5, 0.1], [0.1, 0.1]])
    out, status, ns, _ = _evaluate(checked, P, ("stable",), rtol=1e-9, atol=1e-14)
    plain, s2, ns2, _ = _evaluate(user.resolve(f"{USER}:DECAY"), P, ("stable",), rtol=1e-9, atol=1e-14)
    assert status.tolist() == [st.OK, st.OK] and s2.tolist() == [st.OK, st.OK]
    assert ns[0] == ns2[0] and ns[1] > ns2[1]
    np.testing.assert_array_equal(out["stable"], plain["stable"])


def test_recheck_declarations_are_checked():
    from mechsweep.model import Kick, OdeModel, Recheck
    kw = dict(name="m", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
              initial=lambda p, y: None, measurements=(Kick("k", "y"),))
    with pytest.raises(ValueError, match="recheck: factor = 'nope' is not one of the model's settings"):
        OdeModel(recheck=Recheck(factor="nope"), **kw)
    with pytest.raises(ValueError, match="recheck: skip_settled = 'x'; expected the name of one of the model's Kick"):
        OdeModel(recheck=Recheck(skip_settled="x"), **kw)
    with pytest.raises(ValueError, match="recheck must be a mechsweep.model.Recheck"):
        OdeModel(recheck=1000.0, **kw)
    assert Recheck().tight_rtol(1e-8) == 1e-10 and Recheck().tight_rtol(1e-13) == 1e-14


@pytest.mark.slow  # two radau sampled kernels
def test_radau_counts_the_rhs_calls_of_the_engines_jacobian():
    """Without a declared jac radau's Jacobian is the engine's central differences: 2 n rhs calls each,
    counted in n_rhs (they were not, on this route). DECAY_FD_JAC declares the same differences as its
    jac (same floats, so the same steps), whose calls are not rhs calls: the counts differ by exactly
    2 n per Jacobian, and by some at every point."""
    decay, fdj = user.resolve(f"{USER}:DECAY"), user.resolve(f"{USER}:DECAY_FD_JAC")
    P = np.array([[0.5, 1.0], [2.0, 3.0], [0.05, 1.0], [-0.1, 1.0]])
    a = _evaluate(decay, P, ("stable", "y_hist"), method="radau", rtol=1e-8, atol=1e-12)
    b = _evaluate(fdj, P, ("stable", "y_hist"), method="radau", rtol=1e-8, atol=1e-12)
    for name in ("stable", "y_hist"):
        np.testing.assert_array_equal(a[0][name], b[0][name])
    np.testing.assert_array_equal(a[1], b[1])
    np.testing.assert_array_equal(a[2], b[2])  # the same steps
    extra = a[3] - b[3]
    assert (extra > 0).all() and (extra % 2 == 0).all(), (a[3], b[3])


def test_a_steady_or_rms_output_without_a_forcing_period_says_t_is_one_time_unit():
    """An RMS's window and a Steady's window and harmonic count in T = 1 time unit when the model declares
    no forcing period: each such output's long name says so once, and no longer speaks of a forcing period."""
    from mechsweep.model import RMS, OdeModel, Steady
    note = "(T = 1 time unit: the model declares no forcing period)"
    kw = dict(name="x", description="", params=(), states=("y",), rhs=lambda t, y, p, d: None,
              initial=lambda p, y: None, measurements=(RMS("y_rms", "y", horizon=10.0), Steady("amp", "y", horizon=10.0)))
    unforced = OdeModel(**kw).spec()
    forced = OdeModel(forcing_period=lambda p: 1.0, **kw).spec()
    for o in forced.outputs:
        long_name = unforced.output(o.name).long_name
        assert long_name.endswith(note) and long_name.count("T = 1") == 1, long_name
        assert "forcing period" not in long_name.replace(note, ""), long_name
        assert note not in o.long_name
    assert "(forcing period)" in forced.output("amp_h1").long_name
