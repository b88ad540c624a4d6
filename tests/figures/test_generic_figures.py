"""Generic figures for a model the package has never heard of: chosen from the dataset's declared
attributes (model, output kinds, dimensions, axis spacing), labelled from them, drawn on a given
``Axes`` without touching matplotlib's global state."""
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr
from matplotlib.figure import Figure

import mechsweep
from mechsweep import figures
from mechsweep.cli import main
from mechsweep.errors import InputError
from mechsweep.figures import generic
from mechsweep.figures._style import label

HERE = Path(__file__).parents[1]


@pytest.fixture(autouse=True)
def mpl_state():
    """Every test here checks that drawing changed no matplotlib global state: rcParams (the backend
    included, read raw so as not to resolve it) and pyplot's list of figures. The figures are made
    without pyplot, so no backend needs choosing and nothing is set for the tests that run after."""
    import matplotlib

    before = dict(dict.items(matplotlib.rcParams))
    plt = sys.modules.get("matplotlib.pyplot")
    figs = plt.get_fignums() if plt else None
    yield
    assert dict(dict.items(matplotlib.rcParams)) == before
    if plt is not None:
        assert plt.get_fignums() == figs


def cam(n_speed=30, n_preload=6, contacts=("steel", "bronze"), model="cam_follower"):
    """A dataset as a run of a model unknown to the package stores it: speed log-spaced, preload
    linear, a categorical axis; an output of no declared kind, one of kind floquet_max and one with
    an extra (time) dimension. Two flagged points: one keeps a finite value, one is NaN."""
    speed = np.geomspace(1.0, 1000.0, n_speed)
    preload = np.linspace(0.0, 50.0, n_preload)
    S, P = np.meshgrid(speed, preload, indexing="ij")
    lift = np.stack([np.sqrt(S) * (1 + P / 25) * (1 + 0.3 * k) for k in range(len(contacts))], axis=-1)
    floquet = np.stack([0.5 + S / 400 - P / 100 + 0.1 * k for k in range(len(contacts))], axis=-1)
    status = np.zeros(lift.shape, np.int8)
    status[3, 2, 0] = 1  # flagged, lift still finite (another output failed there)
    status[5, 4, 0] = 4
    lift[5, 4, 0] = np.nan  # flagged, no value
    dims = ("speed", "preload", "contact")
    ds = xr.Dataset(
        {"lift": (dims, lift, {"units": "mm", "long_name": "follower lift-off height", "symbol": "h"}),
         "floquet": (dims, floquet, {"units": "1", "long_name": "largest Floquet multiplier modulus",
                                     "mechsweep_kind": "floquet_max"}),
         "lift_history": (dims + ("t",), np.zeros(lift.shape + (4,)), {"units": "mm", "long_name": "lift over time"}),
         "status": (dims, status)},
        coords={"speed": ("speed", speed, {"units": "rad/s", "long_name": "speed of the cam", "symbol": "Ω",
                                           "spacing": "log"}),
                "preload": ("preload", preload, {"units": "N", "long_name": "spring preload", "symbol": "F0",
                                                 "spacing": "linear"}),
                "contact": ("contact", list(contacts), {"units": "", "long_name": "contact material",
                                                        "spacing": "list"}),
                "t": ("t", np.arange(4.0), {"units": "s", "long_name": "time"})},
        attrs={"model": model, "outputs": "lift floquet lift_history", "title": "cam follower",
               "scene_canonical": "{}", "scene": ""})
    return ds


def _axes_of(ds, *keep):
    """ds with every grid axis not in ``keep`` cut down to its first value (a dimension of size 1)."""
    return ds.isel({d: slice(0, 1) for d in ("speed", "preload", "contact") if d not in keep})


def test_figures_of_an_unknown_model_are_chosen_from_declared_kinds_and_axes():
    ds = cam()
    assert list(figures.available(ds)) == ["stability_map", "heatmap_lift", "nomogram_lift"]
    assert figures.on_request(ds) == {}  # no figure of its own: every generic figure is drawn
    choice = {c.name: c for c in generic.choose(ds)}
    # heatmap: the first numeric axis is y, the second x; nomogram: curves over the axis with <= 10 values
    assert (choice["heatmap_lift"].y, choice["heatmap_lift"].x) == ("speed", "preload")
    assert (choice["nomogram_lift"].x, choice["nomogram_lift"].y) == ("speed", "preload")
    assert "lift_history" not in " ".join(figures.available(ds))  # extra dimension: not drawn generically


@pytest.mark.parametrize("keep,expected", [
    (("speed",), ["curve_lift", "curve_floquet"]),  # one numeric axis (a stability map needs two)
    (("speed", "contact"), ["nomogram_lift", "nomogram_floquet"]),  # + a few names: a curve per name
    (("speed", "preload"), ["stability_map", "heatmap_lift", "nomogram_lift"]),
])
def test_selection_follows_the_axes(keep, expected):
    assert list(figures.available(_axes_of(cam(), *keep))) == expected


def test_no_family_of_curves_over_an_axis_with_many_values():
    ds = cam(n_preload=11)  # both numeric axes have more than FAMILY_MAX values
    assert list(figures.available(ds)) == ["stability_map", "heatmap_lift"]


def test_no_numeric_axis_no_figure(tmp_path):
    ds = _axes_of(cam(), "contact")
    assert figures.available(ds) == {}
    with pytest.raises(InputError, match="no figure fits this dataset"):
        figures.save(ds, tmp_path / "x.png")


