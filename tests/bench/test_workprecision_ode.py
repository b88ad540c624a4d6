"""`mechsweep bench workprecision FILE.py:NAME --scene S.toml`: the work-precision report of a model
the bench has never heard of, against scipy running the model's OWN rhs and initial state."""
import math
from pathlib import Path

import numpy as np
import pytest

from mechsweep.bench import workprecision as wp
from mechsweep.bench import workprecision_ode as wo
from mechsweep.errors import InputError

from tests.conftest import REPO

USER = REPO / "tests" / "user_models"
LINEAR = f"{USER / 'oscillators.py'}:LINEAR"
PENDULUM = f"{USER / 'oscillators.py'}:PENDULUM"  # its period kernel: the one tests/model/test_model_layer.py compiles


def declaration(ref):
    """The OdeModel object a model reference names, as the bench loads it."""
    return wp.resolve_model(ref).declaration


SCENE = """
[scene]
name = "lin"
model = "{model}"
outputs = ["period"]
[axes]
w = {{ start = 0.5, stop = 10.0, num = 40 }}
[fixed]
A = 0.7
"""


def test_scipy_versions_of_the_measurements_match_the_closed_forms():
    """Each generic measurement re-done by scipy on the model's own functions (DOP853, rtol 1e-13):
    period 2 pi / w, x(2) = A cos 2w, max v = A w, the pendulum's period 4 K(sin^2(A/2)) sqrt(L/g),
    the Floquet modulus of Mathieu's equation (central differences; the model's jac)."""
    from scipy.special import ellipk

    lin = declaration(LINEAR)
    P = np.array([[w, 0.7] for w in (0.5, 1.7, 10.0)])
    w = P[:, 0]
    np.testing.assert_allclose(wo.OdeReference(lin, "period").reference(P), 2 * np.pi / w, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(lin, "x_at_2").reference(P), 0.7 * np.cos(2 * w), atol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(lin, "v_max").reference(P), 0.7 * w, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(lin, "t_half_down").reference(P), np.pi / 3 / w, rtol=1e-11)
    pend = declaration(f"{USER / 'oscillators.py'}:PENDULUM")
    A = 2.5
    ref = wo.OdeReference(pend, "period").reference(np.array([[9.81, 0.5, A]]))[0]
    assert ref == pytest.approx(4 * ellipk(math.sin(A / 2) ** 2) * math.sqrt(0.5 / 9.81), rel=1e-11)
    # undamped, inside the first stability region: both multipliers on the unit circle
    undamped = wo.OdeReference(declaration(f"{USER / 'mathieu.py'}:MATHIEU"), "max_multiplier")
    assert undamped.reference(np.array([[0.2, 0.5]]))[0] == pytest.approx(1.0, abs=1e-10)
    damped = wo.OdeReference(declaration(f"{USER / 'mathieu.py'}:MATHIEU_JAC"), "max_multiplier")
    assert "the model's jac" in damped.reference_name
    assert damped.reference(np.array([[0.2, 0.5, 0.2]]))[0] == pytest.approx(math.exp(-0.2 * math.pi / 2), rel=1e-10)


def test_report_of_a_user_model(tmp_path):
    scene = tmp_path / "pendulum.toml"
    scene.write_text(SCENE.format(model=PENDULUM).replace("w = {", "A = {").replace("stop = 10.0", "stop = 3.0")
                     .replace("A = 0.7", "g = 9.81\nL = 0.5"))
    ds = wp.main(PENDULUM, str(scene), points=4, scipy_points=2, ladder=(1e-6, 1e-10), repeats=1, out_dir=tmp_path,
                 quiet=True)
    assert (tmp_path / "workprecision_pendulum.h5").is_file()
    assert ds.attrs["model"] == "pendulum" and ds.attrs["output"] == "period"
    ours, scipy = ds.sel(integrator="mechsweep dop853"), ds.sel(integrator="scipy DOP853")
    assert (ours.ok_fraction.values == 1).all() and (scipy.ok_fraction.values == 1).all()
    assert ours.error_max.values[1] < 1e-3 * ours.error_max.values[0] and ours.error_max.values[1] < 1e-9
    # the same method and step control on the same equations: the errors agree to a few percent
    np.testing.assert_allclose(ours.error_max.values, scipy.error_max.values, rtol=0.1)
    # the pendulum declares its energy conserved (an Invariant): its drift is in the report, at the
    # declaration's point, periods and rtols (dop853 only: no accel), growing with the periods
    assert ds.attrs["drift_quantity"] == "energy"
    assert ds.attrs["drift_problem"] == "pendulum at g = 9.81, L = 0.5, A = 1, one integration over 100 periods"
    assert list(ds.drift_run.values) == ["mechsweep dop853, rtol 1e-06"] and list(ds.periods.values) == [1, 10, 100]
    e = ds.energy_error.values[0]
    assert 0 < e[0] < e[1] < e[2] < 1e-3 and e[2] > 10 * e[0]
    assert (tmp_path / "workprecision_pendulum_energy.csv").is_file()


