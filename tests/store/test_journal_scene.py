"""What a refused resume says differs between the scene a journal was started from and the scene
given now (store/journal.scene_differences): each key with both values, as the user wrote them."""
import json

from mechsweep.store.journal import scene_differences

BEGAN = {"axes": [["W", {"num": 6, "spacing": "linear", "start": 0.5, "stop": 3.0}], ["zeta", [0.05, 0.2]]],
         "fixed": {"Y": 0.01, "w0": 1.0}, "model": "base_osc", "model_source_sha256": "aa",
         "outputs": ["t_peak", "z_rms"], "solver": {"atol": 1e-12, "max_steps": 100000, "method": "dop853",
                                                     "rtol": 1e-10}}


def changed(**edit):
    form = json.loads(json.dumps(BEGAN))
    for path, value in edit.items():
        *keys, last = path.split("__")
        place = form
        for k in keys:
            place = place[k]
        if value is None:
            del place[last]
        else:
            place[last] = value
    return json.dumps(form, sort_keys=True)


def test_each_changed_key_is_named_with_both_values():
    began = json.dumps(BEGAN, sort_keys=True)
    assert scene_differences(began, began) == ""
    assert scene_differences(began, changed(fixed__Y=0.02)) == "fixed.Y: 0.01 when the run began, 0.02 now"
    assert scene_differences(began, changed(solver__method="radau", outputs=["t_peak"])) == (
        "outputs: [\"t_peak\", \"z_rms\"] when the run began, [\"t_peak\"] now; "
        "solver.method: \"dop853\" when the run began, \"radau\" now")
    assert scene_differences(began, changed(model_source_sha256="bb")) == (
        "the model's source files changed")


def test_axes_are_named_by_parameter_and_their_order_counts():
    began = json.dumps(BEGAN, sort_keys=True)
    form = json.loads(began)
    form["axes"][0][1]["num"] = 7
    assert scene_differences(began, json.dumps(form)) == "axes.W.num: 6 when the run began, 7 now"
    form = json.loads(began)
    form["axes"].reverse()
    assert scene_differences(began, json.dumps(form)) == "axes: in the order W, zeta when the run began, zeta, W now"
    form = json.loads(began)
    form["axes"][1] = ["Y", [0.01, 0.02]]
    form["fixed"] = {"zeta": 0.1, "w0": 1.0}
    assert scene_differences(began, json.dumps(form)) == (
        "axes.Y: not given when the run began, [0.01, 0.02] now; axes.zeta: [0.05, 0.2] when the run began, "
        "not given now; fixed.Y: 0.01 when the run began, not given now; and 1 more")


def test_a_form_that_is_not_json_says_nothing():
    assert scene_differences("not json", json.dumps(BEGAN)) == ""
