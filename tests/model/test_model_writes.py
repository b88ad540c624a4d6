"""A model function may write only what its role writes (model/writes.py): an rhs its dydt,
initial its y0, prepare the internal slots of p, compute its row, curves and scratch; an event, an
expression, a closed form, classify and the others nothing. An event that bounced a ball by writing
``y[1] = -e * y[1]`` was accepted and gave wrong apex times with status ok: now every
such model is refused when it is loaded (exit 2), naming the function, the argument, file and line.
Nothing here compiles a kernel: the check runs before numba does."""
from __future__ import annotations

import glob
import importlib
import pkgutil
import re
from pathlib import Path

import numba
import numpy as np
import pytest

import mechsweep.models
from mechsweep.errors import InputError
from mechsweep.model import closed, load, user, writes
from mechsweep.model.closed import ClosedFormModel
from mechsweep.model.ode import OdeModel

HERE = Path(__file__).resolve().parents[1]
USER = HERE / "user_models"
HOSTILE = USER / "hostile_writes.py"


def _line(text: str) -> int:
    """The line of hostile_writes.py that holds ``text`` (the messages name it)."""
    lines = HOSTILE.read_text().splitlines()
    return next(i for i, s in enumerate(lines, 1) if text in s)


# model of tests/user_models/hostile_writes.py -> (function and argument named, the line's text, the rule)
CASES = {
    "EVENT_WRITES_STATE": ("event of FirstEvent 'apex' writes into its state argument y", "y[1] = -p[2] * y[1]",
                           "an event may not change the state"),
    "EVENT_WRITES_ALIAS": ("event of FirstEvent 'apex' writes into its state argument y", "z[0] = 0.0",
                           "state jumps are not supported"),
    "EVENT_SAME_FILE_HELPER": ("writes into its state argument y", "negate(y, 1)",
                               "through negate, which writes it at"),
    "EVENT_MODULE_HELPER": ("writes into its state argument y", "hostile_helpers.negate(y, 1)",
                            "hostile_helpers.py:10 (v[k] = -v[k])"),
    "EVENT_JITTED": ("event of FirstEvent 'apex' writes into its state argument y", "y[0] = max(y[0], 0.0)",
                     "an event may not"),
    "RHS_WRITES_P": ("rhs writes into its parameter argument p", "p[0] += 1e-9 * t", "its 4th argument (dydt)"),
    "RHS_WRITES_STATE": ("rhs writes into its state argument y", "np.copyto(y, np.maximum(y, -1.0))", "(dydt)"),
    "EXPRESSION_WRITES_STATE": ("expression of Extremum 'e_max' writes into its state argument y", "y[:] = np.abs(y)",
                                "may not write into its arguments"),
    "KICK_ERROR_WRITES_STATE": ("error of Kick 'settles' writes into its state argument y", "y.fill(0.0)",
                                "may not write"),
    "VALUE_WRITES_P": ("value of FirstEvent 'apex' writes into its parameter argument p", "q[0] = t",
                       "value may not write into p"),
    "PREPARE_WRITES_PARAMETER": ("prepare writes into its parameter argument p", "p[0] = 2.0 * p[0]",
                                 "only the model's internal slots of p (p[3:4]"),
    "CLASSIFY_WRITES_P": ("classify writes into its parameter argument p", "p[2] = min(p[2], 1.0)", "classify may not"),
    "FORCING_WRITES_P": ("forcing_period writes into its parameter argument p", "np.negative(p, p)", "may not write"),
    "CLOSED_FORM_WRITES_P": ("closed form 't_fall' writes into its parameter argument p", "p[1] = 0.0",
                             "a closed form may not"),
    "FLOQUET_INITIAL_WRITES_P": ("initial of Floquet 'mu' writes into its parameter argument p", "p[0] = 1.0",
                                 "only its 2nd argument (y0)"),
    "SYSTEM_RHS_WRITES_STATE": ("the System's rhs of FirstEvent 'apex' writes into its state argument y",
                                "y[1] = min(y[1], 10.0)", "(dydt)"),
    "JAC_WRITES_STATE": ("jac writes into its state argument y", "y += 0.0", "only its 4th argument (J)"),
    "VARIATIONAL_WRITES_PHI": ("variational of Floquet 'mu' writes into its variational state argument Phi",
                               "Phi[0] = 1.0", "(dPhi)"),
    "COMPUTE_WRITES_DATA": ("compute writes into its shared data argument u", "u[0] = p[0]",
                            "only row, curves and scratch"),
    "STEADY_OF_WRITES_STATE": ("expression of Steady 'peak' writes into its state argument y", "y[0] = abs(y[0])",
                               "may not write"),
    "HISTORY_OF_WRITES_STATE": ("expression of History 'y_t' writes into its state argument y", "y[0] = abs(y[0])",
                                "may not write"),
    "KICK_RESPONSE_WRITES_P": ("response of Kick 'settles' writes into its parameter argument p", "p[1] = 0.5 * p[1]",
                               "may not write"),
    "WINDOW_WRITES_P": ("window start t0 of Extremum 'y_max' writes into its parameter argument p", "p[2] += 0.0",
                        "may not write into p"),
    "SWITCH_TIMES_WRITES_P": ("switch_times writes into its parameter argument p", "p[0] = 9.81", "may not write"),
    "SYMPLECTIC_STEP_WRITES_P": ("symplectic_step writes into its parameter argument p", "p[1] = 1.0",
                                 "may not write"),
    "SYSTEM_PREPARE_WRITES_PARAMETER": (
        "the System's prepare of FirstEvent 'apex' writes into its parameter argument p", "p[2] = 1.0",
        "internal slots of p (p[3:4]"),
    "MEASUREMENT_CLASSIFY_WRITES_P": ("classify of FirstEvent 'apex' writes into its parameter argument p",
                                      "p[1] = max(p[1], 0.1)", "classify may not"),
    "CLOSED_CLASSIFY_WRITES_P": ("classify of closed form 'one' writes into its parameter argument p", "p[:] = 1.0",
                                 "classify may not"),
    "VARIATIONAL_JAC_WRITES_PHI": ("variational_jac of Floquet 'mu' writes into its variational state argument Phi",
                                   "Phi.sort()", "only its 4th argument (JJ)"),
    "INVARIANT_WRITES_STATE": ("invariant 'energy' writes into its state argument y", "y[1] = 0.0",
                               "may not write into its arguments"),
}
# seen only by the call at the probe point: a helper with no readable source, a write through a view
# of p whose index is known only when it runs
DYNAMIC = {
    "EVENT_HIDDEN_HELPER": ("event of FirstEvent 'apex' wrote into its state argument y (component(s) 1) when run at "
                            "the probe point (def hidden_helper_event", "an event may not"),
    "PREPARE_WRITES_THROUGH_VIEW": ("prepare wrote into its parameter argument p (component(s) 1) when run at the "
                                    "probe point (def prepare_writes_through_view", "internal slots of p (p[3:4]"),
}


