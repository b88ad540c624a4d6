"""A user model is refused at load, naming the problem, when a dataset could not carry its
declaration: a unit UDUNITS-2 does not read (the dataset claims CF), or a name that is no Python
identifier or is a keyword (a dataset's dimensions are selected by keyword, ``ds.sel(lam=0.3)``).
Every built-in model's declaration passes the same check. A declaration no scene could use as
meant (an empty range, a default outside it, repeated names) is refused when declared, and a
misspelt model file is named with the closest file beside it."""
from __future__ import annotations

import numpy as np
import pytest

from mechsweep.cli import main
from mechsweep.errors import InputError
from mechsweep.model import Crossing, Extremum, Period, user
from mechsweep.models import MODELS

from tests.conftest import SWEEPS

MODEL = '''
from mechsweep.model import OdeModel, Param, Period


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


M = OdeModel(name="spring", description="x'' + k x = 0",
             params=(Param({name!r}, "k", {unit!r}, "stiffness over mass", lo=0.0, lo_open=True),),
             states=("x", "v"), rhs=rhs, initial=initial,
             measurements=(Period("period", "x", t_max=100.0, unit={out_unit!r}),))
'''


def _scene(tmp_path, name="k", unit="s-2", out_unit="s"):
    (tmp_path / "spring.py").write_text(MODEL.format(name=name, unit=unit, out_unit=out_unit))
    scene = tmp_path / "s.toml"
    scene.write_text(f'[scene]\nname = "s"\nmodel = "spring.py:M"\noutputs = ["period"]\n\n[fixed]\n{name} = 4.0\n'
                     if name.isidentifier() else
                     f'[scene]\nname = "s"\nmodel = "spring.py:M"\noutputs = ["period"]\n\n[fixed]\n"{name}" = 4.0\n')
    return scene