def test_bad_requests_are_input_errors(tmp_path):
    scene = tmp_path / "lin.toml"
    scene.write_text(SCENE.format(model=LINEAR))
    with pytest.raises(InputError, match="has no reference scene; give one with --scene"):
        wp.main(LINEAR)
    with pytest.raises(InputError, match="is for model 'linear_oscillator'.*not .*PENDULUM"):
        wp.main(f"{USER / 'oscillators.py'}:PENDULUM", str(scene))
    with pytest.raises(InputError, match="--output 'nothing' is not an output of model 'linear_oscillator'"):
        wp.main(LINEAR, str(scene), output="nothing")


def test_scipy_versions_of_nth_roots_and_extrema_of_expressions():
    """FirstEvent (n-th root, either direction) and Extremum of an expression over windows given by
    functions of p, re-done by scipy on the model's own functions: x = A cos(w t), v = -A w sin(w t)
    (tests/user_models/measure_more.py)."""
    more = declaration(f"{USER / 'measure_more.py'}:MODEL")
    P = np.array([[w, 0.7] for w in (0.5, 1.7, 3.0)])
    w = P[:, 0]
    np.testing.assert_allclose(wo.OdeReference(more, "down3").reference(P), 17 * np.pi / 4 / w, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(more, "up2").reference(P), 13 * np.pi / 4 / w, rtol=1e-11)
    assert wo.OdeReference(more, "down3").error == "relative"
    np.testing.assert_allclose(wo.OdeReference(more, "period_up").reference(P), 2 * np.pi / w, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(more, "two_periods").reference(P), 2 * np.pi / w, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(more, "ke_max").reference(P), 0.5 * (0.7 * w) ** 2, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(more, "power_late").reference(P), 0.49 * w / 2, rtol=1e-11)
    np.testing.assert_allclose(wo.OdeReference(more, "power_early").reference(P), -0.49 * w / 2 * math.sin(0.2),
                               rtol=1e-11)


def test_scipy_versions_of_a_system_and_a_refined_measurement():
    """A FirstEvent integrating a System of its own (tests/user_models/layer_systems.py: x'' = -4 w^2 x
    from x = 1, its prepare refusing w > 5) and one with a refine (factor = the parameter tighten):
    scipy runs the System's rhs and initial state after its prepare, and refine decides as the
    engine's: a second pass at rtol / f, atol / f from the start (both counted), not finite: NaN."""
    model = declaration(f"{USER / 'layer_systems.py'}:SYSTEMS")
    P = np.array([[1.0, 0.5, 1.0], [2.0, 0.3, 1.0], [6.0, 0.5, 1.0]])
    half = wo.OdeReference(model, "half").reference(P)
    np.testing.assert_allclose(half[:2], np.pi / P[:2, 0], rtol=1e-11)  # the System's equation, not the model's
    assert np.isnan(half[2])  # its prepare: INFEASIBLE
    refined = wo.OdeReference(model, "refined")
    one = refined.value([1.0, 0.5, 1.0], "DOP853", 2.0**-20, 2.0**-30)  # factor 1: one pass
    tight = refined.value([1.0, 0.5, 1.0], "DOP853", 2.0**-33, 2.0**-43)
    two = refined.value([1.0, 0.5, 2.0**13], "DOP853", 2.0**-20, 2.0**-30)
    assert two[0] == tight[0] != one[0] and two[1:] == (one[1] + tight[1], one[2] + tight[2])
    assert math.isnan(refined.value([1.0, 0.5, math.inf], "DOP853", 1e-6, 1e-8)[0])  # ILL_CONDITIONED