@pytest.fixture
def user_models_importable(monkeypatch):
    monkeypatch.syspath_prepend(str(USER))  # hostile_writes imports hostile_helpers by name


def _refused(name: str) -> str:
    with pytest.raises(InputError) as info:
        user.resolve(f"{HOSTILE}:{name}")
    return str(info.value)


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_function_writing_what_its_role_may_not_is_refused_with_file_and_line(name, user_models_importable):
    what, text, rule = CASES[name]
    msg = _refused(name)
    line = _line(text)
    assert what in msg and rule in msg, msg
    assert f"{HOSTILE}:{line} ({text})" in msg, msg


@pytest.mark.parametrize("name", sorted(DYNAMIC))
def test_a_write_the_source_does_not_show_is_found_at_the_probe_point(name, user_models_importable):
    what, rule = DYNAMIC[name]
    msg = _refused(name)
    assert what in msg and rule in msg and str(HOSTILE) in msg, msg


def test_a_model_given_from_python_is_checked_too(user_models_importable):
    """run(scene, models={...}): the object passes the same checks as a model file."""
    mod = load.import_module(load.module_name(HOSTILE), str(HOSTILE))
    with pytest.raises(InputError, match=r"models\['ball'\].*event of FirstEvent 'apex' writes into its state "):
        user.from_object("ball", mod.EVENT_WRITES_STATE)