def test_model_figures_follow_the_model_attribute_not_variable_names():
    """Outputs named like the built-in Duffing model's do not bring its figures to another model;
    for that model, its figure is drawn and the generic ones are on request."""
    A = np.linspace(0.1, 1.0, 5)
    data = {n: ("A", A * k, {"units": "1", "long_name": n}) for k, n in ((1.0, "epsilon"), (2.0, "kv"))}
    ds = xr.Dataset({**data, "status": ("A", np.zeros(5, np.int8))},
                    coords={"A": ("A", A, {"units": "rad", "long_name": "amplitude"})},
                    attrs={"model": "my_own", "outputs": "epsilon kv"})
    assert list(figures.available(ds)) == ["curve_epsilon", "curve_kv"]
    ds.attrs["model"] = "duffing"
    assert list(figures.available(ds)) == ["kinematic_coefficients"]
    assert list(figures.on_request(ds)) == []  # kinematic_coefficients draws both
    ds.attrs["outputs"] = "epsilon kv"
    ds["other"] = ("A", A, {"units": "m", "long_name": "other"})
    ds.attrs["outputs"] = "epsilon kv other"
    assert list(figures.on_request(ds)) == ["curve_other"]


def test_declared_outputs_are_read_by_one_helper_for_grid_and_history_outputs():
    """generic.declared_floats reads the run's ``outputs`` attribute for float_outputs (over the grid)
    and history_outputs (one extra dimension at a one-point grid) alike: the runner's space-separated
    text, bytes (an HDF5 attribute written by another tool) or a list of names; undeclared and
    non-float variables are left out, the declared order kept. No drawing."""
    s = np.linspace(0.0, 2.0, 5)
    ds = xr.Dataset({"x_hist": (("w", "period"), np.ones((1, 5))), "x_end": ("w", [1.0]), "extra": ("w", [2.0]),
                     "status": ("w", np.zeros(1, np.int8))}, coords={"w": ("w", [1.0]), "period": ("period", s)})
    for declared in ("x_hist x_end status", b"x_hist x_end status", ["x_hist", "x_end", "status"],
                     np.array([b"x_hist", b"x_end", b"status"])):
        ds.attrs["outputs"] = declared
        assert generic.declared_floats(ds) == ["x_hist", "x_end"], declared
        assert generic.float_outputs(ds) == ["x_end"], declared
        assert generic.history_outputs(ds) == [("x_hist", "period")], declared
    del ds.attrs["outputs"]  # none declared: every float variable
    assert generic.float_outputs(ds) == ["x_end", "extra"]
    assert generic.history_outputs(ds) == [("x_hist", "period")]


def test_the_generic_figure_code_names_no_model_and_no_variable():
    """The front and the generic modules hold no built-in model's name, parameter or output; only the
    figure modules for a model (duffing.py, ...) do."""
    from mechsweep.models import MODELS
    from mechsweep.model.spec import OUTPUT_KINDS

    folder = Path(figures.__file__).parent
    names = set(MODELS) | {x.name for spec in MODELS.values() for x in spec.outputs + spec.params}
    # declared kinds are the generic vocabulary (an output may share a kind's name); one letter is
    # too short to tell a name from e.g. matplotlib's colour "k"
    names = {n for n in names if len(n) > 1} - set(OUTPUT_KINDS)
    for module in ("__init__.py", "generic.py", "_registry.py", "_style.py"):
        source = (folder / module).read_text()
        assert not [n for n in names if f'"{n}"' in source or f"'{n}'" in source], module


def test_heatmap_on_a_given_axes_returns_its_artists_labelled_from_attributes():
    ds = cam()
    fig = Figure()
    ax = fig.add_subplot()
    art = generic.heatmap(ds, "lift", x="preload", y="speed", at={"contact": "bronze"}, ax=ax)
    assert art["mesh"].axes is ax and art["contours"].axes is ax and art["where"] == {"contact": "bronze"}
    assert ax.get_yscale() == "log" and ax.get_xscale() == "linear"  # speed was swept log-spaced
    assert ax.get_ylabel() == label(ds["speed"]) and "speed of the cam [rad/s]" in ax.get_ylabel()
    assert "spring preload [N]" in ax.get_xlabel()
    assert art["colorbar"].ax.get_ylabel() == label(ds["lift"])
    np.testing.assert_array_equal(np.asarray(art["mesh"].get_array()).reshape(30, 6),
                                  ds["lift"].sel(contact="bronze").values)
    levels = art["contours"].levels
    values = ds["lift"].sel(contact="bronze").values
    assert len(levels) >= 3 and (levels > values.min()).all() and (levels < values.max()).all()
    labelled = {float(t.get_text()) for t in art["contour_labels"]}
    assert labelled and labelled <= set(np.round(levels, 12))
    assert art["flagged"] is None  # no flagged point in the bronze slice


def test_drawing_arguments_are_checked():
    ds = cam()
    with pytest.raises(ValueError, match="'contact' holds names"):
        generic.heatmap(ds, "lift", x="contact", y="speed")
    with pytest.raises(ValueError, match="'t' is not a dimension of 'lift'"):
        generic.nomogram(ds, "lift", x="t")
    with pytest.raises(ValueError, match="at: speed is not one of the dimensions"):
        generic.nomogram(ds, "lift", x="speed", at={"speed": 1.0})


def test_contour_levels_are_round_numbers():
    np.testing.assert_allclose(generic.contour_levels(0.013, 0.087, False), [0.02, 0.04, 0.06, 0.08])
    np.testing.assert_allclose(generic.contour_levels(-3.3, 11.9, False), [-2.5, 0, 2.5, 5, 7.5, 10])
    np.testing.assert_allclose(generic.contour_levels(3e-7, 0.2, True), [1e-6, 1e-5, 1e-4, 1e-3, 1e-2, 1e-1])
    assert generic.contour_levels(2.0, 2.0, False).size == 0