def test_an_invariant_is_checked_when_the_model_is_declared():
    from mechsweep.model import Invariant, OdeModel, Param

    def energy(y, p):
        return y[0]

    base = dict(name="m", description="", params=(Param("w", "w", "1", "w"), Param("k", "k", "1", "k",
                                                                                        required=False, default=0.0)),
                states=("x", "v"), rhs=energy, initial=energy)
    assert OdeModel(**base, invariant=Invariant(energy, at={"w": 1.0})).invariant.periods[-1] == 10000
    for inv, match in ((Invariant(energy, at={"w": 1.0, "x": 2.0}), r"at names \['x'\], which are not parameters"),
                       (Invariant(energy, at={"k": 1.0}), r"at does not give the required parameters \['w'\]"),
                       (Invariant(energy, at={"w": 1.0}, period=-1.0), "period = -1.0; expected"),
                       (Invariant(energy, at={"w": 1.0}, periods=(10, 1)), "periods = \\(10, 1\\); expected"),
                       ("energy", "invariant must be a mechsweep.model.Invariant")):
        with pytest.raises(ValueError, match=match):
            OdeModel(**base, invariant=inv)


HARMONIC = f"{USER / 'harmonic_wp.py'}:HARMONIC"  # declares WorkPrecision(scene, output, reference=its ClosedForm)


def test_a_user_closed_form_declared_as_the_reference(tmp_path, monkeypatch):
    """A user model's WorkPrecision: no --scene (its scene is named relative to the model file,
    found from any working folder), and its own ClosedForm period_exact = 2 pi / w is the reference
    every method's error is measured against; scipy still runs the model's own rhs."""
    monkeypatch.chdir(tmp_path)  # the declared scene is found next to the model file, not in the cwd
    ds = wp.main(HARMONIC, points=3, scipy_points=1, ladder=(1e-10,), repeats=1, out_dir=tmp_path, quiet=True)
    assert ds.attrs["reference"] == "the model's closed form period_exact (period 2 pi / w)"
    assert ds.attrs["norm"] == "relative error |period - period_exact| / |period_exact|"
    assert ds.attrs["scene"] == str(USER / "harmonic_wp.toml") and ds.attrs["output"] == "period"
    assert list(ds.integrator.values) == ["mechsweep dop853", "scipy DOP853", "scipy Radau", "scipy LSODA"]
    # the errors are against 2 pi / w: recomputed here from the same sample and the model's values
    from mechsweep.bench.workprecision import _run_ours, sample
    from mechsweep.scene import Solver, load_scene

    scene = load_scene(USER / "harmonic_wp.toml")
    P = sample(scene, 3)
    solver = Solver.for_model(scene.model, rtol=1e-10, atol=1e-10 * wp.ATOL_RATIO)
    period = _run_ours(scene.model, P, "period", solver)[0]
    err = np.abs(period - 2 * np.pi / P[:, 0]) / (2 * np.pi / P[:, 0])
    assert float(ds.error_max_sample.sel(integrator="mechsweep dop853", rtol=1e-10)) == err.max()
    assert 0 < err.max() < 1e-8
    ours, scipy = ds.sel(integrator="mechsweep dop853"), ds.sel(integrator="scipy DOP853")
    np.testing.assert_allclose(ours.error_max.values, scipy.error_max.values, rtol=0.1)  # same method, same rhs
    with pytest.raises(InputError, match="--output 'nothing' is not an output of model 'harmonic_wp'"):
        wp.main(HARMONIC, output="nothing")