def test_the_bouncing_ball_is_refused_through_the_cli_with_exit_2(in_tmp, capsys, monkeypatch):
    """The reproduction: `check` and `run` used to exit 0 with status ok and wrong apex times."""
    from mechsweep.cli import main

    monkeypatch.syspath_prepend(str(USER))
    (in_tmp / "ball.toml").write_text(f'[scene]\nname = "ball"\nmodel = "{HOSTILE}:EVENT_WRITES_STATE"\n'
                                      'outputs = ["apex"]\n[axes]\ne = [0.5, 0.8]\n')
    for argv in (["check", "ball.toml"], ["run", "ball.toml", "--no-progress"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "event of FirstEvent 'apex' writes into its state argument y" in err and "Traceback" not in err, err
    assert list((in_tmp / "data" / "runs").iterdir()) == []


# ----------------------------------------------------------------------------- the static net, form by form
def _direct(t, y, p): y[1] = -p[2] * y[1]; return 0.0  # noqa: E702
def _slice(t, y, p): y[:] = 0.0; return 0.0  # noqa: E702


def _augmented(t, y, p):
    y[1] += 1.0
    return 0.0


def _fill(t, y, p):
    y.fill(0.0)
    return 0.0


def _copyto(t, y, p):
    np.copyto(y, p[:2])
    return 0.0


def _copyto_by_keyword(t, y, p):
    np.copyto(dst=y, src=p[:2])
    return 0.0


def _alias(t, y, p):
    z = y
    z[0] = 1.0
    return 0.0


def _view_in_place(t, y, p):
    z = y[1:]
    z += 1.0
    return 0.0


def _transpose(t, y, p):
    y.T[0] = 1.0
    return 0.0


def _ufunc_positional_out(t, y, p):
    np.negative(y, y)
    return 0.0


def _ufunc_out_keyword(t, y, p):
    np.add(y, 1.0, out=y)
    return 0.0


def _ufunc_at(t, y, p):
    np.add.at(y, 0, 1.0)
    return 0.0


def _nested(t, y, p):
    def inner(v):
        v[0] = 2.0
    inner(y)
    return 0.0


def _walrus(t, y, p):
    if (z := y) is not None:
        z[0] = 1.0
    return 0.0


def _unpacked(t, y, p):
    a, b = y, p
    b[1] = 0.0
    return 0.0


def _alias_in_a_loop(t, y, p):
    z = np.zeros(2)
    for i in range(2):
        z[i] = 1.0
        z = y
    return 0.0


def _alias_on_one_branch(t, y, p):
    z = y if t > 0.0 else np.zeros(2)
    z[0] = 1.0
    return 0.0


def _setitem(t, y, p):
    y.__setitem__(0, 1.0)
    return 0.0


@numba.njit
def _writes_first(v):
    v[0] = 0.0


def _through_helper(t, y, p):
    _writes_first(p)
    return 0.0


@numba.njit
def _jitted(t, y, p):
    y[0] = 0.0
    return 0.0


WRITES = {  # function -> the argument it writes (1: y, 2: p)
    _direct: 1, _slice: 1, _augmented: 1, _fill: 1, _copyto: 1, _copyto_by_keyword: 1, _alias: 1, _view_in_place: 1,
    _transpose: 1,
    _ufunc_positional_out: 1, _ufunc_out_keyword: 1, _ufunc_at: 1, _nested: 1, _walrus: 1, _unpacked: 2,
    _alias_in_a_loop: 1, _alias_on_one_branch: 1, _setitem: 1, _through_helper: 2, _jitted: 1,
}


@pytest.mark.parametrize("func", list(WRITES), ids=[f.__name__.strip("_") for f in WRITES])
def test_each_way_of_writing_an_argument_is_found(func):
    found = writes.param_writes(func, (0, 1, 1, 0))
    assert set(found) == {WRITES[func]}, found
    f = found[WRITES[func]]
    assert f.file == __file__ and f.line > 0 and f.text, f


def _local_array(t, y, p):
    tmp = np.empty(2)
    tmp[:] = y
    tmp[0] += p[0]
    return tmp[0]


def _rebound(t, y, p):
    y = y.copy()
    y[0] = 1.0
    return y[0]


def _element_updated(t, y, p):
    v = y[1]
    v += 1.0
    v *= 2.0
    return v


def _fancy_copy(t, y, p):
    z = y[[0, 1]]
    z[0] = 1.0
    return z[0]


def _reads(v):
    return v[0] + v[1]


def _helper_reads(t, y, p):
    return _reads(y) + _reads(p)


def _copy_method(t, y, p):
    z = y.copy()
    z.fill(0.0)
    return z[0]


def _first(out):  # a helper whose parameter is called out, and only read
    return out[0]


def _helper_reads_out(t, y, p):
    return _first(out=y)


@pytest.mark.parametrize("func", [_local_array, _rebound, _element_updated, _fancy_copy, _helper_reads, _copy_method,
                                  _helper_reads_out],
                         ids=lambda f: f.__name__.strip("_"))
def test_writing_a_local_array_or_a_copy_is_not_a_finding(func):
    assert writes.param_writes(func, (0, 1, 1, 0)) == {}


# ----------------------------------------------------------------------------- no false positives
def test_writes_that_the_roles_allow_pass_the_load_time_checks(monkeypatch):
    """tests/user_models/writes_allowed.py writes its outputs through aliases, slices and helpers,
    prepare its internal slots by index, by a view and by a helper, compute its row, curves and
    scratch: user.check and closed.check accept both models (numba's compile is left out: it
    follows the write check)."""
    monkeypatch.setattr(load, "jitted", lambda *ref: (lambda *args: None))
    path = USER / "writes_allowed.py"
    mod = load.import_module(load.module_name(path), str(path))
    user.check(mod.ALLOWED, "ALLOWED", str(path))
    closed.check(mod.ALLOWED_CLOSED, "ALLOWED_CLOSED", str(path))


def _shipped_models():
    """Every OdeModel and ClosedFormModel of mechsweep.models, sweeps/models and tests/user_models
    (but the hostile ones and those that exit), with the module it is in."""
    mods = [importlib.import_module(f"mechsweep.models.{m.name}")
            for m in pkgutil.iter_modules(mechsweep.models.__path__)]
    repo = HERE.parent
    files = sorted(glob.glob(str(repo / "sweeps" / "models" / "*.py")))
    files.append(str(repo / "tests" / "data" / "nonsmooth" / "meissner.py"))
    files += [f for f in sorted(glob.glob(str(USER / "*.py")))
              if re.search(r"(OdeModel|ClosedFormModel)\(", Path(f).read_text())
              and not Path(f).name.startswith(("hostile", "exit_")) and "__main__" not in Path(f).read_text()]
    mods += [load.import_module(load.module_name(Path(f)), f) for f in files]
    seen = {}
    for mod in mods:
        for name, obj in vars(mod).items():
            if isinstance(obj, (OdeModel, ClosedFormModel)) and id(obj) not in seen:
                seen[id(obj)] = (f"{mod.__name__}:{name}", obj)
    return list(seen.values())


def test_every_shipped_model_passes_the_write_check():
    """No false positive on the models the project ships and tests (the built-in Duffing, torsional
    and auto-balancer models write their internal slots from prepare through views and a helper).
    The one exception is measure_more.py's COUNTED, an instrument whose rhs counts its own calls in
    an internal slot: refused, as any rhs that writes into p."""
    checked = 0
    for label, model in _shipped_models():
        if isinstance(model, OdeModel):
            calls = writes.ode_calls(model, user._probe_layout(model), np.ones(len(model.states)))
        else:
            data = () if model.data is None else model.data(model.size)
            calls = writes.closed_calls(model, closed._probe_arrays(model, load.probe_params(model), np.nan),
                                        tuple(np.ascontiguousarray(a) for a in data))
        if label.endswith(":COUNTED"):
            with pytest.raises(InputError, match=r"rhs writes into its parameter argument p at .*measure_more.py"):
                writes.check(calls, label)
            continue
        # the built-in models never pass through user.check: their source is what is checked here (a
        # call from Python would compile their numba helpers for nothing)
        writes.check(calls, label, dynamic=not label.startswith("mechsweep.models."))
        checked += 1
    assert checked >= 40