def test_flagged_points_are_marked_and_finite_values_drawn():
    ds = cam()
    art = generic.heatmap(ds, "lift", x="preload", y="speed")  # contact = steel, the first
    shown = np.ma.asarray(art["mesh"].get_array()).reshape(30, 6)
    assert not np.ma.is_masked(shown[3, 2]) and shown[3, 2] == ds["lift"].values[3, 2, 0]
    assert np.ma.getmaskarray(shown)[5, 4] and np.ma.getmaskarray(shown).sum() == 1  # only the NaN
    marks = art["flagged"].get_offsets()
    np.testing.assert_allclose(sorted(map(tuple, marks)), sorted([(ds.preload.values[2], ds.speed.values[3]),
                                                                  (ds.preload.values[4], ds.speed.values[5])]))
    assert "2 flagged points" in art["note"].get_text() and "1 with a value (drawn), 1 without" in art["note"].get_text()
    curves = generic.nomogram(ds, "lift", x="speed", family="preload")
    flagged = np.concatenate([m.get_offsets() for m in curves["flagged"]])
    np.testing.assert_allclose(flagged, [(ds.speed.values[3], ds["lift"].values[3, 2, 0])])


def test_nomogram_many_curves_get_a_colour_scale_and_end_labels():
    ds = cam()
    ds["lift"][-1] = 50.0  # every curve ends at the same value: their labels must be moved apart
    fig = Figure()
    ax = fig.add_subplot()
    art = generic.nomogram(ds, "lift", x="speed", family="preload", ax=ax)
    assert len(art["lines"]) == 6 and all(line.axes is ax for line in art["lines"])
    assert ax.get_xscale() == "log" and "follower lift-off height [mm]" in ax.get_ylabel()
    assert [t.get_text().strip() for t in art["end_labels"]] == ["0", "10", "20", "30", "40", "50"]
    ys = sorted(t.xyann[1] for t in art["end_labels"])
    assert min(np.diff(ys)) >= 0.05 - 1e-12  # moved apart (by 5 % of the axes height): none overlaps the next
    assert art["legend"] is None and art["colorbar"].ax.get_ylabel() == label(ds["preload"])


def test_nomogram_few_curves_get_a_legend():
    ds = cam()
    art = generic.nomogram(ds, "lift", x="speed", family="contact", at={"preload": 20.0})
    assert [t.get_text() for t in art["legend"].get_texts()] == ["steel", "bronze"]
    assert art["colorbar"] is None and art["end_labels"] == [] and art["where"] == {"preload": 20.0}
    np.testing.assert_array_equal(art["lines"][1].get_ydata(), ds["lift"].sel(preload=20.0, contact="bronze").values)


def test_panels_for_the_axes_a_figure_does_not_use():
    fig = figures.draw(cam(), "heatmap_lift")
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles == ["contact = steel", "contact = bronze"]
    fig = figures.draw(cam(contacts=tuple("abcdef")), "heatmap_lift")
    assert "first 4 of 6 slices of contact" in fig.get_suptitle()


def test_descriptions_are_whole_sentences():
    """`plot --list` prints each figure's description whole (it used to print the first line of a
    docstring, cut mid-sentence)."""
    texts = [f.description for f in figures.MODEL_FIGURES] + list(figures.available(cam()).values())
    assert all(t.endswith((".", ".)")) and "\n" not in t for t in texts), texts


def test_an_output_without_a_finite_value_is_drawn_empty():
    ds = cam()
    ds["lift"][:] = np.nan
    art = generic.heatmap(ds, "lift", x="preload", y="speed")
    assert np.ma.getmaskarray(art["mesh"].get_array()).all() and art["contours"] is None
    art = generic.nomogram(ds, "lift", x="speed", family="contact")
    assert all(np.isnan(line.get_ydata()).all() for line in art["lines"])


