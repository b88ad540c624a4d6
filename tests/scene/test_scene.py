"""Scene validation: every shipped scene loads; every bad input names key, value and range."""
import copy
import math

import pytest

from mechsweep.scene import SceneError, load_scene, to_toml, validate

from tests.conftest import SMALL_DUFFING, SWEEPS

SHIPPED = sorted(SWEEPS.rglob("*.toml"))


def test_there_are_shipped_scenes():
    assert len(SHIPPED) >= 3


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_scene_is_valid(path):
    scene = load_scene(path)
    assert scene.n_points >= 1 and scene.outputs
    assert scene.text == path.read_text()


def problems(mutate):
    data = copy.deepcopy(SMALL_DUFFING)
    mutate(data)
    with pytest.raises(SceneError) as info:
        load_scene(data)
    return "\n".join(info.value.problems)


@pytest.mark.parametrize("mutate,expected", [
    (lambda d: d["scene"].update(model="dufing"), ["scene.model", "'dufing'", "did you mean 'duffing'"]),
    (lambda d: d["scene"].update(outputs=["perod"]), ["scene.outputs", "did you mean 'period'"]),
    (lambda d: d["scene"].update(outputs=[]), ["scene.outputs", "non-empty list"]),
    (lambda d: d["scene"].update(outputs=["period", "period"]), ["listed twice"]),
    (lambda d: d["axes"].update(omgea={"start": 1, "stop": 2, "num": 3}), ["axes.omgea", "did you mean 'omega'"]),
    (lambda d: d["fixed"].update(A=0.5), ["fixed.A", "both as an axis and as a fixed value"]),
    (lambda d: d["fixed"].pop("omega"), ["fixed.omega", "missing", "(0, inf)"]),
    (lambda d: d["fixed"].update(omega=-1.0), ["fixed.omega", "-1.0", "(0, inf)"]),
    (lambda d: d["fixed"].update(omega=math.nan), ["fixed.omega", "not finite"]),
    (lambda d: d["fixed"].update(omega=math.inf), ["fixed.omega", "not finite"]),
    (lambda d: d["fixed"].update(omega=True), ["fixed.omega", "not a number"]),
    (lambda d: d["fixed"].update(omega="fast"), ["fixed.omega", "'fast'", "not a number"]),
    (lambda d: d["axes"]["A"].update(start=-1.0), ["axes.A.start", "-1.0", "[0, inf)"]),
    (lambda d: d["axes"]["A"].update(num=0), ["axes.A.num", "whole number"]),
    (lambda d: d["axes"]["A"].update(num=2.5), ["axes.A.num", "whole number"]),
    (lambda d: d["axes"]["A"].update(spacing="log", start=0.0), ["log spacing needs start > 0"]),
    (lambda d: d["axes"]["A"].update(spacing="cubic"), ["axes.A.spacing", "'cubic'"]),
    (lambda d: d["axes"]["A"].update(step=0.1), ["axes.A.step", "unknown axis key"]),
    (lambda d: d["axes"].update(A=[]), ["axes.A", "empty list"]),
    (lambda d: d["axes"].update(A=[0.1, 0.1]), ["axes.A", "repeat"]),
    (lambda d: d["axes"].update(A=[0.1, -2.0]), ["axes.A[1]", "-2.0"]),
    (lambda d: d["axes"].update(A=3.0), ["axes.A", "list of values or a table"]),
    (lambda d: d["solver"].update(rtol=0.0), ["solver.rtol", "outside the allowed range"]),
    (lambda d: d["solver"].update(method="euler"), ["solver.method", "'euler'", "dop853"]),
    (lambda d: d["solver"].update(max_steps=10.5), ["solver.max_steps", "whole number"]),
    (lambda d: d["solver"].update(tol=1e-3), ["solver.tol", "did you mean 'rtol'"]),
    (lambda d: d.update(axis={}), ["axis", "unknown section", "did you mean 'axes'"]),
    (lambda d: d["storage"].update(chunk_size=0), ["storage.chunk_size"]),
    (lambda d: d["scene"].pop("name"), ["scene.name"]),
])
def test_bad_input_names_key_value_and_allowed(mutate, expected):
    text = problems(mutate)
    for piece in expected:
        assert piece in text, f"{piece!r} missing from:\n{text}"


def test_all_problems_reported_together():
    def mutate(d):
        d["fixed"]["omega"] = -1.0
        d["solver"]["rtol"] = 5.0
    assert problems(mutate).count("\n") >= 1


