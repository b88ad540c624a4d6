"""Located boundaries (mechsweep.boundaries): against closed forms and published characteristic values,
for built-in models and a user model, through the API and the `mechsweep boundaries` command."""
from __future__ import annotations

import hashlib
import math
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from scipy.optimize import brentq

from mechsweep import boundaries as bd
from mechsweep.boundaries import search as bd_search
from mechsweep.cli import main
from mechsweep.scene import load_scene
from tests import evaluating

HERE = Path(__file__).resolve().parents[1]
MATHIEU_FILE = HERE / "user_models" / "mathieu.py"


def _locate(scene_dict):
    """Locate a scene's boundaries on its grid evaluated here (no file written)."""
    scene = load_scene(scene_dict)
    rows, col, others = bd.base_rows(scene, scene.boundaries.along)
    axis = next(a for a in scene.axes if a.name == scene.boundaries.along)
    res = bd.locate(scene, bd.criterion_of(scene), rows, col, axis.array(), rtol=scene.boundaries.rtol)
    return scene, rows, res


def test_duffing_soft_separatrix_located_to_1e_10():
    """Status ok -> not_oscillatory along A at fixed omega, mu < 0: A* = omega / sqrt(-mu) (the soft
    separatrix omega^2 + mu A^2 = 0); a hard spring (mu > 0) has no boundary."""
    omega, mus = 2.0, [-0.5, -1.3, -3.0, 1.0]
    scene, rows, res = _locate({
        "scene": {"name": "sep", "model": "duffing", "outputs": ["period_exact"]},
        "axes": {"A": {"start": 0.1, "stop": 3.0, "num": 30}, "mu": mus}, "fixed": {"omega": omega},
        "boundaries": {"along": "A", "status_change": ["ok", "not_oscillatory"]}})
    exact = omega / np.sqrt(-np.array(mus[:3]))
    assert res.location.shape == (4, 1)
    np.testing.assert_allclose(res.location[:3, 0], exact, rtol=1e-10, atol=0)
    assert (res.bound[:3, 0] == bd.PARAMETER).all() and (res.direction[:3, 0] == 1).all()
    assert (res.width[:3, 0] <= 1e-10 * exact * (1 + 1e-9)).all() and (res.width[:3, 0] > 0).all()
    assert (res.evaluations[:3, 0] <= 30).all(), res.evaluations  # bisection from a grid cell of 0.1
    assert np.isnan(res.location[3, 0]) and res.bound[3, 0] == -1


def test_torsional_free_length_limit_located_to_1e_10():
    """Status ok -> infeasible along s0_over_r: the free length L0 = R (sqrt(D0) - sigma s) reaches 0 at
    s = sigma sqrt(D0), D0 = (1 - sigma lambda1)^2 + lambda2^2 (physics.md, Domain)."""
    lam1, lam2 = [0.3, 1.0, 1.7], 0.4
    scene, rows, res = _locate({
        "scene": {"name": "free", "model": "torsional_circuit", "outputs": ["chi"]},
        "axes": {"s0_over_r": {"start": -3.0, "stop": 3.0, "num": 25}, "lambda1": lam1,
                 "spring": ["tension", "compression"]},
        "fixed": {"lambda2": lam2},
        "boundaries": {"along": "s0_over_r", "status_change": ["ok", "infeasible"]}})
    sigma = np.array([1.0, -1.0])[None, :]
    exact = sigma * np.sqrt((1 - sigma * np.array(lam1)[:, None]) ** 2 + lam2 ** 2)
    loc = res.location[:, 0].reshape(3, 2)
    np.testing.assert_allclose(loc, exact, rtol=1e-10, atol=0)
    # tension: feasible below the limit (ok -> infeasible as s grows); compression: the reverse
    np.testing.assert_array_equal(res.direction[:, 0].reshape(3, 2), np.tile([1, -1], (3, 1)))


def _mathieu_scene(tmp, c, extra=None):
    text = f"""
[scene]
name = "mathieu"
model = "{MATHIEU_FILE}:MATHIEU_JAC"
outputs = ["max_multiplier"]
[axes]
a = {{ start = -1.0, stop = 5.0, num = 31 }}
q = [0.5, 1.5]
[fixed]
c = {c!r}
[solver]
rtol = 1e-12
atol = 1e-14
[storage]
path = "{tmp / 'mathieu.h5'}"
[boundaries]
along = "a"
criterion = "max_multiplier"
{extra or ''}
"""
    path = tmp / "mathieu.toml"
    path.write_text(text)
    return path


def test_mathieu_boundaries_match_characteristic_values(tmp_path, capsys):
    """Undamped Mathieu x'' + (a - 2 q cos 2t) x = 0 as a user model: the largest Floquet multiplier
    is 1 on the stable side and leaves it on the unstable side, so each boundary is a band edge;
    located through `mechsweep boundaries` (the grid run first), they are a_0, b_1, a_1, b_2, a_2 of
    scipy.special to 1e-8, the critical multiplier +1 for a_n, b_n with n even, -1 for n odd."""
    from scipy.special import mathieu_a, mathieu_b

    scene = _mathieu_scene(tmp_path, 0.0)
    assert main(["boundaries", str(scene), "--no-progress", "--threads", "1"]) == 0
    assert "boundaries located along a" in capsys.readouterr().out
    data, sib = tmp_path / "mathieu.h5", tmp_path / "mathieu.boundaries.h5"
    before = hashlib.sha256(data.read_bytes()).hexdigest()
    with xr.open_dataset(sib) as ds:
        assert ds["boundary"].dims == ("q", "crossing") and ds["boundary"].attrs["units"] == "1"
        assert "max_multiplier = 1" in ds["boundary"].attrs["long_name"]
        assert ds.attrs["mechsweep_kind"] == "boundaries" and ds.attrs["along"] == "a"
        assert ds.attrs["along_span"] == 6.0  # a = -1 .. 5: the scale of `info`'s absolute bracket widths
        for i, q in enumerate(ds["q"].values):
            ref = [mathieu_a(0, q), mathieu_b(1, q), mathieu_a(1, q), mathieu_b(2, q), mathieu_a(2, q)]
            order = np.argsort(ref)
            np.testing.assert_allclose(ds["boundary"].values[i], np.array(ref)[order], rtol=1e-8, atol=1e-8)
            np.testing.assert_array_equal(ds["boundary_kind"].values[i], np.array([1, -1, -1, 1, 1])[order])
            np.testing.assert_array_equal(ds["boundary_angle"].values[i], np.pi * np.array([0, 1, 1, 0, 0])[order])
            assert (ds["boundary_bound"].values[i] == bd.BAND_EDGE).all()
            # a_n: unstable below (the criterion falls to its level as a grows), b_n: unstable above
            np.testing.assert_array_equal(ds["boundary_direction"].values[i], np.array([-1, 1, -1, 1, -1])[order])
        evaluations = ds["boundary_evaluations"].values
    # from a grid cell of 0.2 down to 1e-10 |a|: 11-20 measured (bisection took 29-32)
    assert evaluations.max() <= 24, evaluations
    # a re-run replaces the boundaries, never the grid's dataset (finished: not computed again)
    sib.write_bytes(b"\x89HDF\r\n\x1a\nstale")
    assert main(["boundaries", str(scene), "--no-progress", "--threads", "1"]) == 0
    assert hashlib.sha256(data.read_bytes()).hexdigest() == before
    with xr.open_dataset(sib) as ds:
        assert ds["boundary"].shape == (2, 5)