def test_plot_lists_full_descriptions_and_draws_the_generic_figures(tmp_path, capsys):
    path = tmp_path / "cam.h5"
    cam(n_speed=12, contacts=("steel",)).to_netcdf(path, engine="h5netcdf")  # small: one panel per figure
    assert main(["plot", str(path), "--list"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert [line.split(":")[0] for line in lines] == ["stability_map", "heatmap_lift", "nomogram_lift"]
    assert all(line.endswith(".") for line in lines)  # whole sentences, never cut
    assert main(["plot", str(path)]) == 0
    assert sorted(p.name for p in tmp_path.glob("*.png")) == ["cam_heatmap_lift.png", "cam_nomogram_lift.png",
                                                              "cam_stability_map.png"]


def test_a_user_model_run_is_plotted_with_generic_figures(tmp_path, capsys):
    """The user-model scene of tests/model/test_model_layer.py (same outputs: its compiled kernel is reused):
    one list axis, so one curve per output; the period is drawn at every point although five points
    are flagged (another output, period_short, finds no event there)."""
    scene = mechsweep.load_scene(HERE / "user_models" / "linear.toml")
    ds = mechsweep.run(scene, output=tmp_path / "lin.h5", progress=False)
    assert list(figures.available(ds)) == [f"curve_{n}" for n in scene.outputs]
    fig = figures.draw(ds, "curve_period")
    line = fig.axes[0].lines[0]
    np.testing.assert_allclose(line.get_ydata(), ds["period"].values)
    assert np.isfinite(line.get_ydata()).all() and (ds["status"].values != 0).sum() == 5
    assert main(["plot", str(tmp_path / "lin.h5"), "--kind", "curve_period"]) == 0
    assert (tmp_path / "lin.png").stat().st_size > 10_000


def test_stability_map_draws_every_valued_point_and_the_located_boundaries():
    """A point whose status is not ok but whose multiplier modulus has a value (e.g. undecided:
    within the verdict's margin of 1) is shaded like the others; located boundaries of the same
    grid (along speed, one line per preload) are drawn at (boundary, preload); the longer axis
    (speed, 30 values) runs across."""
    from mechsweep import status as st

    ds = _axes_of(cam(), "speed", "preload")
    ds["status"].values[7, 1, 0] = st.UNDECIDED  # its floquet value stays finite
    crossing = np.array([[30.0 + 10 * i, np.nan] for i in range(ds.sizes["preload"])])
    bds = xr.Dataset(
        {"boundary": (("preload", "crossing"), crossing, {"units": "rad/s"}),
         "boundary_width": (("preload", "crossing"), np.full(crossing.shape, 1e-9), {"units": "rad/s"})},
        coords={"preload": ds["preload"].values, "crossing": [0, 1]},
        attrs={"mechsweep_kind": "boundaries", "model": "cam_follower", "along": "speed", "criterion": "floquet",
               "level": 1.0, "rtol": 1e-10})
    art = figures.artists(ds, "stability_map", boundaries=bds)
    ax = art["axes"][0, 0]
    assert "speed of the cam" in ax.get_xlabel() and "spring preload" in ax.get_ylabel()
    panel = art["panels"][0]
    shaded = panel["mesh"].get_array().reshape(ds.sizes["preload"], ds.sizes["speed"])
    assert not np.ma.is_masked(shaded[1, 7])  # the undecided point is drawn
    points = panel["located"][0].get_offsets()
    np.testing.assert_allclose(points[:, 0], crossing[:, 0])
    np.testing.assert_allclose(points[:, 1], ds["preload"].values)
    assert "located" not in figures.artists(ds, "stability_map")["panels"][0]


def _speed_boundaries(ds, continued=False):
    """A boundaries dataset of ds's grid (speed x preload) located along speed: one crossing per
    preload at 30 + 10 i; ``continued``: one curve continued in preload, through those points."""
    crossing = np.array([[30.0 + 10 * i, np.nan] for i in range(ds.sizes["preload"])])
    data = {"boundary": (("preload", "crossing"), crossing, {"units": "rad/s"}),
            "boundary_width": (("preload", "crossing"), np.full(crossing.shape, 1e-9), {"units": "rad/s"})}
    attrs = {"mechsweep_kind": "boundaries", "model": "cam_follower", "along": "speed", "criterion": "lift",
             "level": 20.0, "rtol": 1e-10}
    if continued:
        data["curve_speed"] = (("curve", "point"), crossing[:, :1].T, {"units": "rad/s"})
        data["curve_preload"] = (("curve", "point"), ds["preload"].values[None, :], {"units": "N"})
        attrs["continue_in"] = "preload"
    return xr.Dataset(data, coords={"preload": ds["preload"].values, "crossing": [0, 1]}, attrs=attrs)


def test_a_heatmap_over_the_located_axis_draws_the_located_boundaries():
    """Boundaries located along speed are drawn over the heatmap whose axes are speed and preload
    (speed vertical: the points at (preload, boundary)), with the continued curve and a legend
    saying what they are, readable; a nomogram draws none (it plots the output against speed)."""
    from . import figure_checks as fc

    ds = _axes_of(cam(), "speed", "preload")
    bds = _speed_boundaries(ds, continued=True)
    assert figures.boundary_figures(ds, bds) == ["stability_map", "heatmap_lift"]
    art = figures.artists(ds, "heatmap_lift", boundaries=bds)
    assert (art["panels"][0]["located"] and (generic.choose(ds)[1].x, generic.choose(ds)[1].y)
            == ("preload", "speed"))
    points, curve = art["panels"][0]["located"][:2]
    np.testing.assert_allclose(points.get_offsets()[:, 0], ds["preload"].values)
    np.testing.assert_allclose(points.get_offsets()[:, 1], 30.0 + 10 * np.arange(ds.sizes["preload"]))
    np.testing.assert_allclose(curve.get_xdata(), ds["preload"].values)
    assert "boundary where" in " ".join(t.get_text() for t in art["legend"].get_texts())
    assert fc.check_readable(art["figure"], ds) == []
    assert "located" not in figures.artists(ds, "heatmap_lift")["panels"][0]
    assert "located" not in figures.artists(ds, "nomogram_lift", boundaries=bds)["panels"][0]


def test_plot_refuses_boundaries_no_figure_drawn_can_draw(tmp_path, capsys):
    """`plot --boundaries` on a figure that cannot draw them (a nomogram) is refused, naming the
    figures that can (it was ignored without a word); drawn with figures some of which cannot,
    a note says which show them."""
    ds = _axes_of(cam(n_speed=12), "speed", "preload")
    ds.to_netcdf(tmp_path / "cam.h5", engine="h5netcdf")
    _speed_boundaries(ds).to_netcdf(tmp_path / "b.h5", engine="h5netcdf")
    args = ["plot", str(tmp_path / "cam.h5"), "--boundaries", str(tmp_path / "b.h5")]
    assert main(args + ["--kind", "nomogram_lift"]) == 2
    err = capsys.readouterr().err
    assert "none of the figures drawn (nomogram_lift) draws located boundaries" in err
    assert "stability_map, heatmap_lift" in err
    assert main(args + ["--kind", "heatmap_lift"]) == 0
    assert "note" not in capsys.readouterr().err
    assert main(args) == 0
    assert "drawn on stability_map, heatmap_lift; not on nomogram_lift" in capsys.readouterr().err


def test_plot_names_an_unknown_kind_before_any_problem_of_the_boundaries(tmp_path, capsys):
    """`plot --kind NAME --boundaries PATH` with a figure the dataset does not have is refused for the
    figure, naming those it can draw, whatever the boundaries are (located on its grid, not
    boundaries at all, missing): it was refused for the boundaries first."""
    ds = _axes_of(cam(n_speed=12), "speed", "preload")
    ds.to_netcdf(tmp_path / "cam.h5", engine="h5netcdf")
    _speed_boundaries(ds).to_netcdf(tmp_path / "b.h5", engine="h5netcdf")
    cam(n_speed=7).to_netcdf(tmp_path / "other.h5", engine="h5netcdf")
    for given in ("b.h5", "other.h5", "missing.h5"):
        args = ["plot", str(tmp_path / "cam.h5"), "--kind", "NOT_A_FIGURE", "--boundaries", str(tmp_path / given)]
        assert main(args) == 2
        err = capsys.readouterr().err
        assert err.splitlines() == ["mechsweep plot: error: figure 'NOT_A_FIGURE' does not fit this dataset; "
                                    "it can draw: stability_map, heatmap_lift, nomogram_lift"], given
    assert not list(tmp_path.glob("*.png"))


def test_save_refuses_boundaries_no_figure_written_draws(tmp_path):
    """figures.save with boundaries refuses them as `plot --boundaries` does when no figure it writes
    draws them (a nomogram: they were dropped without a word), naming the figure and those that do,
    and when they were not located on the dataset's grid; nothing is written."""
    from mechsweep.errors import InputError

    ds = _axes_of(cam(n_speed=12), "speed", "preload")
    bds = _speed_boundaries(ds)
    with pytest.raises(InputError, match=r"none of the figures drawn \(nomogram_lift\) draws located boundaries; "
                                         r"the figures of this dataset that do: stability_map, heatmap_lift"):
        figures.save(ds, tmp_path / "n.png", kind="nomogram_lift", boundaries=bds)
    other = bds.assign_coords(preload=bds["preload"].values + 1.0)
    with pytest.raises(InputError, match="not located on the grid of this dataset: its axis 'preload'"):
        figures.save(ds, tmp_path / "n.png", kind="heatmap_lift", boundaries=other)
    assert not list(tmp_path.iterdir())
    assert figures.save(ds, tmp_path / "h.png", kind="heatmap_lift", boundaries=bds) == [tmp_path / "h.png"]


def _undamped(ds):
    """ds as an undamped model's run asked for a verdict: every stable point has the modulus 1 to
    round-off, status undecided, and the verdict (1 stable, 0 unstable) NaN there."""
    from mechsweep import status as st

    ds = ds.copy(deep=True)
    stable = ds["floquet"].values <= 1.0
    ds["floquet"].values[stable] = 1.0 + 1e-12
    ds["status"].values[...] = np.where(stable, st.UNDECIDED, st.OK)
    ds["stable"] = (ds["floquet"].dims, np.where(stable, np.nan, 0.0),
                    {"units": "1", "long_name": "1 if stable, 0 if unstable, NaN within the margin",
                     "mechsweep_kind": "verdict"})
    ds.attrs["outputs"] += " stable"
    return ds


def test_an_undamped_chart_says_its_stable_side_is_undecided_and_a_thinned_family_says_so():
    """On an undamped model's chart the stability map's stable entry says its points are at 1
    within the margin, status undecided (neutrally stable); the verdict's nomogram over a family
    of 30 values asked by --y names that status in its note (its stable side is blank) and says
    that every 3rd value of the family is drawn (it drew 10 of 30 curves without a word)."""
    from . import figure_checks as fc

    ds = _undamped(_axes_of(cam(), "speed", "preload"))
    n_stable = int((ds["floquet"].values <= 1.0 + 1e-6).sum())
    art = figures.artists(ds, "stability_map")
    stable_text = " ".join(art["legend"].get_texts()[0].get_text().split())  # as wrapped to the legend
    assert f"{n_stable} of them at 1 within the margin (status undecided" in stable_text, stable_text
    art = figures.artists(ds, "nomogram_stable", axes=("preload", "speed"))
    panel = art["panels"][0]
    assert len(panel["lines"]) == 10 and panel["thinned"] == "every 3rd of 30 values drawn"
    assert "every 3rd of 30 values drawn" in " ".join(panel["colorbar"].ax.get_ylabel().split())
    drawn = int((ds["floquet"].isel(speed=slice(None, None, 3)).values <= 1.0 + 1e-6).sum())  # on the curves drawn
    assert f"{drawn} flagged points (status undecided {drawn}, see status)" in " ".join(panel["note"].get_text().split())
    assert fc.check_readable(art["figure"], ds) == []
    damped = figures.artists(cam(), "stability_map")
    assert "undecided" not in damped["legend"].get_texts()[0].get_text()


def test_discrete_outputs_are_drawn_by_class_without_contours():
    """A declared verdict (0/1) and an output of a few whole numbers (a -1/0/+1 kind) get one flat
    colour per value and a colour bar ticked at the values, no interpolated contours (they used to
    get a continuous scale with contours at 0.2, 0.4, ...); a continuous output keeps its contours."""
    from matplotlib.colors import BoundaryNorm

    ds = _axes_of(cam(), "speed", "preload")
    S = ds["floquet"].values
    ds["kind"] = (ds["floquet"].dims, np.where(S > 1.2, -1.0, np.where(S > 0.8, 1.0, 0.0)),
                  {"units": "1", "long_name": "kind of the critical multiplier"})
    ds["stable"] = (ds["floquet"].dims, (S <= 1).astype(float), {"units": "1", "long_name": "stable",
                                                                 "mechsweep_kind": "verdict"})
    for name, classes in (("kind", [-1.0, 0.0, 1.0]), ("stable", [0.0, 1.0])):
        art = generic.heatmap(ds, name, x="preload", y="speed")
        assert art["contours"] is None and art["contour_labels"] == []
        assert isinstance(art["mesh"].norm, BoundaryNorm) and art["mesh"].cmap.N == len(classes)
        np.testing.assert_array_equal(art["colorbar"].get_ticks(), classes)
        shown = np.asarray(art["mesh"].get_array()).reshape(ds["kind"].shape[:2])
        colours = art["mesh"].cmap(art["mesh"].norm(shown))  # one colour per class, every class its own
        for c in classes:
            assert len({tuple(x) for x in colours[shown == c]}) == 1
        assert len({tuple(colours[shown == c][0]) for c in classes}) == len(classes)
    assert generic.heatmap(ds, "lift", x="preload", y="speed")["contours"] is not None


def test_a_stability_map_draws_the_panels_its_description_announces():
    """`plot --list` says "the first 4 of 6"; the drawing had 6 panels: now both say 4."""
    ds = cam(contacts=tuple("abcdef"))
    choice = next(c for c in generic.choose(ds) if c.kind == "stability_map")
    assert "(the first 4 of 6)" in choice.description
    fig = figures.draw(ds, "stability_map")
    titles = [ax.get_title() for ax in fig.axes if ax.get_title()]
    assert titles == [f"contact = {c}" for c in "abcd"]
    assert "first 4 of 6 slices of contact" in fig.get_suptitle()


def test_long_titles_wrap_inside_the_figure_and_a_lone_maps_legend_goes_below():
    """A title longer than the figure is wide wraps (it was cut at both edges); a one-panel stability
    map has its legend below the panel, not beside it squeezing it."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    ds = _axes_of(cam(), "speed", "preload").assign_coords(mass=xr.DataArray(2.0, attrs={"units": "kg"}))
    ds["floquet"].attrs["long_name"] = "largest modulus of the Floquet multipliers over one forcing period " * 2
    fig = figures.draw(ds, "stability_map")
    FigureCanvasAgg(fig).draw()
    box, renderer = fig.bbox, fig.canvas.get_renderer()
    head = fig._suptitle.get_window_extent(renderer)
    assert box.x0 <= head.x0 and head.x1 <= box.x1
    ax = fig.axes[0]
    legend = fig.legends[0].get_window_extent(renderer)
    assert legend.y1 <= ax.get_window_extent(renderer).y0  # below the panel
    assert ax.get_window_extent(renderer).width >= 0.6 * box.width
    assert ax.get_window_extent(renderer).height >= 0.45 * box.height  # the legend took half of it (a trial)
    # the fixed parameters head the legend (a caption box under the panel lay beneath it) ...
    assert fig.legends[0].get_title().get_text().replace("\xa0", " ").split("\n")[0] == "fixed: mass = 2 kg"
    assert fig._supxlabel is None
    # ... and the title stays inside the figure when saved at 150 dpi (matplotlib's wrap=True did not)
    import io
    fig.savefig(io.BytesIO(), dpi=150)
    renderer = fig.canvas.get_renderer()
    head = fig._suptitle.get_window_extent(renderer)
    assert fig.bbox.x0 <= head.x0 and head.x1 <= fig.bbox.x1


def test_panel_titles_give_the_slice_with_its_unit():
    """A panel's title names its slice with the axis's unit ("w = 1" was read without one); a
    list of names has none."""
    assert figures.draw(cam(), "heatmap_lift").axes[0].get_title() == "contact = steel"
    fig = figures.draw(cam(), "nomogram_lift", axes=("speed", "contact"))  # a panel per preload
    assert [a.get_title().replace("\xa0", " ") for a in fig.axes[:2]] == ["$F_{0}$ = 0 N", "$F_{0}$ = 10 N"]


def test_a_list_axis_spread_in_the_logarithm_gets_log_cells_and_crowded_contour_labels_are_thinned():
    """A list axis 0.1, 1, 10: log scale, cells from 10^-1.5 to 10^1.5 (linear cells stretched the
    last to 14.5). Contours bunched at one edge (a steep rise) are labelled where labels do not
    overlap: no two within LABEL_GAP of each other (they piled up there)."""
    L = np.array([0.1, 1.0, 10.0])
    A = np.linspace(0.0, 1.0, 41)
    value = np.exp(12.0 * A)[:, None] * (1 + L)[None, :] * np.ones((1, 3))
    ds = xr.Dataset({"err": (("A", "L"), value, {"units": "1", "long_name": "error"}),
                     "status": (("A", "L"), np.zeros(value.shape, np.int8))},
                    coords={"A": ("A", A, {"units": "1", "spacing": "linear"}),
                            "L": ("L", L, {"units": "m", "spacing": "list"})},
                    attrs={"model": "x", "outputs": "err"})
    art = generic.heatmap(ds, "err", x="L", y="A")
    ax = art["mesh"].axes
    assert ax.get_xscale() == "log"
    np.testing.assert_allclose(ax.get_xlim(), [10**-1.5, 10**1.5])
    ds2 = xr.Dataset({"err": (("A", "L"), 1.0 / (1.02 - A)[:, None] * np.ones((1, 6)), {"units": "1"}),
                      "status": (("A", "L"), np.zeros((41, 6), np.int8))},
                     coords={"A": ("A", A, {"units": "1"}), "L": ("L", np.linspace(0.1, 10.0, 6), {"spacing": "list"})})
    art = generic.heatmap(ds2, "err", x="L", y="A")
    ax = art["mesh"].axes
    assert ax.get_xscale() == "linear"  # evenly spread: linear cells
    assert len(art["contours"].levels) >= 4  # 10, 20, 30, 40 at A = 0.92, 0.97, 0.987, 0.995
    to_axes = ax.transScale + ax.transLimits
    where = [to_axes.transform(t.get_position()) for t in art["contour_labels"]]
    assert 2 <= len(where) < len(art["contours"].levels)
    for i, a in enumerate(where):
        for b in where[i + 1:]:
            assert abs(a[0] - b[0]) >= generic.LABEL_GAP[0] or abs(a[1] - b[1]) >= generic.LABEL_GAP[1]


def test_a_stability_maps_legend_names_continued_curves_and_folds_too():
    """Besides the located points, a continued boundary and its fold get a legend entry (they were
    drawn without one)."""
    ds = _axes_of(cam(), "speed", "preload")
    n = ds.sizes["preload"]
    crossing = np.array([[30.0 + 10 * i, np.nan] for i in range(n)])
    bds = xr.Dataset(
        {"boundary": (("preload", "crossing"), crossing, {"units": "rad/s"}),
         "boundary_width": (("preload", "crossing"), np.full(crossing.shape, 1e-9), {"units": "rad/s"}),
         "curve_speed": (("curve", "point"), [[30.0, 40.0, 50.0]]),
         "curve_preload": (("curve", "point"), [[0.0, 10.0, 20.0]]),
         "fold_speed": (("fold",), [50.0]), "fold_preload": (("fold",), [20.0])},
        coords={"preload": ds["preload"].values, "crossing": [0, 1]},
        attrs={"mechsweep_kind": "boundaries", "model": "cam_follower", "along": "speed", "criterion": "floquet",
               "level": 1.0, "rtol": 1e-10, "continue_in": "preload"})
    art = figures.artists(ds, "stability_map", boundaries=bds)
    texts = [t.get_text().replace("\n", " ") for t in art["legend"].get_texts()]
    # one entry for the located points and the curves continued from them, one for the folds
    assert any(t.startswith("boundary where") and "located along $\\Omega$" in t and "continued between them" in t
               for t in texts)
    assert any(t.startswith("fold of a continued boundary") for t in texts)


def test_axes_chosen_by_the_user_replace_the_automatic_choice():
    """--x/--y: the stability map and heatmap with the axes swapped, a nomogram with one curve per
    name of a list axis; only the outputs over the given axes get figures, drawn from those axes."""
    ds = cam()
    swapped = {c.name: c for c in generic.choose(ds, x="speed", y="preload")}
    assert list(swapped) == ["stability_map", "heatmap_lift", "nomogram_lift"]
    assert all((c.x, c.y) == ("speed", "preload") for c in swapped.values())  # the automatic choice: x = preload
    art = swapped["stability_map"].draw(ds)
    mesh = art["panels"][0]["mesh"].get_array()
    assert art["axes"][0, 0].get_xlabel().startswith(label(ds["speed"])) and mesh.shape == (6, 30)
    by_name = {c.name: c for c in generic.choose(ds, x="preload", y="contact")}
    assert list(by_name) == ["nomogram_lift"] and by_name["nomogram_lift"].y == "contact"  # no map over names
    lines = figures.draw(ds, "nomogram_lift", axes=("preload", "contact")).axes[0].lines
    np.testing.assert_allclose(lines[1].get_ydata(), ds["lift"].isel(speed=0, contact=1).values)
    assert [c.name for c in generic.choose(_axes_of(ds, "speed"), x="speed")] == ["curve_lift", "curve_floquet"]


def test_an_axis_asked_for_as_y_gives_curves_however_many_values_it_has():
    """Without --y an axis of more than FAMILY_MAX values gives no family of curves; asked for, it
    does, thinned to at most MAX_CURVES curves (what docs/your-own-model.md promises)."""
    ds = cam(n_speed=30, contacts=("steel",))
    assert "nomogram_lift" not in [c.name for c in generic.choose(ds, x="preload")]
    chosen = {c.name: c for c in generic.choose(ds, x="preload", y="speed")}
    assert list(chosen) == ["stability_map", "heatmap_lift", "nomogram_lift"] and chosen["nomogram_lift"].y == "speed"
    lines = figures.draw(ds, "nomogram_lift", axes=("preload", "speed")).axes[0].lines
    assert 2 <= len(lines) <= generic.MAX_CURVES


@pytest.mark.parametrize("x,y,words,allowed", [
    ("contact", None, "--x contact: is not numeric", "speed, preload"),
    ("mass", None, "--x mass: is not an axis", "speed, preload"),
    ("Speed", None, "--x Speed: is not an axis of this dataset with more than one value (did you mean 'speed'?)",
     "speed, preload"),
    ("speed", "speed", "--y speed: the same axis as --x", "preload, contact"),
    (None, "t", "--y t: not an axis", "speed, preload, contact"),
])
def test_axes_that_cannot_be_drawn_are_refused_naming_the_allowed_ones(tmp_path, capsys, x, y, words, allowed):
    path = tmp_path / "cam.h5"
    cam(n_speed=12).to_netcdf(path, engine="h5netcdf")
    args = ["plot", str(path)] + (["--x", x] if x else []) + (["--y", y] if y else [])
    assert main(args) == 2
    err = capsys.readouterr().err
    assert words in err and err.rstrip().endswith(f"allowed: {allowed}"), err
    assert not list(tmp_path.glob("*.png"))


def test_plot_draws_the_generic_figures_on_the_axes_given(tmp_path, capsys):
    path = tmp_path / "cam.h5"
    cam(n_speed=12, contacts=("steel",)).to_netcdf(path, engine="h5netcdf")
    assert main(["plot", str(path), "--x", "preload", "--y", "speed", "--list"]) == 0
    assert "over preload and speed (log axis)" in capsys.readouterr().out.splitlines()[1]
    assert main(["plot", str(path), "--x", "speed", "--kind", "heatmap_lift", "-o", str(tmp_path / "h.png")]) == 0
    assert (tmp_path / "h.png").stat().st_size > 10_000


def test_a_time_history_of_one_point_is_drawn_for_any_model(tmp_path, capsys):
    """`mechsweep plot --point` on a model the package does not know: each output with one extra
    numeric dimension (a History) is drawn against it, titled with the point (before, nothing fitted
    and the plot was refused, though the help promised the point's time histories)."""
    ds = cam(n_speed=8, n_preload=6)
    ds["lift_history"].values[:] = np.arange(ds["lift_history"].size, dtype=float).reshape(ds["lift_history"].shape)
    path = tmp_path / "cam.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    assert main(["plot", str(path), "--point", "speed=10,preload=25,contact=bronze", "--list"]) == 0
    assert capsys.readouterr().out.startswith("history_lift_history: lift_history (lift over time [mm]) against t")
    assert main(["plot", str(path), "--point", "speed=10,preload=25,contact=bronze"]) == 0
    written = capsys.readouterr().out.split()[-1]
    assert written.endswith(".png") and Path(written).stat().st_size > 10_000
    from mechsweep.commands.plot import select_point
    one = select_point(ds, "speed=10,preload=25,contact=bronze")
    art = figures.draw(one, "history_lift_history")
    np.testing.assert_array_equal(art.axes[0].lines[0].get_ydata(), one["lift_history"].values.ravel())
    assert "at $\\Omega$ = " in art.figure._suptitle.get_text() and "contact = bronze" in art.figure._suptitle.get_text()


def test_a_point_without_time_histories_is_refused_saying_why(tmp_path, capsys):
    path = tmp_path / "cam.h5"
    ds = cam(n_speed=8).drop_vars("lift_history")
    ds.attrs["outputs"] = "lift floquet"
    ds.to_netcdf(path, engine="h5netcdf")
    assert main(["plot", str(path), "--point", "speed=10,preload=25,contact=bronze"]) == 2
    err = capsys.readouterr().err
    assert "--point speed=10,preload=25,contact=bronze: nothing to draw at one point" in err and "History" in err, err
    assert not list(tmp_path.glob("*.png"))


def _unsorted(ds, dim, order):
    """ds with the values of ``dim`` in the given order (a list axis a scene gave unsorted)."""
    out = ds.isel({dim: list(order)})
    out[dim].attrs["spacing"] = "list"
    return out


def test_plot_point_on_an_unsorted_list_axis_draws_the_point_asked_for(tmp_path, capsys):
    """`plot --point` on a list axis that is not sorted (e = [0.0, 0.03, -0.03]) was refused as a
    dataset 'not laid out as a mechsweep dataset (ValueError: index must be monotonic ...)': the
    nearest grid value is now found by position."""
    ds = _unsorted(cam(n_speed=8, n_preload=6), "preload", [0, 3, 1, 5, 2, 4])
    ds["lift_history"].values[:] = np.arange(ds["lift_history"].size, dtype=float).reshape(ds["lift_history"].shape)
    path = tmp_path / "cam.h5"
    ds.to_netcdf(path, engine="h5netcdf")
    assert main(["plot", str(path), "--point", "speed=10,preload=29,contact=bronze"]) == 0, capsys.readouterr().err
    from mechsweep.commands.plot import select_point
    one = select_point(ds, "speed=10,preload=29,contact=bronze")
    assert float(one["preload"].values[0]) == 30.0
    expected = ds["lift_history"].sel(preload=30.0, contact="bronze").isel(speed=[int(np.argmin(abs(ds.speed.values - 10)))])
    np.testing.assert_array_equal(one["lift_history"].values.ravel(), expected.values.ravel())


def test_maps_of_an_unsorted_axis_draw_each_cell_at_its_value():
    """A stability map (and a heatmap) over a list axis given unsorted draws the same cells as over
    the sorted axis (pcolormesh was given the values in the file's order)."""
    ds = cam(n_speed=8, n_preload=6)
    shuffled = _unsorted(ds, "preload", [0, 3, 1, 5, 2, 4])
    for kind in ("stability_map", "heatmap_lift"):
        a = figures.artists(ds, kind)["axes"][0, 0].collections[0].get_array()
        b = figures.artists(shuffled, kind)["axes"][0, 0].collections[0].get_array()
        np.testing.assert_array_equal(np.ma.filled(a, -1.0), np.ma.filled(b, -1.0))


def test_a_bug_while_drawing_is_not_blamed_on_the_dataset(tmp_path, capsys, monkeypatch):
    """An exception raised while drawing a dataset that passed the layout checks is mechsweep's bug:
    it goes on with a note saying so (a traceback, exit 1), not 'not laid out as a mechsweep
    dataset' (exit 2), which every ValueError of the drawing code was said as; a file whose grid
    values are not finite and distinct is still said to be badly laid out."""
    path = tmp_path / "cam.h5"
    cam(n_speed=8).to_netcdf(path, engine="h5netcdf")

    def broken(*args, **kwargs):
        raise ValueError("a drawing bug")

    monkeypatch.setattr(generic, "heatmap", broken)
    with pytest.raises(ValueError, match="a drawing bug") as raised:
        main(["plot", str(path), "--kind", "heatmap_lift", "-o", str(tmp_path / "h.png")])
    notes = " ".join(getattr(raised.value, "__notes__", []))
    assert "internal error while drawing the figures of" in notes and "not a problem of the dataset" in notes
    assert "not laid out" not in capsys.readouterr().err
    monkeypatch.undo()
    bad = cam(n_speed=8)
    bad = bad.assign_coords(preload=("preload", np.array([0.0, 10.0, 10.0, 30.0, 40.0, 50.0]), bad.preload.attrs))
    bad.to_netcdf(tmp_path / "bad.h5", engine="h5netcdf")
    assert main(["plot", str(tmp_path / "bad.h5"), "-o", str(tmp_path / "b.png")]) == 2
    assert "not laid out as a mechsweep dataset (ValueError: the values of the grid dimension 'preload' are not " \
           "finite and distinct)" in capsys.readouterr().err