def test_a_key_that_is_not_text_is_reported_not_a_traceback():
    """A dict scene may have keys TOML cannot: an unknown section or key that is a number is
    reported like any unknown key (it was a TypeError from the message's formatting)."""
    data = copy.deepcopy(SMALL_DUFFING)
    data[3] = {}
    data["scene"][7] = 1
    with pytest.raises(SceneError) as info:
        load_scene(data)
    assert any(p.startswith("3: unknown section 3") for p in info.value.problems), info.value.problems
    assert any(p.startswith("scene.7: unknown key 7") for p in info.value.problems), info.value.problems


def test_categorical_parameter():
    data = {"scene": {"name": "t", "model": "torsional_circuit", "outputs": ["chi"]},
            "axes": {"spring": ["tension", "compresion"], "lambda2": {"start": 0, "stop": 1, "num": 3}},
            "fixed": {"lambda1": 0.8, "s0_over_r": 0.1}}
    with pytest.raises(SceneError, match=r"axes.spring\[1\].*'compresion'.*'tension', 'compression'"):
        load_scene(data)


def test_output_needing_optional_parameter():
    data = {"scene": {"name": "t", "model": "torsional_circuit", "outputs": ["period"]},
            "axes": {"lambda2": {"start": 0.1, "stop": 1, "num": 3}},
            "fixed": {"spring": "tension", "lambda1": 0.8, "s0_over_r": 0.1}}
    with pytest.raises(SceneError, match="output 'period' needs parameter\\(s\\) A, R, c, I"):
        load_scene(data)


def test_solver_only_for_integrated_outputs():
    data = copy.deepcopy(SMALL_DUFFING)
    data["scene"]["outputs"] = ["period_exact", "v_max"]
    assert load_scene(data).solver is None
    assert load_scene(SMALL_DUFFING).solver is not None


def test_scene_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(b"[scene\nname = 1")
    with pytest.raises(SceneError, match="TOML syntax error"):
        load_scene(bad)
    bad.write_bytes(b"\xff\xfe[scene]")
    with pytest.raises(SceneError, match="not UTF-8"):
        load_scene(bad)
    with pytest.raises(SceneError, match="does not exist"):
        load_scene(tmp_path / "missing.toml")
    with pytest.raises(SceneError, match="is a directory"):
        load_scene(tmp_path)


def test_dict_round_trips_through_toml_text():
    scene = load_scene(SMALL_DUFFING)
    again = validate(__import__("tomllib").loads(to_toml(SMALL_DUFFING)), text="")
    assert again.canonical() == scene.canonical()


def test_log_axis_keeps_exact_ends():
    data = copy.deepcopy(SMALL_DUFFING)
    data["axes"]["mu"] = {"start": 1e-3, "stop": 1e3, "num": 61, "spacing": "log"}
    axis = [a for a in load_scene(data).axes if a.name == "mu"][0]
    assert axis.values[0] == 1e-3 and axis.values[-1] == 1e3 and len(axis.values) == 61


def test_a_long_list_of_allowed_names_is_printed_once():
    """A scene written for another model: every unknown output named, the model's 50 outputs listed
    once (the message grew past 8,000 characters, a fuzzed scene found it)."""
    from mechsweep.scene import SceneError
    outputs = ["floquet_max", "stable_floquet", "P_approx", "omega_p"]
    with pytest.raises(SceneError) as err:
        load_scene({"scene": {"name": "x", "model": "fourbar_balancing", "outputs": outputs},
                    "axes": {"omega": [1.0, 2.0]}})
    text = str(err.value)
    assert all(f"'{o}'" in text for o in outputs)
    assert text.count("dM_inertia_phi") == 1 and text.count("(allowed: as above)") == len(outputs) - 1, text


def test_a_method_for_a_model_that_integrates_nothing_says_so():
    """solver.method for a closed-form model (every output a closed form) is refused saying that
    no integration method applies; it was 'unknown method ... (allowed: dop853)', as if dop853
    integrated something there (a docs-only trial asked radau for its slider-crank)."""
    import tomllib

    data = tomllib.loads((SWEEPS / "fourbar_methods.toml").read_text())
    data["solver"] = {"method": "radau"}
    with pytest.raises(SceneError) as err:
        load_scene(data)
    text = str(err.value)
    assert ("solver.method: 'radau' is not allowed: model 'fourbar_balancing' integrates nothing (every output is a "
            "closed form), so no integration method applies; leave solver.method out") in text, text
    assert "allowed: dop853" not in text
