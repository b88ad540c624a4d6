"""A declaration's names and metadata of the outputs of its multi-output measurements
(``output_meta``) and its cross-parameter rules (``OdeModel.check``): tests/user_models/declared_meta.py."""
import dataclasses
from pathlib import Path

import numpy as np
import pytest

from mechsweep import status as st
from mechsweep.errors import InputError
from mechsweep.model import ClosedForm, Floquet, History, Kick, OdeModel, Steady, user
from mechsweep.scene import Solver, load_scene
from tests import evaluating

USER = Path(__file__).resolve().parents[1] / "user_models"
FILE = USER / "declared_meta.py"
import sys  # noqa: E402

sys.path.insert(0, str(USER))
import declared_meta as dm  # noqa: E402
import forced  # noqa: E402


def test_output_meta_names_and_describes_each_output():
    spec = dm.RENAMED.spec()
    assert spec.output_names() == ("stable_sim", "settling_time", "final_error", "peak", "peak_harmonic", "peak_lag",
                                   "y_hist", "mu", "mu_stable_old", "mu_crit_kind", "mu_crit_angle", "kind_sq")
    o = spec.output("stable_sim")
    assert (o.symbol, o.unit, o.long_name, o.kind) == ("stable (simulation)", "1", "1 if the kick decays", "verdict")
    o = spec.output("settling_time")  # the generic symbol and unit kept, the long name set
    assert (o.symbol, o.unit, o.long_name) == ("t_s", "s", "time until |y| < 0.01")
    o = spec.output("final_error")
    assert (o.symbol, o.unit, o.long_name) == ("|y(end)|", "1", "error at the end of the simulation")
    assert spec.output("peak_lag").unit == "degree" and spec.output("peak_harmonic").symbol == "A1"
    assert spec.output("y_hist").symbol == "y(t)" and spec.output("y_hist").extra_dims[0].name == "time"
    assert spec.output("mu_crit_angle").symbol == "θ" and spec.output("mu_crit_angle").needs == ("mu",)
    assert spec.output("mu_stable_old").kind == "verdict"
    # the names the kernel's values and the closed forms read
    floquet = dm.RENAMED.measurements[3]
    assert floquet.values() == ("mu", "mu_crit_kind", "mu_crit_angle")


def test_without_output_meta_the_generic_outputs_are_unchanged():
    spec = user.resolve(f"{USER / 'forced.py'}:DECAY")
    o = {x.name: x for x in spec.outputs}
    assert [k for k in o if k.startswith("stable")] == ["stable", "stable_settling", "stable_final"]
    assert (o["stable"].symbol, o["stable_settling"].long_name, o["stable_final"].symbol) == (
        "stable (kick)", "time after which the error stays below settle_threshold", "e_end")
    assert forced.CUBIC.spec().output_names() == ("mu", "mu_stable", "mu_kind", "mu_angle", "mu_rest", "rest_stable",
                                                  "rest_kind", "mu_rest_angle")


@pytest.mark.parametrize("meta, message", [
    ({"x_settling": dict(name="t")}, "output_meta names 'x_settling', which is not one of its generic outputs"),
    ({"k_settling": dict(colour="red")}, "output_meta['k_settling'] sets 'colour'; allowed: name, symbol"),
    ({"k": dict(name="other")}, "cannot rename the main output 'k'"),
    ({"k_final": dict(name="k settling")}, "expected a string that is an identifier"),
    ({"k_final": dict(name="k_settling")}, "repeated output names"),
    ("nonsense", "output_meta must map generic output names to dicts"),
])
def test_bad_output_meta_is_refused(meta, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace("[", r"\[")):
        OdeModel(name="bad", description="", params=dm.RENAMED.params, states=("y",), rhs=dm.rhs, initial=dm.initial,
                 measurements=(Kick("k", dm.error, output_meta=meta),))