def test_boundaries_says_why_band_edges_give_no_continued_curve(tmp_path, capsys, monkeypatch):
    """Undamped, every boundary is a band edge (the multiplier stays 1 on one side): continuation
    has no crossing to follow, and the command says so instead of '0 curve(s)' alone (a docs-only
    trial's undamped rotor). The located dataset is stood in for: only the report is tested."""
    scene = _mathieu_scene(tmp_path, 0.0, extra='continue_in = "q"')
    stored = xr.Dataset({"boundary_bound": (("q", "crossing"), np.full((2, 5), bd.BAND_EDGE)),
                         "curve_stop": ("curve", np.zeros(0, int)), "fold_axis": ("fold", np.zeros(0, int))},
                        attrs={"located": 10, "along": "a", "evaluations_per_point_mean": 12.0,
                               "evaluations_per_point_max": 20, "evaluate_calls": 30, "wall_time_s": 0.1,
                               "continue_in": "q", "continuation_evaluated_points": 0, "continuation_calls": 0,
                               "continuation_wall_time_s": 0.0})
    monkeypatch.setattr(bd, "run_boundaries", lambda *a, **k: (tmp_path / "x.boundaries.h5", stored))
    assert main(["boundaries", str(scene), "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "continued in q: 0 curve(s)" in out and "10 band edge(s) not continued" in out, out


def test_damped_mathieu_boundaries_by_illinois_bracket_the_crossing():
    """Damped (c = 0.1): the multiplier crosses 1 transversally, so Illinois refines a sign change;
    with the criterion's accuracy given as 1e-12 the bracket reaches 1e-10 |a| in about a dozen
    evaluations, and the criterion has opposite signs on either side of it."""
    scene, rows, res = _locate({
        "scene": {"name": "md", "model": f"{MATHIEU_FILE}:MATHIEU_JAC", "outputs": ["max_multiplier"]},
        "axes": {"a": {"start": -1.0, "stop": 5.0, "num": 31}, "q": [1.5]}, "fixed": {"c": 0.1},
        "solver": {"rtol": 1e-12, "atol": 1e-14},
        "boundaries": {"along": "a", "criterion": "max_multiplier", "criterion_accuracy": 1e-12}})
    loc, width = res.location[0], res.width[0]
    assert loc.size == 5 and (res.bound[0] == bd.PARAMETER).all()
    assert (width <= 1.01e-10 * np.abs(loc)).all() and (width > 0).all()
    assert res.evaluations.max() <= 20, res.evaluations
    P = np.repeat(rows[:1], 2 * loc.size, axis=0)
    P[:, 0] = np.concatenate([loc - width, loc + width])
    out, status, _, _ = evaluating.evaluate(scene.model, P, ("max_multiplier",), scene.solver)
    g = out["max_multiplier"] - 1.0
    below, above = g[:loc.size], g[loc.size:]
    assert (np.sign(below) == -np.sign(above)).all() and (np.sign(above) == res.direction[0]).all()


def test_bound_says_which_accuracy_limited_the_bracket():
    """With the criterion's default accuracy (the Floquet margin 1e-8, far above the integration error
    at rtol 1e-12) the band |g| <= 1e-8 is wider than 1e-10 |a|: those brackets are marked
    "criterion"; a point marked "parameter" has its bracket within rtol of the larger end."""
    scene, rows, res = _locate({
        "scene": {"name": "md", "model": f"{MATHIEU_FILE}:MATHIEU_JAC", "outputs": ["max_multiplier"]},
        "axes": {"a": {"start": -1.0, "stop": 5.0, "num": 31}, "q": [0.5, 1.5]}, "fixed": {"c": 0.1},
        "solver": {"rtol": 1e-12, "atol": 1e-14},
        "boundaries": {"along": "a", "criterion": "max_multiplier"}})
    found = res.bound >= 0
    loc, width, bound = res.location[found], res.width[found], res.bound[found]
    assert found.sum() == 8 and set(bound.tolist()) <= {bd.PARAMETER, bd.CRITERION}
    within = width <= 1e-10 * (np.abs(loc) + width)
    np.testing.assert_array_equal(bound == bd.PARAMETER, within)
    assert (bound == bd.CRITERION).sum() >= 4
    assert (width < 1e-7 * np.abs(loc)).all()  # the band: 2 eps / slope, slope O(1)


BASE = {"scene": {"name": "b", "model": "duffing", "outputs": ["period_exact"]},
        "axes": {"A": {"start": 0.1, "stop": 3.0, "num": 5}, "mu": [-1.0, -2.0]}, "fixed": {"omega": 2.0}}


@pytest.mark.parametrize("section, key, words", [
    ({"along": "A", "status_change": ["ok", "not_oscillatory"], "levle": 1}, "boundaries.levle", "did you mean 'level'"),
    ({"along": "omega", "status_change": ["ok", "not_oscillatory"]}, "boundaries.along",
     "'omega' is a fixed parameter in this scene, not an axis; expected an axis of at least 2 numeric values (A, mu)"),
    ({"along": "omgea", "status_change": ["ok", "not_oscillatory"]}, "boundaries.along", "allowed: A"),
    ({"status_change": ["ok", "not_oscillatory"]}, "boundaries.along", "missing"),
    ({"along": "A", "criterion": "period", "level": 1.0}, "boundaries.criterion", "allowed: period_exact"),
    ({"along": "A", "criterion": "period_exact"}, "boundaries.level", "missing"),
    ({"along": "A", "criterion": "period_exact", "level": "one"}, "boundaries.level", "finite number"),
    ({"along": "A", "criterion": "period_exact", "level": 3.0, "status_change": ["ok", "no_motion"]},
     "boundaries", "exactly one of criterion"),
    ({"along": "A", "status_change": ["ok", "not_oscilatory"]}, "boundaries.status_change", "not_oscillatory"),
    ({"along": "A", "status_change": ["ok"]}, "boundaries.status_change", "two status names"),
    ({"along": "A", "status_change": ["ok", "not_oscillatory"], "rtol": 0.5}, "boundaries.rtol", "[1e-15, 0.01]"),
    ({"along": "A", "criterion": "period_exact", "level": 3.0, "criterion_accuracy": -1},
     "boundaries.criterion_accuracy", ">= 0"),
    ({"along": "A", "status_change": ["ok", "not_oscillatory"], "continue_in": "mu"}, "boundaries.continue_in",
     "a change of status cannot be continued"),
    ({"along": "A", "criterion": "period_exact", "level": 3.0, "continue_in": "A"}, "boundaries.continue_in",
     "allowed: mu"),
])
def test_bad_boundaries_section_exits_2_naming_the_key(in_tmp, capsys, section, key, words):
    scene = in_tmp / "bad.toml"
    from mechsweep.scene import to_toml
    scene.write_text(to_toml({**BASE, "boundaries": section}))
    assert main(["boundaries", str(scene), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert f"{key}:" in err and words in err, err
    assert sorted(p.name for p in in_tmp.iterdir()) == ["bad.toml", "data"]  # nothing written
    assert not any((in_tmp / "data" / "runs").iterdir())


def test_a_misspelt_criterion_is_named_without_a_level_it_may_not_need():
    """A Floquet criterion needs no level (1, the unit circle): misspelt, the scene was also told
    'boundaries.level: missing', which a Floquet criterion never needs (a docs-only trial wrote
    mu_maxx for its mu_max and looked for the level first). The criterion alone is named."""
    from mechsweep.errors import InputError
    with pytest.raises(InputError) as info:
        load_scene({"scene": {"name": "b", "model": "autobalancer", "outputs": ["floquet_max"]},
                    "axes": {"Omega": {"start": 10.0, "stop": 40.0, "num": 5}},
                    "boundaries": {"along": "Omega", "criterion": "floquet_mx"}})
    text = str(info.value)
    assert "boundaries.criterion: unknown criterion" in text and "did you mean 'floquet_max'?" in text, text
    assert "boundaries.level" not in text, text


@pytest.mark.parametrize("accuracy, warned", [(1e-10, True), (3e-8, True), (1e-5, False), (None, False)])
def test_a_criterion_accuracy_below_what_rtol_gives_is_warned_of(in_tmp, capsys, accuracy, warned):
    """rtol 1e-8 gives an integrated criterion at level 3 about 100 rtol |level| = 3e-6: a band given
    narrower than that is warned of by `check` (and by `boundaries`, before it runs), naming the
    key, the floor and the rtol that would do; the scene is still valid (exit 0)."""
    from mechsweep.scene import to_toml
    b = {"along": "A", "criterion": "period", "level": 3.0}
    if accuracy is not None:
        b["criterion_accuracy"] = accuracy
    scene = {**BASE, "scene": {**BASE["scene"], "outputs": ["period"]}, "solver": {"rtol": 1e-8}, "boundaries": b}
    (in_tmp / "s.toml").write_text(to_toml(scene))
    assert main(["check", "s.toml"]) == 0
    err = capsys.readouterr().err
    assert ("boundaries.criterion_accuracy = " in err) == warned, err
    if warned:
        assert f"criterion_accuracy = {accuracy:g} is below" in err and "about 100 rtol |level| = 3e-06" in err
        assert f"solver.rtol to {accuracy / 300:g}" in err
    assert (bd.accuracy_warning(load_scene(in_tmp / "s.toml")) is not None) == warned


@pytest.mark.parametrize("change, warned", [(["ok", "not_oscillatory"], False), (["ok", "undecided"], True)])
def test_a_status_change_the_model_never_gives_is_warned_of(in_tmp, capsys, change, warned):
    """duffing lists no 'undecided': a status_change naming it is valid but locates nothing (a
    docs-only trial got "0 boundaries located", exit 0, no word why): check warns, naming the
    status and the model's list."""
    from mechsweep.scene import to_toml
    scene = {**BASE, "boundaries": {"along": "A", "status_change": change}}
    (in_tmp / "s.toml").write_text(to_toml(scene))
    assert main(["check", "s.toml"]) == 0
    err = capsys.readouterr().err
    assert ("boundaries.status_change names 'undecided', which model 'duffing' does not list among its "
            "statuses (" in err) == warned, err
    assert (bd.status_warning(load_scene(in_tmp / "s.toml")) is not None) == warned


def test_an_axis_with_a_refused_value_is_not_also_called_unknown_by_boundaries():
    """One error for one mistake: A's start out of its range is reported; boundaries.along = "A" is
    not also refused as an unknown axis (a docs-only trial got both)."""
    from mechsweep.scene import SceneError
    bad = {**BASE, "axes": {**BASE["axes"], "A": {"start": -0.1, "stop": 3.0, "num": 5}},
           "boundaries": {"along": "A", "criterion": "period_exact", "level": 3.0}}
    with pytest.raises(SceneError) as err:
        load_scene(bad)
    assert "axes.A.start" in str(err.value) and "boundaries.along" not in str(err.value), err.value
    with pytest.raises(SceneError, match="boundaries.along"):  # an axis that is not there still is
        load_scene({**bad, "boundaries": {"along": "B", "criterion": "period_exact", "level": 3.0}})


def test_scene_without_boundaries_is_refused_and_a_failed_write_keeps_the_old_file(in_tmp, capsys, monkeypatch):
    from mechsweep.scene import to_toml
    (in_tmp / "none.toml").write_text(to_toml(BASE))
    assert main(["boundaries", "none.toml"]) == 2
    assert "has no [boundaries] section" in capsys.readouterr().err
    scene = {**BASE, "boundaries": {"along": "A", "status_change": ["ok", "not_oscillatory"]},
             "storage": {"path": "grid.h5"}}
    (in_tmp / "s.toml").write_text(to_toml(scene))
    assert main(["boundaries", "s.toml", "--no-progress", "--threads", "1"]) == 0
    old = (in_tmp / "grid.boundaries.h5").read_bytes()

    def broken(self, path, *args, **kwargs):
        Path(path).write_bytes(b"half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(xr.Dataset, "to_netcdf", broken)
    with pytest.raises(OSError):
        bd.run_boundaries(load_scene(in_tmp / "s.toml"), threads=1)
    assert (in_tmp / "grid.boundaries.h5").read_bytes() == old  # replaced whole or not at all
    assert sorted(p.name for p in in_tmp.iterdir()) == ["data", "grid.boundaries.h5", "grid.h5", "none.toml", "s.toml"]
    with xr.open_dataset(in_tmp / "grid.boundaries.h5") as ds:
        assert ds["boundary"].values[0, 0] == pytest.approx(2.0, rel=1e-10)


# ---------------------------------------------------------------- a built-in model: the auto-balancer
def _balancer(ratios, outputs=("floquet_max",), rtol=1e-10, num=35, **solver):
    from benchmarks.boundaries import scene_dict

    d = scene_dict(len(ratios), num, rtol)
    d["solver"].update(solver)
    d["axes"]["M"] = [1.0 / r for r in ratios]  # m = 0.5: 2 m / M = 1 / M
    d["scene"]["outputs"] = list(outputs)
    return _locate(d)


def test_autobalancer_located_boundaries_agree_with_brentq_and_converge_on_the_first_approximation():
    """Floquet boundaries of the balanced state along Omega (omega_xi = 1, omega_eta = 1.5, zeta = 0.02):
    located by Illinois, scipy's brentq on the same criterion (xtol 1e-13) finds its root inside their
    brackets;
    as 2 m / M goes from 0.02 to 0.0005 (40x lighter) their distance to the damped first
    approximation's roots P(Omega) = 0 shrinks 30 to 60x (linear convergence), as
    tests/models/test_autobalancer.py measures on its own grid."""
    from scipy.optimize import brentq

    from benchmarks.boundaries import scene_dict

    from tests.reference import autobalancer_kernels as ab  # the reference formula (numpy)

    scene, rows, res = _balancer([0.02, 0.0005])
    assert np.isin(res.bound, (bd.PARAMETER, bd.CRITERION)).all() and res.location.shape == (2, 3)
    # the criterion's accuracy 100 rtol = 1e-10 limits some: near omega_p at 2 m / M = 0.0005 the
    # multiplier leaves 1 slowly (2e-8 |Omega| measured with the hand-written kernels). Relaxed at the
    # swap to the layer (models/autobalancer.py): its floquet_max is the old one bitwise (its own
    # variational system), but the output now has kind "floquet_max", so the criterion's accuracy is
    # the Floquet verdict margin max(floquet_margin, 100 rtol) = 1e-8 instead of 100 rtol |value| =
    # 1e-10 (boundaries.criterion_accuracy) and the search treats it as a Floquet criterion (its
    # angle, the square-root approach): every bracket here is criterion-bound, wider with the wider
    # band: 1.5e-6 |Omega| at one, 3e-8 to 6e-8 elsewhere (measured; the hand-written model's SPEC on
    # the same scene: 1.5e-8 and 2.6e-10..6.8e-10); brentq's root is still inside each (below)
    assert (res.width <= 2e-6 * res.location).all()
    assert (res.width <= 1e-7 * res.location).sum() >= 5
    assert res.evaluations.max() <= 15, res.evaluations
    # the band is the default's choice, not the search's limit: given the multiplier's numerical
    # accuracy (100 rtol = 1e-10 at the solver's rtol 1e-12) the brackets are the hand-written
    # model's again (1.5e-8 and 2.6e-10..6.8e-10 |Omega|), each inside the default's bracket
    d = scene_dict(2, 35, 1e-10)
    d["axes"]["M"] = [1.0 / r for r in (0.02, 0.0005)]
    d["boundaries"]["criterion_accuracy"] = 1e-10
    _, _, tight = _locate(d)
    assert (tight.width <= 5e-8 * tight.location).all() and (tight.width < res.width).all()
    assert (np.abs(tight.location - res.location) <= res.width).all()

    def g(row, x):
        P = row[None, :].copy()
        P[0, 0] = x
        out, _, _, _ = evaluating.evaluate(scene.model, P, ("floquet_max",), scene.solver)
        return out["floquet_max"][0] - 1.0

    for i in range(2):
        for x, w in zip(res.location[i], res.width[i]):
            ref = brentq(lambda v: g(rows[i], v), x - 1e-3, x + 1e-3, xtol=1e-13, rtol=1e-14)
            assert abs(x - ref) <= max(w, 1e-10 * x), (x, ref, w)  # brentq's root is inside the bracket
    roots = np.array([brentq(lambda v: ab.receptance_sum(v, 1.0, 1.0, 2.25, 0.04, 0.06), lo, hi, xtol=1e-13)
                      for lo, hi in ((0.9, 1.1), (1.2, 1.35), (1.4, 1.55))])
    dist = (res.location - roots) / roots
    np.testing.assert_allclose(dist[0], [0.1244, 0.0036, 0.1866], atol=0.002)
    ratio = dist[0] / dist[1]
    assert ((ratio > 30) & (ratio < 60)).all(), ratio


@pytest.mark.slow  # 200-point lines over 1500 revolutions; in the default suite the located boundaries are
# checked against brentq above and Floquet against simulation on both sides of every boundary by
# tests/models/test_autobalancer.py (light pendulums)
def test_autobalancer_heavy_pendulum_boundaries_confirmed_by_direct_simulation():
    """Heavy pendulums (2 m / M = 0.05 and 0.2): on either side of every located boundary (2 % off)
    the direct simulation of the kicked balanced state (stable_sim, over 1500 revolutions: at 0.2 the
    default 300 leave both sides of the upper boundary undecided) settles on the side where the
    criterion falls below 1 and departs on the other."""
    # the window at 0.05 is 0.04 rad/s wide; near the boundaries the kick decays or grows slowly
    scene, rows, res = _balancer([0.05, 0.2], rtol=1e-8, num=200, horizon_revolutions=1500)
    found = np.isfinite(res.location)
    assert found.sum(axis=1).tolist() == [3, 1], res.location
    line, slot = np.nonzero(found)
    x, d = res.location[found], res.direction[found]
    P = np.repeat(rows[line], 2, axis=0)
    P[:, 0] = np.column_stack([x * 0.98, x * 1.02]).ravel()
    out, status, _, _ = evaluating.evaluate(scene.model, P, ("stable_sim",), scene.solver)
    sim = out["stable_sim"].reshape(-1, 2)
    # direction +1: floquet_max rises through 1 as Omega grows: stable below, unstable above
    expected = np.where(d[:, None] > 0, [[1.0, 0.0]], [[0.0, 1.0]])
    np.testing.assert_array_equal(sim, expected, err_msg=f"{status.reshape(-1, 2)} {x}")


# ---------------------------------------------------------------- continuation in two parameters
def test_continuation_follows_the_damped_mathieu_tongue_through_its_fold():
    """Damped Mathieu (c = 0.1) in the (a, q) chart: the first instability tongue's boundary, started
    at its left edge located along a at q = 0.6, is followed down through the tongue's tip (a fold in
    q: the two boundaries of a search along a meet there; for small c the tip is near a = 1, q = c)
    and back up to the chart's edge q = 0.6, where it ends on the tongue's right edge as located
    along a. Every point is on the boundary: re-evaluated, |max_multiplier - 1| <= 1e-9."""
    scene = load_scene({
        "scene": {"name": "tongue", "model": f"{MATHIEU_FILE}:MATHIEU_JAC", "outputs": ["max_multiplier"]},
        "axes": {"a": {"start": 0.3, "stop": 1.7, "num": 29}, "q": {"start": 0.0, "stop": 0.6, "num": 7}},
        "fixed": {"c": 0.1}, "solver": {"rtol": 1e-12, "atol": 1e-14},
        "boundaries": {"along": "a", "criterion": "max_multiplier", "criterion_accuracy": 1e-11}})
    crit = bd.criterion_of(scene)
    rows, col, _ = bd.base_rows(scene, "a")
    res = bd.locate(scene, crit, rows[-1:], col, np.linspace(0.3, 1.7, 29), rtol=1e-10)
    left, right = res.location[0]
    curve = bd.continue_boundary(scene, crit, rows[-1], "a", "q", (left, 0.6))
    pts = curve.points
    assert curve.stop == "edge" and pts[-1, 1] == pytest.approx(0.6, abs=1e-12)
    assert pts[-1, 0] == pytest.approx(right, rel=1e-9)
    assert len(curve.folds) == 1 and curve.folds[0][2:] == ("q", True)
    a_fold, q_fold = curve.folds[0][:2]
    assert abs(a_fold - 1.0) < 0.01 and 0.09 < q_fold < 0.11, curve.folds
    assert pts[:, 1].min() == pytest.approx(q_fold, abs=1e-3) and q_fold <= pts[:, 1].min()
    # the fold is located: the tongue's tip, the lowest q of the boundary. Located along q (a one-axis
    # search, not the continuation) at a = a_fold, the boundary is at q_fold; 1e-3 either side, higher
    # (the interpolated fold of before was 5e-4 above the tip: 0.1006 against 0.1000468)
    r = np.repeat(rows[-1:], 3, axis=0)
    r[:, 0] = a_fold + np.array([0.0, -1e-3, 1e-3])
    q_b = bd.locate(scene, crit, r, 1, np.linspace(0.0, 0.6, 13), rtol=1e-13).location
    q_b = np.where(np.isfinite(q_b), q_b, np.inf).min(axis=1)
    assert q_b[0] == pytest.approx(q_fold, abs=1e-12), (q_b, q_fold)
    assert (q_b[1:] > q_fold + 1e-8).all(), (q_b, q_fold)
    P = np.repeat(rows[-1:], len(pts), axis=0)
    P[:, 0], P[:, 1] = pts[:, 0], pts[:, 1]
    out, _, _, _ = evaluating.evaluate(scene.model, P, ("max_multiplier",), scene.solver)
    assert np.abs(out["max_multiplier"] - 1.0).max() <= 1e-9
    assert np.diff(pts, axis=0).max() < 0.05 * 1.4 and len(pts) < 300  # steps adapt, within step_max


def test_continuation_reproduces_a_closed_form_curve():
    """Duffing, epsilon = mu A^2 / omega^2 = 0.5 in the (A, mu) chart: mu = 0.5 omega^2 / A^2 at every
    point to 1e-10, from the chart's top edge to its right edge."""
    scene = load_scene({
        "scene": {"name": "eps", "model": "duffing", "outputs": ["epsilon"]},
        "axes": {"A": {"start": 0.2, "stop": 2.0, "num": 10}, "mu": {"start": 0.1, "stop": 20.0, "num": 10}},
        "fixed": {"omega": 2.0}, "boundaries": {"along": "A", "criterion": "epsilon", "level": 0.5}})
    crit = bd.criterion_of(scene)
    row = np.array([2.0, np.nan, np.nan])
    A0 = math.sqrt(0.5 * 4.0 / 20.0)  # where the curve meets mu = 20
    curve = bd.continue_boundary(scene, crit, row, "A", "mu", (A0, 20.0))
    A, mu = curve.points[:, 0], curve.points[:, 1]
    assert curve.stop == "edge" and A[-1] == pytest.approx(2.0, abs=1e-12) and len(curve.folds) == 0
    np.testing.assert_allclose(mu, 0.5 * 4.0 / A**2, rtol=1e-10)


@pytest.mark.parametrize("axes, section, words", [
    ({"A": [0.5], "mu": [-1.0]}, {"along": "w", "criterion": "period_exact", "level": 3.0},
     "unknown axis to locate boundaries along 'w' (allowed: (none in this scene: give an axis of at least 2 values "
     "of a numeric parameter: "),
    ({"A": {"start": 0.1, "stop": 3.0, "num": 5}, "mu": [-1.0]},
     {"along": "A", "criterion": "period_exact", "level": 3.0, "continue_in": "nu"},
     "(allowed: (none in this scene: give a second axis of at least 2 values of a numeric parameter: ")])
def test_boundaries_axis_with_no_candidate_names_the_parameters_it_can_be(axes, section, words):
    from mechsweep.errors import InputError
    with pytest.raises(InputError) as info:
        load_scene({**BASE, "axes": axes, "boundaries": section})
    text = str(info.value)
    assert words in text and "omega, mu, A)" in text, text


@pytest.mark.parametrize("section, words, not_said", [
    ({"along": "mu", "criterion": "period_exact", "level": 3.0},
     "boundaries.along: 'mu' has 1 value in this scene; expected an axis of at least 2 numeric values (A)", "unknown"),
    ({"along": "A", "criterion": "period_exact", "level": 3.0, "continue_in": "mu"},
     "boundaries.continue_in: 'mu' has 1 value in this scene; expected an axis of at least 2 numeric values other "
     "than along (this scene has none)", "unknown"),
    ({"along": "A", "criterion": "period_exact", "level": 3.0, "status_change": ["ok", "no_motion"],
      "continue_in": "mu"}, "exactly one of criterion", "needs a criterion"),
])
def test_a_boundaries_axis_that_is_known_but_cannot_be_swept_says_why(section, words, not_said):
    """An axis of one value is not 'unknown', and a section giving both a criterion and a status
    change is told that, not also that continuation 'needs a criterion' (a docs-only trial)."""
    from mechsweep.errors import InputError
    mu = [-1.0, -2.0] if "status_change" in section else [-1.0]
    with pytest.raises(InputError) as info:
        load_scene({**BASE, "axes": {"A": {"start": 0.1, "stop": 3.0, "num": 5}, "mu": mu}, "boundaries": section})
    text = str(info.value)
    assert words in text and not_said not in text, text


def test_continuation_on_linear_axes_of_large_values_warns_nothing():
    """A linear axis is not raised to a power of ten (it overflowed for values above 308 and
    leaked RuntimeWarning: overflow encountered in power): the same curve, mu up to 1000."""
    import warnings
    scene = load_scene({
        "scene": {"name": "eps", "model": "duffing", "outputs": ["epsilon"]},
        "axes": {"A": {"start": 0.04, "stop": 2.0, "num": 10}, "mu": {"start": 0.1, "stop": 1000.0, "num": 10}},
        "fixed": {"omega": 2.0}, "boundaries": {"along": "A", "criterion": "epsilon", "level": 0.5}})
    crit = bd.criterion_of(scene)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        curve = bd.continue_boundary(scene, crit, np.array([2.0, np.nan, np.nan]), "A", "mu",
                                     (math.sqrt(0.5 * 4.0 / 1000.0), 1000.0))
    A, mu = curve.points[:, 0], curve.points[:, 1]
    assert curve.stop == "edge" and A[-1] == pytest.approx(2.0, abs=1e-12)
    np.testing.assert_allclose(mu, 0.5 * 4.0 / A**2, rtol=1e-10)


def test_continuation_from_a_zero_coordinate_on_a_linear_axis_warns_nothing():
    """A start at mu = 0 on a linear axis is not put through log10 (it leaked RuntimeWarning: divide
    by zero, a docs-only trial's start at delta = 0): epsilon = 0 is the line mu = 0, followed to A's end."""
    import warnings
    scene = load_scene({
        "scene": {"name": "eps", "model": "duffing", "outputs": ["epsilon"]},
        "axes": {"A": {"start": 0.04, "stop": 2.0, "num": 10}, "mu": {"start": -1.0, "stop": 1.0, "num": 10}},
        "fixed": {"omega": 2.0}, "boundaries": {"along": "A", "criterion": "epsilon", "level": 0.0}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        curve = bd.continue_boundary(scene, bd.criterion_of(scene), np.array([1.0, np.nan, np.nan]), "A", "mu",
                                     (1.0, 0.0))
    assert curve.stop == "edge" and curve.points[-1, 0] == pytest.approx(2.0, abs=1e-12)
    assert (curve.points[:, 1] == 0.0).all()


def _box_crossings(s, c):
    """Where the line y = s x + c meets the edges of the unit square, sorted by x (exact)."""
    found = [(x, s * x + c) for x in (0.0, 1.0) if 0.0 <= s * x + c <= 1.0]
    found += [((y - c) / s, y) for y in (0.0, 1.0) if 0.0 < (y - c) / s < 1.0]
    return sorted(set(found))


@pytest.mark.parametrize("s,c", [
    (2.0, -0.998),  # leaves through the top edge 0.001 before the corner (x = 1 was held: y = 1.002)
    (1.5, -0.4653125),  # the same 0.023 before it
    (-3.0, 2.997),  # down through the bottom edge near the corner (x = 0.999)
    (2.0, 0.2),  # from the top edge to the left one; level 0: the corrector's test never converged
    (2.0, -1.0),  # through the corner (1, 1) itself
])
def test_continuation_of_a_straight_boundary_is_the_line_once_and_inside_the_chart(tmp_path, s, c):
    """g = y - s x - c, level 0, continued in (x, y) over the unit square from the crossings located
    along x on the lines y = 0 and y = 1: one curve (the start on the other end line lies on it and
    is not followed again; it was followed a second time from there), every point on the line to
    round-off and inside the chart, from one edge crossing of the line to the other (a curve leaving
    near a corner ended beyond the chart, on the edge its chord reached first, not the one it
    crossed). A level-0 closed form reached its end (its accuracy 16 ulp |g| is never met by g's
    round-off: the curve stopped after its first point, step_too_small)."""
    scene = load_scene({
        "scene": {"name": "line", "model": f"{HERE / 'user_models' / 'line_boundary.py'}:LINE", "outputs": ["g"]},
        "axes": {"x": {"start": 0.0, "stop": 1.0, "num": 11}, "y": {"start": 0.0, "stop": 1.0, "num": 6}},
        "fixed": {"s": s, "c": c}, "storage": {"path": str(tmp_path / "line.h5")},
        "boundaries": {"along": "x", "criterion": "g", "level": 0.0, "continue_in": "y"}})
    _, ds = bd.run_boundaries(scene, warn=False)
    x, y = ds["curve_x"].values, ds["curve_y"].values
    assert x.shape[0] == 1 and ds["curve_stop"].values.tolist() == [bd.CURVE_STOPS.index("edge")]
    ok = np.isfinite(x[0])
    x, y = x[0][ok], y[0][ok]
    assert ((x >= 0) & (x <= 1) & (y >= 0) & (y <= 1)).all()
    np.testing.assert_allclose(y - s * x - c, 0.0, atol=1e-12)
    ends = sorted([(x[0], y[0]), (x[-1], y[-1])])
    np.testing.assert_allclose(ends, _box_crossings(s, c), rtol=0, atol=1e-9)


def test_scene_continue_in_stores_the_tongue_with_its_fold(tmp_path, capsys):
    """[boundaries] continue_in = "q": the boundaries located along a at the ends of the q axis are
    followed in (a, q); the tongue's two edges at q = 0.6 are one curve (the second start lies on
    the first curve and is not followed again), stored with its fold and why it stopped."""
    scene = tmp_path / "tongue.toml"
    scene.write_text(f"""
[scene]
name = "tongue"
model = "{MATHIEU_FILE}:MATHIEU_JAC"
outputs = ["max_multiplier"]
[axes]
a = {{ start = 0.3, stop = 1.7, num = 29 }}
q = {{ start = 0.0, stop = 0.6, num = 7 }}
[fixed]
c = 0.1
[solver]
rtol = 1e-12
atol = 1e-14
[storage]
path = "{tmp_path / 'tongue.h5'}"
[boundaries]
along = "a"
criterion = "max_multiplier"
criterion_accuracy = 1e-11
continue_in = "q"
""")
    assert main(["boundaries", str(scene), "--no-progress", "--threads", "1"]) == 0
    assert "continued in q: 1 curve(s), 1 fold(s)" in capsys.readouterr().out
    with xr.open_dataset(tmp_path / "tongue.boundaries.h5") as ds:
        assert ds["curve_a"].dims == ("curve", "point") and ds["curve_q"].attrs["units"] == "1"
        a, q = ds["curve_a"].values[0], ds["curve_q"].values[0]
        a, q = a[np.isfinite(a)], q[np.isfinite(q)]
        assert q[0] == q[-1] == pytest.approx(0.6, abs=1e-12)
        np.testing.assert_allclose([a[0], a[-1]], ds["boundary"].sel(q=0.6).values, rtol=1e-9)
        assert ds["curve_stop"].values.tolist() == [0]  # edge
        assert ds["fold_axis"].values.tolist() == [[1]] and 0.09 < float(ds["fold_q"].values[0, 0]) < 0.11
        assert ds["fold_located"].values.tolist() == [[1]]


def test_the_speck_of_stability_in_the_damping_chart_is_a_real_island():
    """sweeps/autobalancer_damping.toml shows a speck of 'stable' near Omega / omega_xi = 1.38,
    zeta_xi = 0.025. Located along Omega at zeta_xi = 0.025 it has two boundaries; followed in
    (Omega, zeta_xi) both ways from both, the four curves end at one point (a corner of floquet_max,
    where the largest multiplier changes) and enclose an island Omega in [27.632, 27.851] rad/s,
    zeta_xi in [0.02154, 0.02861] (measured 2026-11-23): the speck is real."""
    import tomllib

    from tests.conftest import SWEEPS

    d = tomllib.loads((SWEEPS / "autobalancer_damping.toml").read_text())
    d["scene"]["outputs"] = ["floquet_max"]
    d["axes"] = {"Omega": {"start": 27.0, "stop": 28.4, "num": 15}, "zeta_xi": {"start": 0.015, "stop": 0.04, "num": 2}}
    d["boundaries"] = {"along": "Omega", "criterion": "floquet_max", "level": 1.0, "rtol": 1e-8}
    scene = load_scene(d)
    crit = bd.criterion_of(scene)
    rows, col, _ = bd.base_rows(scene, "Omega")
    row = rows[0].copy()
    names = scene.model.param_names()
    row[names.index("zeta_xi")] = 0.025
    res = bd.locate(scene, crit, row[None, :], col, np.linspace(27.0, 28.4, 15), rtol=1e-8)
    assert np.isfinite(res.location).sum() == 2 and res.direction[0].tolist() == [-1, 1]  # stable between
    ends, pts = [], []
    for x in res.location[0]:
        for d in (1, -1):
            c = bd.continue_boundary(scene, crit, row, "Omega", "zeta_xi", (x, 0.025), step=0.005, step_max=0.01,
                                     direction=d)
            assert c.stop == "step_too_small"
            ends.append(c.points[-1])
            pts.append(c.points)
    np.testing.assert_allclose(np.array(ends), np.repeat(ends[:1], 4, axis=0), rtol=1e-5)
    pts = np.vstack(pts)
    np.testing.assert_allclose(pts.min(axis=0), [27.632, 0.02154], rtol=2e-4)
    np.testing.assert_allclose(pts.max(axis=0), [27.851, 0.02861], rtol=2e-4)


def test_scene_continue_in_follows_an_island_touching_neither_end_line(tmp_path):
    """[boundaries] continue_in also starts from a crossing located on an inner line of the
    continue_in axis that no curve followed so far passes through (both ways): the damping chart's
    island (Omega in [27.632, 27.851] rad/s, zeta_xi in [0.02154, 0.02861], see the test above) is
    found from the middle one of three zeta_xi lines, and stored as continued curves, its second
    crossing on that line not followed again."""
    import tomllib

    from tests.conftest import SWEEPS

    d = tomllib.loads((SWEEPS / "autobalancer_damping.toml").read_text())
    d["scene"]["outputs"] = ["floquet_max"]
    d["axes"] = {"Omega": {"start": 27.0, "stop": 28.4, "num": 15}, "zeta_xi": [0.015, 0.025, 0.035]}
    d["boundaries"] = {"along": "Omega", "criterion": "floquet_max", "level": 1.0, "rtol": 1e-8,
                       "continue_in": "zeta_xi"}
    d["storage"] = {"path": str(tmp_path / "island.h5")}
    _, ds = bd.run_boundaries(load_scene(d))
    loc = ds["boundary"].values
    assert np.isfinite(loc[1]).sum() == 2 and not np.isfinite(loc[[0, 2]]).any()  # only the inner line crosses it
    x, y = ds["curve_Omega"].values, ds["curve_zeta_xi"].values
    assert x.shape[0] == 2  # both ways from the first crossing; the second lies on them
    ok = np.isfinite(x)
    np.testing.assert_allclose([x[ok].min(), y[ok].min()], [27.632, 0.02154], rtol=2e-4)
    np.testing.assert_allclose([x[ok].max(), y[ok].max()], [27.851, 0.02861], rtol=2e-4)


X0_EDGE = 1.2345678901234


def _sqrt_edge(x):  # leaves 0 like a double Floquet multiplier: expm1(C sqrt(d))
    return np.where(x > X0_EDGE, np.expm1(0.7 * np.sqrt(np.abs(x - X0_EDGE))), 0.0)


def _linear_edge(x):
    return np.where(x > X0_EDGE, 3.0 * (x - X0_EDGE) + (x - X0_EDGE) ** 2, 0.0)


def _band_edge_search(fun, power, eps=1e-9, rtol=1e-10):
    """locate._band_edges on the one cell [1.0, 1.4] of the criterion ``fun`` (band |g| <= eps):
    (A, B, loc, bound, n_eval) after the search."""
    A, B = np.array([1.0]), np.array([1.4])
    gA, gB = fun(A), fun(B)
    acc = lambda g: np.full(np.size(g), eps)  # noqa: E731
    n_eval, bound, loc = np.zeros(1, dtype=np.int64), np.full(1, -1, dtype=np.int8), np.full(1, np.nan)

    def ev(line, x):
        x = np.asarray(x)
        return fun(x), np.zeros(x.size), np.full(x.size, np.nan)

    bd_search._band_edges(ev, np.zeros(1, dtype=int), np.array([0]), A, B, bd_search._sides(gA, acc(gA)),
                          bd_search._sides(gB, acc(gB)), gA, gB, np.full(1, np.nan), np.full(1, np.nan), n_eval,
                          bound, loc, lambda a, b: rtol * np.maximum(np.abs(a), np.abs(b)), acc, power)
    return A, B, loc, bound, n_eval


@pytest.mark.parametrize("fun, power", [(_sqrt_edge, 2.0), (_linear_edge, 1.0), (_sqrt_edge, 1.0),
                                        (_linear_edge, 2.0)])
def test_band_edges_are_found_to_tol_in_few_evaluations_whichever_law_is_guessed(fun, power):
    """The band |g| <= eps ends at X0 (+ the distance where g reaches eps); the edge search
    closes a bracket of width <= tol around it from a 0.4-wide cell, within 24 evaluations even
    when it starts with the wrong law (square root vs linear): bisection would take 32."""
    eps, rtol = 1e-9, 1e-10
    A, B, loc, bound, n_eval = _band_edge_search(fun, power, eps, rtol)
    edge = brentq(lambda x: float(fun(np.array([x]))[0]) - eps, X0_EDGE, 1.4, xtol=1e-15, rtol=1e-15)
    assert bound[0] == bd.BAND_EDGE and B[0] - A[0] <= rtol * B[0]
    assert A[0] <= edge <= B[0] and abs(loc[0] - edge) <= rtol * edge
    assert n_eval[0] <= 24, n_eval


def test_a_band_edge_with_a_flat_criterion_beside_it_is_found_by_bisection_without_a_warning():
    """Off the band the criterion takes the same value at the two points nearest the edge (a jump
    to a plateau; at a tongue tip the two off-band values can tie): the secant through them has
    no root (the prediction is +-inf), so the search bisects. The infinite prediction used to
    reach the probes' arithmetic (inf - inf: numpy's "invalid value encountered in add")."""
    import warnings

    rtol = 1e-10

    def fun(x):
        return np.where(np.asarray(x) > X0_EDGE, 0.5, 0.0)

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        A, B, loc, bound, n_eval = _band_edge_search(fun, 2.0, rtol=rtol)
    assert bound[0] == bd.BAND_EDGE and B[0] - A[0] <= rtol * B[0]
    assert A[0] <= X0_EDGE <= B[0] and abs(loc[0] - X0_EDGE) <= rtol * X0_EDGE


def test_a_closed_form_of_an_integrated_output_inherits_its_accuracy():
    """ratio = T / T0 of a pendulum's integrated period T at solver rtol 1e-6: the criterion is only
    as accurate as the integration, so its accuracy is 100 rtol max(|value|, |level|) (it was 16 ulp,
    "a closed form": brackets 1e-10 wide, bound 'parameter', the true boundary outside them). Each
    bracket now holds the boundary of the exact period 4 K(sin^2(A/2)) sqrt(L/g), bound 'criterion'."""
    from scipy.special import ellipk

    level, g, L = 1.1, 9.81, 0.8
    scene, rows, res = _locate({
        "scene": {"name": "pr", "model": f"{HERE / 'user_models' / 'pendulum_ratio.py'}:PENDULUM_RATIO",
                  "outputs": ["ratio"]},
        "axes": {"A": {"start": 0.2, "stop": 2.0, "num": 7}}, "fixed": {"g": g, "L": L},
        "solver": {"rtol": 1e-6, "atol": 1e-9},
        "boundaries": {"along": "A", "criterion": "ratio", "level": level}})
    exact = brentq(lambda a: 2.0 * ellipk(math.sin(a / 2) ** 2) / math.pi - level, 0.2, 2.0, xtol=1e-15)
    found = res.bound >= 0
    loc, width = res.location[found][0], res.width[found][0]
    assert abs(loc - exact) <= width / 2 and width < 1e-2, (loc, width, exact)
    assert abs(loc - exact) > 1e-9 * exact  # the integration's error: a bracket of rtol 1e-10 would miss it
    assert found.sum() == 1 and res.bound[found][0] == bd.CRITERION
    crit = bd.criterion_of(scene)
    assert bd.from_integration(scene.model, "ratio")
    assert bd.criterion_accuracy(scene.model, scene.solver, crit, np.array([1.0]))[0] == pytest.approx(1e-4 * level)
    assert "(a closed form of integrated outputs: their accuracy)" in bd.accuracy_text(scene, crit)