@pytest.mark.parametrize("name, unit, out_unit, words", [
    ("k", "metres please", "s", ["parameter 'k'", "'metres please'", "UDUNITS-2", "'kg m2'", "'rad s-1'"]),
    ("k", "s-2", "seconds?", ["output 'period'", "'seconds?'", "UDUNITS-2", "'m'"]),
    ("lambda", "s-2", "s", ["parameter 'lambda'", "identifier that is not a keyword", "'lambda_'"]),
    ("k-1", "s-2", "s", ["parameter 'k-1'", "identifier", "'k_1'"]),
])
def test_a_model_the_dataset_cannot_carry_is_refused_at_load(tmp_path, capsys, name, unit, out_unit, words):
    scene = _scene(tmp_path, name, unit, out_unit)
    assert main(["check", str(scene)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and "'spring.py:M'" in err and "model 'spring'" in err, err
    for w in words:
        assert w in err, (w, err)


@pytest.mark.parametrize("unit", ["s-2", "rad/s2", "1/s^2", "N m kg-1 m-2"])
def test_units_udunits_reads_load(tmp_path, capsys, unit):
    assert main(["check", str(_scene(tmp_path, unit=unit))]) == 0, capsys.readouterr().err


def test_a_model_given_from_python_is_checked_too(tmp_path, monkeypatch):
    (tmp_path / "spring_api.py").write_text(MODEL.format(name="k", unit="metres please", out_unit="s"))
    monkeypatch.syspath_prepend(str(tmp_path))
    import spring_api

    with pytest.raises(InputError, match="parameter 'k': unit 'metres please' is not a unit UDUNITS-2 reads"):
        user.from_object("spring_api_model", spring_api.M)


@pytest.mark.parametrize("spec", [*MODELS.values(), user.resolve(str(SWEEPS / "models" / "vibrating_pendulum.py")
                                                                 + ":VIBRATING_PENDULUM")], ids=lambda s: s.name)
def test_every_built_in_and_shipped_declaration_passes(spec):
    user.check_declaration(spec, spec.name)


# ------------------------------------------------------------ declarations no scene could use as meant
def _ode(params=None, states=("x", "v"), measurement=None):
    """x'' + k x = 0 (the spring of tests/user_models/unstorable.py) with a declaration's pieces replaced."""
    from mechsweep.model import OdeModel, Param, Period

    from tests.user_models.unstorable import initial, rhs

    return OdeModel(name="spring", description="x'' + k x = 0",
                    params=params or (Param("k", "k", "s-2", "stiffness over mass", lo=0.0, lo_open=True),),
                    states=states, rhs=rhs, initial=initial,
                    measurements=(measurement or Period("period", "x", t_max=100.0),))


@pytest.mark.parametrize("kw, words", [
    (dict(lo=0.0, hi=10.0, required=False, default=20.0),
     "parameter 'zeta': default = 20.0 is outside the physical range; expected a finite number in [0, 10]"),
    (dict(lo=0.0, lo_open=True, required=False, default=0.0), "default = 0.0 is outside the physical range"),
    (dict(lo=10.0, hi=0.0), "parameter 'zeta': lo = 10.0, hi = 0.0 (lo_open = False, hi_open = False) admit no value"),
    (dict(lo=1.0, hi=1.0, hi_open=True), "admit no value"),
    (dict(choices=("a", "b"), required=False, default=2.0), "default = 2.0 is not the index of one of its choices"),
    (dict(lo=0.0, required=False), "parameter 'zeta': required=False needs a default"),
])
def test_a_range_no_value_satisfies_or_a_default_outside_it_is_refused_when_declared(kw, words):
    from mechsweep.model import Param

    with pytest.raises(ValueError) as refused:
        Param("zeta", "zeta", "1", "damping ratio", **kw)
    assert words in str(refused.value), refused.value


def test_a_nan_default_still_means_not_given_and_a_one_point_range_is_allowed():
    from mechsweep.model import Param

    assert Param("l", "l", "m", "rod", lo=0.0, lo_open=True, required=False, default=float("nan")).required is False
    assert Param("c", "c", "1", "fixed", lo=1.0, hi=1.0, required=False, default=1.0).problem(1.0) is None


def test_repeated_parameter_or_state_names_are_refused_when_declared():
    from mechsweep.model import ClosedFormModel, Output, Param

    k = Param("k", "k", "s-2", "stiffness over mass", lo=0.0, lo_open=True)
    with pytest.raises(ValueError, match=r"model 'spring': parameter names repeat: \['k', 'k'\]"):
        _ode(params=(k, k))
    with pytest.raises(ValueError, match=r"model 'spring': state names repeat: \['x', 'x'\]"):
        _ode(states=("x", "x"))
    with pytest.raises(ValueError, match=r"model 'm': parameter names repeat: \['k', 'k'\]"):
        ClosedFormModel(name="m", description="d", params=(k, k), outputs=(Output("a", "a", "1", "a"),),
                        compute=len, size=3)
    assert _ode().params == (k,)  # the same declaration with one of each loads


def test_a_misspelt_model_file_is_named_with_the_closest_python_file_beside_it(tmp_path, capsys):
    (tmp_path / "base_osc.py").write_text("")
    (tmp_path / "s.toml").write_text('[scene]\nname = "s"\nmodel = "base_os.py:M"\noutputs = ["period"]\n')
    assert main(["check", str(tmp_path / "s.toml")]) == 2
    err = capsys.readouterr()
    assert f"model file {tmp_path / 'base_os.py'} does not exist (did you mean base_osc.py?)" in err.out + err.err
    (tmp_path / "s.toml").write_text('[scene]\nname = "s"\nmodel = "zzz.py:M"\noutputs = ["period"]\n')
    assert main(["check", str(tmp_path / "s.toml")]) == 2
    err = capsys.readouterr()
    assert "zzz.py does not exist" in err.out + err.err and "did you mean" not in err.out + err.err


@pytest.mark.parametrize("t_max", [lambda p: 10.0, "10", float("inf"), 0.0, True])
def test_a_crossing_or_period_t_max_that_is_no_positive_number_is_named(t_max):
    for m in (Crossing("t_cross", "x", t_max=t_max), Period("T", "x", t_max=t_max)):
        with pytest.raises(ValueError, match=f"{m.name}: t_max = .*; expected a finite number > 0 .*FirstEvent's t_max"):
            _ode(measurement=m)
    _ode(measurement=Crossing("t_cross", "x", t_max=np.float64(10.0)))  # a numpy number is a number


@pytest.mark.parametrize("make, words", [
    (lambda: Crossing("c", "x", level="0"),
     "c: level = '0'; expected a finite number"),
    (lambda: Period("c", "x", level=len),
     "c: level = <built-in function len>; expected a finite number"),
    (lambda: Extremum("c", "x", "0", 1.0),
     "c: t0 = '0'; expected a finite number or a function t0(p)"),
])
def test_a_level_or_window_that_is_no_number_is_named_not_a_format_error(make, words):
    with pytest.raises(ValueError) as refused:
        _ode(measurement=make())
    assert words in str(refused.value), refused.value