def test_closed_forms_read_a_renamed_value_and_not_its_generic_name():
    assert dm.RENAMED.spec().output("kind_sq").needs == ("mu_crit_kind",)
    with pytest.raises(ValueError, match=r"needs \['mu_kind'\], which are not other outputs"):
        dataclasses.replace(dm.RENAMED, closed_forms=(ClosedForm("kind_sq", dm.kind_squared, needs=("mu_kind",)),))
    with pytest.raises(ValueError, match="both stable_name and output_meta"):
        Floquet("mu", stable_name="a", output_meta={"mu_stable": dict(name="b")}).validate(("y",))


def _scene(lam, y0):
    return {"scene": {"name": "c", "model": f"{FILE}:RENAMED", "outputs": ["peak"]},
            "axes": {"lam": lam}, "fixed": {"y0": y0}}


def test_the_models_check_refuses_a_scene_naming_the_rule():
    load_scene(_scene({"start": -0.5, "stop": 0.5, "num": 3}, 1.0))  # allowed: y0 = 1
    with pytest.raises(InputError, match=r"y0: 2 > 1 with lam = -0.5 < 0; a growing motion \(lam < 0\) must start"):
        load_scene(_scene({"start": -0.5, "stop": 0.5, "num": 3}, 2.0))
    with pytest.raises(InputError, match="y0: 2 > 1 with lam = -0.1"):  # a list axis: its values
        load_scene(_scene([0.2, -0.1], 2.0))
    with pytest.raises(ValueError, match="check must be a function"):
        dataclasses.replace(dm.RENAMED, check=3)


def test_a_scene_the_check_refuses_exits_2(in_tmp, capsys):
    from mechsweep.cli import main
    scene = in_tmp / "s.toml"
    scene.write_text(f'[scene]\nname = "c"\nmodel = "{FILE}:RENAMED"\noutputs = ["peak"]\n'
                     '[axes]\nlam = { start = -0.5, stop = 0.5, num = 3 }\n[fixed]\ny0 = 2.0\n')
    before = sorted(p.relative_to(in_tmp) for p in in_tmp.rglob("*") if "__pycache__" not in p.parts)
    assert main(["run", str(scene), "--no-progress", "--threads", "1"]) == 2
    err = capsys.readouterr().err
    assert "y0: 2 > 1 with lam = -0.5 < 0" in err and "Traceback" not in err
    assert sorted(p.relative_to(in_tmp) for p in in_tmp.rglob("*") if "__pycache__" not in p.parts) == before


@pytest.mark.slow  # integrates (one sampled kernel)
def test_renamed_outputs_get_the_generic_values_and_statuses():
    # the renamed Kick/Steady/History against the same measurements under their generic names
    # (forced.DECAY's Kick "stable", the same fields): bitwise, with the same statuses
    lam = np.array([0.5, 0.2, -0.05, 1e-6])
    P = np.column_stack([lam, np.full(4, 0.1)])
    generic = OdeModel(name="decay_generic", description="", params=dm.RENAMED.params, states=("y",), rhs=dm.rhs,
                       initial=dm.initial, forcing_period=dm.period,
                       measurements=(Kick("stable_sim", dm.error, **dm.KICK),
                                     Steady("peak", "y", horizon=40.0, window=0.1, samples_per_period=8,
                                            settle_rtol=None),
                                     History("y_hist", "y", horizon=40.0, samples=9, dim="time")))
    runs = []
    for spec, names in ((dm.RENAMED.spec(), ("stable_sim", "settling_time", "final_error", "peak", "peak_harmonic",
                                             "peak_lag", "y_hist")),
                        (generic.spec(), ("stable_sim", "stable_sim_settling", "stable_sim_final", "peak", "peak_h1",
                                          "peak_phase", "y_hist"))):
        slv = Solver.for_model(spec, rtol=1e-10, atol=1e-13, max_steps=10**6)
        out, status, _, _ = evaluating.evaluate(spec, P, names, slv)
        runs.append(([out[k] for k in names], status))
        # the settling output alone still decides NO_EVENT (lam < 0 never settles)
        _, status1, _, _ = evaluating.evaluate(spec, P, names[1:2], slv)
        assert status1[2] == st.NO_EVENT
    (a, sa), (b, sb) = runs
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)
    np.testing.assert_array_equal(sa, sb)
    assert sa[3] == st.UNDECIDED and sa[2] == st.NO_EVENT and np.isfinite(a[4]).all()