def test_a_model_without_a_declared_report_is_told_what_to_declare(tmp_path):
    with pytest.raises(InputError, match=r"has no reference scene; give one with --scene S.toml .* or declare it with "
                                         r"the model: OdeModel\(\.\.\., workprecision=WorkPrecision\(scene="):
        wp.main(LINEAR)
    import dataclasses

    from mechsweep.model import WorkPrecision

    lost = dataclasses.replace(declaration(HARMONIC), name="lost", workprecision=WorkPrecision(scene="nowhere.toml"))
    with pytest.raises(InputError, match=r"names scene 'nowhere.toml', which is not a file: .*tests/bench/nowhere.toml \(a "
                                         r"path relative to the folder of the file that declares it"):
        wp.declared_scene(lost.workprecision)
    from mechsweep.bench import workprecision_linkage as wl

    with pytest.raises(InputError, match=r"no linkage work-precision case for model .*LINEAR.*SizeWorkPrecision"):
        wl.main(LINEAR)


def test_a_work_precision_declaration_is_checked_when_the_model_is_declared():
    from mechsweep.model import ClosedForm, OdeModel, Param, Period, WorkPrecision

    def f(t, y, p, d):
        d[0] = y[1]

    def exact(p):
        return 1.0

    def from_period(p, T):
        return T

    base = dict(name="m", description="", params=(Param("w", "w", "1", "w"),), states=("x", "v"), rhs=f, initial=f,
                measurements=(Period("period", "x", t_max=10.0),),
                closed_forms=(ClosedForm("T_exact", exact), ClosedForm("T_again", from_period, needs=("period",))))
    ok = OdeModel(**base, workprecision=WorkPrecision(scene="s.toml", output="period", reference="T_exact"))
    assert ok.workprecision.base == str(Path(__file__).resolve().parent)  # the folder of the declaring file
    for decl, match in ((WorkPrecision(output="T_exact"), "output = 'T_exact' is not a measured output"),
                        (WorkPrecision(output="period", reference="nothing"), "reference = 'nothing' is not one of"),
                        (WorkPrecision(output="period", reference="T_again"),
                         r"reference 'T_again' needs the integrated outputs \['period'\]"),
                        (WorkPrecision(reference="T_exact"), "is given without the output"),
                        (WorkPrecision(scene="s.txt"), "expected a scene file ending in .toml"),
                        ("period", "workprecision must be a mechsweep.model.WorkPrecision")):
        with pytest.raises(ValueError, match=match):
            OdeModel(**base, workprecision=decl)


def test_the_reference_steps_onto_a_models_switch_times():
    """Square-wave stiffness x'' + (delta + eps sign(cos t)) x = 0 (tests/user_models/switched.py),
    exact by 2 x 2 matrix exponentials of the segments: with the declared switch times every scipy
    run is restarted at each switch as the engine's, so x(10) by DOP853 at rtol 1e-10 is within
    ~1e-10 (measured 1.5e-10) and the reference (rtol 1e-13) within 1e-12 (1.6e-13); the same
    equation without them: 6.9e-9 and 8.9e-12. The Floquet reference with the exact jac: 3.1e-13
    relative against 4.3e-12 (its central differences would bound both near 1e-10)."""
    from tests.engine.test_switch_times import ROWS, _M, exact

    P = np.column_stack([ROWS, np.zeros(len(ROWS))])
    x10 = np.array([exact(d, e, 10.0)[0] for d, e, _ in P])
    mu = np.array([max(abs(np.linalg.eigvals(_M(d + e, 0.5 * math.pi) @ _M(d - e, math.pi) @ _M(d + e, 0.5 * math.pi))))
                   for d, e, _ in P])
    err = {}
    for name in ("SWITCHED", "UNDECLARED"):
        ref = wo.OdeReference(declaration(f"{USER / 'switched.py'}:{name}"), "x_end")
        assert ref.reference_name.endswith("restarted at each of its switch times") == (name == "SWITCHED")
        at = np.array([ref.value(row, "DOP853", 1e-10, 1e-12)[0] for row in P])
        err[name] = (np.abs(ref.reference(P) - x10).max(), np.abs(at - x10).max())
        floquet = wo.OdeReference(declaration(f"{USER / 'switched.py'}:{name}_JAC"), "mu")
        err[name] += (np.abs(floquet.reference(P) / mu - 1.0).max(),)
    assert err["SWITCHED"][0] < 1e-12 and err["SWITCHED"][1] < 3e-10 and err["SWITCHED"][2] < 1e-12, err
    assert err["UNDECLARED"][0] > 3e-12 and err["UNDECLARED"][1] > 3e-9 and err["UNDECLARED"][2] > 2e-12, err
