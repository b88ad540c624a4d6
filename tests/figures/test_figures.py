"""Figures draw from stored datasets and label every axis with its unit."""
import numpy as np
import pytest

import mechsweep
from mechsweep import figures
from mechsweep.figures._style import units_text

from tests.conftest import REPO


@pytest.fixture(scope="module")
def datasets(tmp_path_factory):
    out = tmp_path_factory.mktemp("fig")
    small = {
        "quickstart": {"axes": {"A": {"start": 0.1, "stop": 1.0, "num": 4},
                                "mu": {"start": 0.1, "stop": 10.0, "num": 5, "spacing": "log"}}},
        "torsional_circuit_nomogram": {"axes": {"spring": ["tension", "compression"],
                                                "s0_over_r": [0.0, 0.1],
                                                "lambda2": {"start": 0.0, "stop": 2.0, "num": 11}}},
        "torsional_circuit_truncation": {"axes": {"lambda2": {"start": 0.3, "stop": 2.0, "num": 4},
                                                  "A": {"start": 0.05, "stop": 1.0, "num": 5}}},
        "fourbar_methods": {},
        "fourbar_geometry_family": {"axes": {"a2": {"start": 0.2, "stop": 0.8, "num": 12},
                                             "a3": {"start": 0.15, "stop": 0.6, "num": 10}}},
        "fourbar_pareto": {"axes": {"cw1_mr": {"start": 0.0, "stop": 0.4, "num": 5},
                                    "cw1_angle": {"start": 2.0, "stop": 4.2, "num": 4},
                                    "cw3_mr": {"start": 0.0, "stop": 0.4, "num": 3}}},
        "slidercrank_partial": {"axes": {"k": {"start": 0.0, "stop": 1.0, "num": 6}, "lambda": [0.2, 0.4]}},
        "autobalancer_damping": {"axes": {"Omega": {"start": 10.0, "stop": 60.0, "num": 6},
                                          "zeta_xi": {"start": 0.01, "stop": 0.3, "num": 3, "spacing": "log"}}},
        "autobalancer_residual": {"axes": {"Omega": [30.0, 55.0], "A0": [0.1, 0.3]},
                                  "fixed": {**__import__("tomllib").loads(
                                      (REPO / "sweeps" / "autobalancer_residual.toml").read_text())["fixed"], "A1": 0.0},
                                  "solver": {"rtol": 1e-7, "atol": 1e-9, "horizon_revolutions": 60,
                                             "trajectory_samples": 50}},
    }
    result = {}
    for name, override in small.items():
        data = __import__("tomllib").loads((REPO / "sweeps" / f"{name}.toml").read_text())
        data.update(override)
        result[name] = mechsweep.run(data, output=out / f"{name}.h5", progress=False)
    return result


@pytest.mark.parametrize("name,kinds", [
    ("quickstart", {"amplitude_period", "kinematic_coefficients"}),
    ("torsional_circuit_nomogram", {"coefficients"}),
    ("torsional_circuit_truncation", {"truncation_error"}),
    ("autobalancer_damping", {"stability_chart"}),
    ("autobalancer_residual", {"residual"}),
    ("fourbar_methods", {"moment_methods"}),
    ("fourbar_geometry_family", {"balancing_map"}),
    ("fourbar_pareto", {"pareto"}),
    ("slidercrank_partial", {"slider_residual"}),
])
def test_each_dataset_gets_its_figures(datasets, name, kinds):
    assert kinds <= set(figures.available(datasets[name]))


@pytest.mark.parametrize("name", ["quickstart", "torsional_circuit_nomogram", "torsional_circuit_truncation",
                                  "autobalancer_damping", "autobalancer_residual", "fourbar_methods",
                                  "fourbar_geometry_family", "fourbar_pareto", "slidercrank_partial"])
def test_axes_are_labelled_with_units(datasets, name):
    """Every axis has labels; a label naming a dimensional variable carries its [unit]. Also for
    the generic figures drawn on request (outputs the model's own figures do not show)."""
    ds = datasets[name]
    variables = [ds[v] for v in list(ds.coords) + list(ds.data_vars)]
    for kind in list(figures.available(ds)) + list(figures.on_request(ds)):
        fig = figures.draw(ds, kind)
        for ax in fig.axes:
            if ax.get_label() == "<colorbar>":
                continue
            for text in (ax.get_xlabel(), ax.get_ylabel()):
                flat = text.replace("\n", " ")
                assert flat, (kind, ax)
                for var in variables:
                    unit = var.attrs.get("units", "")
                    if var.attrs.get("long_name", "@") in flat and units_text(unit):
                        assert f"[{units_text(unit)}]" in flat.replace("\u00a0", " "), (kind, flat, unit)


def test_figures_do_not_draw_flagged_points(datasets):
    ds = datasets["quickstart"].copy(deep=True)
    ds["status"].values[0, 0] = 4  # pretend one point was flagged infeasible
    art = figures.artists(ds, "amplitude_period")
    drawn = art["integrated"].get_xdata()  # integrated markers: only finite values are picked to draw
    assert drawn.size == int(np.isfinite(figures._style.ok_values(ds, "period").values).sum())
    texts = [t.get_text() for t in art.figure.axes[0].texts]
    assert any("not drawn: 1 infeasible" in t for t in texts)  # how many, and why (the status meaning)


def test_save_writes_files(datasets, tmp_path):
    written = figures.save(datasets["torsional_circuit_nomogram"], tmp_path / "nomo.png")
    assert [p.name for p in written] == ["nomo.png"] and written[0].stat().st_size > 20_000


@pytest.mark.parametrize("name,kind,axes", [("quickstart", "amplitude_period", None),
                                            ("quickstart", "kinematic_coefficients", None),
                                            ("autobalancer_damping", "stability_chart", None),
                                            ("quickstart", None, ("A", "mu"))])
def test_save_writes_matplotlibs_png_byte_for_byte_drawing_the_figure_once(datasets, tmp_path, monkeypatch, name,
                                                                          kind, axes):
    """figures.save (and so `mechsweep plot`) writes the file matplotlib's savefig writes of the same figure,
    byte for byte (pixels and metadata), but draws the figure once: matplotlib's savefig of a figure
    with a layout engine draws it twice, once with drawing turned off to lay it out (figures.savefig).
    The figure is left with its canvas, resolution and layout engine (a stability map with hatching,
    a generic heatmap with its colourbar among them)."""
    from matplotlib.figure import Figure

    ds = datasets[name]
    kind = kind or next(iter(figures.available(ds, axes)))
    figures.draw(ds, kind, axes=axes).savefig(tmp_path / "theirs.png", format="png", dpi=150)
    draws, draw = [], Figure.draw
    monkeypatch.setattr(Figure, "draw", lambda self, renderer: (draws.append(self), draw(self, renderer))[1])
    assert figures.save(ds, tmp_path / "ours.png", kind=kind, axes=axes) == [tmp_path / "ours.png"]
    assert (tmp_path / "ours.png").read_bytes() == (tmp_path / "theirs.png").read_bytes()
    assert len(draws) == 1
    fig = draws[0]
    assert type(fig.canvas).__name__ == "FigureCanvasBase" and fig.dpi == Figure().dpi
    assert type(fig.get_layout_engine()).__name__ == "ConstrainedLayoutEngine"


def test_time_history_of_one_point_via_the_cli(datasets, tmp_path, capsys):
    from mechsweep.cli import main

    data = __import__("tomllib").loads((REPO / "sweeps" / "autobalancer_residual.toml").read_text())
    data["scene"]["outputs"] = ["xi_history", "eta_history", "phase_error1_history", "phase_error2_history"]
    data["axes"] = {"Omega": [30.0, 55.0]}
    data["fixed"]["A0"] = 0.1
    data["fixed"]["A1"] = 0.0
    data["solver"].update(horizon_revolutions=20, trajectory_samples=40, rtol=1e-7, atol=1e-9)
    mechsweep.run(data, output=tmp_path / "h.h5", progress=False)
    assert main(["plot", str(tmp_path / "h.h5"), "--point", "Omega=54", "-o", str(tmp_path / "h.png")]) == 0
    assert "h_time_history.png" in capsys.readouterr().out or (tmp_path / "h.png").exists()
    assert main(["plot", str(tmp_path / "h.h5"), "--point", "Omeg=54"]) == 2
    assert "grid dimensions Omega" in capsys.readouterr().err


# ----------------------------------------------------------------------------- located boundaries on the charts
@pytest.fixture(scope="module")
def located(datasets, tmp_path_factory):
    """Tiny `mechsweep boundaries` runs on two of the small datasets above: the torsional
    free-length limit along lambda2, and the auto-balancer's floquet_max = 1 along Omega continued
    in zeta_xi. Returns {name: (grid path, grid dataset, boundaries dataset)}."""
    import tomllib

    from mechsweep.boundaries import run_boundaries
    from mechsweep.scene import load_scene

    out = tmp_path_factory.mktemp("bnd")
    specs = {
        "torsional_circuit_nomogram": ({"axes": {"spring": ["tension"], "s0_over_r": [0.2, 0.4, 0.8],
                                                 "lambda2": {"start": 0.0, "stop": 2.0, "num": 11}}},
                                       {"along": "lambda2", "status_change": ["infeasible", "ok"]}),
        "autobalancer_damping": ({"axes": {"Omega": {"start": 40.0, "stop": 60.0, "num": 5},
                                           "zeta_xi": {"start": 0.01, "stop": 0.3, "num": 3, "spacing": "log"}}},
                                 {"along": "Omega", "criterion": "floquet_max", "level": 1.0, "rtol": 1e-8,
                                  "continue_in": "zeta_xi"}),
    }
    result = {}
    for name, (override, section) in specs.items():
        data = tomllib.loads((REPO / "sweeps" / f"{name}.toml").read_text())
        data.update(override)
        data["boundaries"] = section
        data["storage"] = {"path": str(out / f"{name}.h5")}
        path, bds = run_boundaries(load_scene(data))
        result[name] = (out / f"{name}.h5", mechsweep.open_dataset(out / f"{name}.h5"), bds)
    return result


def _dotted_vlines(fig):
    return sorted({round(float(line.get_xdata()[0]), 12) for ax in fig.axes for line in ax.lines
                   if line.get_linestyle() == ":" and len(set(line.get_xdata())) == 1})


def test_nomogram_marks_the_located_free_length_limit_only_when_given(located):
    path, ds, bds = located["torsional_circuit_nomogram"]
    want = np.asarray(bds["boundary"].values, dtype=float)
    want = sorted(round(float(x), 12) for x in want[np.isfinite(want)])
    assert len(want) >= 2  # S0/R = 0.4 and 0.8 are infeasible at small lambda2
    assert _dotted_vlines(figures.draw(ds, "coefficients", boundaries=bds)) == want
    assert _dotted_vlines(figures.draw(ds, "coefficients")) == []


def test_stability_chart_draws_located_and_continued_boundaries_only_when_given(located):
    path, ds, bds = located["autobalancer_damping"]
    scale = float(ds["omega_xi"])
    x = np.asarray(bds["boundary"].values, dtype=float)
    assert np.isfinite(x).any() and "curve_Omega" in bds
    fig = figures.draw(ds, "stability_chart", boundaries=bds)
    ax = fig.axes[0]
    pts = np.vstack([c.get_offsets() for c in ax.collections if "located along $\\Omega$" in c.get_label()])
    np.testing.assert_allclose(np.sort(pts[:, 0]), np.sort(x[np.isfinite(x)] / scale), rtol=1e-12)
    curves = [line for line in ax.lines if "continued in ($\\Omega$, $\\zeta_\\xi$)" in line.get_label()]
    assert curves
    cx = np.asarray(bds["curve_Omega"].isel(curve=0).values, dtype=float)
    np.testing.assert_allclose(curves[0].get_xdata(), cx[np.isfinite(cx)] / scale, rtol=1e-12)
    legend = [t.get_text().replace("\n", " ") for t in ax.get_legend().get_texts()]
    assert any("interpolated on the grid" in t for t in legend)
    assert any("located along $\\Omega$" in t and "rtol 1e-08" in t for t in legend)
    bare = figures.draw(ds, "stability_chart").axes[0]
    assert not any("located" in c.get_label() for c in bare.collections)
    assert not any("continued" in line.get_label() for line in bare.lines)


def test_plot_finds_the_sibling_boundaries_and_refuses_a_foreign_one(located, tmp_path, capsys, monkeypatch):
    from mechsweep.cli import main

    path, ds, bds = located["autobalancer_damping"]
    seen = []
    real = figures.save
    monkeypatch.setattr(figures, "save", lambda *a, **k: seen.append(k.get("boundaries")) or real(*a, **k))
    assert main(["plot", str(path), "-o", str(tmp_path / "a.png")]) == 0
    assert seen[-1] is not None and seen[-1].attrs["along"] == "Omega"  # DATA.boundaries.h5 beside it
    assert main(["plot", str(path), "--no-boundaries", "-o", str(tmp_path / "b.png")]) == 0
    assert seen[-1] is None
    foreign = located["torsional_circuit_nomogram"][0].with_name("torsional_circuit_nomogram.boundaries.h5")
    capsys.readouterr()
    assert main(["plot", str(path), "--boundaries", str(foreign), "-o", str(tmp_path / "c.png")]) == 2
    assert "not located on the grid" in capsys.readouterr().err and not (tmp_path / "c.png").exists()


def test_info_and_plot_of_a_boundaries_dataset(located, tmp_path, capsys):
    from mechsweep.cli import main

    path = located["torsional_circuit_nomogram"][0].with_name("torsional_circuit_nomogram.boundaries.h5")
    bds = located["torsional_circuit_nomogram"][2]
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert f"located: {bds.attrs['located']} boundaries" in out and "status infeasible -> ok" in out
    assert "accuracy bound met: parameter" in out and "evaluations:" in out
    assert main(["plot", str(path), "--list"]) == 0
    assert capsys.readouterr().out.startswith("boundaries:")
    assert main(["plot", str(path), "-o", str(tmp_path / "b.png")]) == 0
    fig = figures.draw(bds, "boundaries")
    drawn = np.vstack([c.get_offsets() for c in fig.axes[0].collections])
    x = np.asarray(bds["boundary"].values, dtype=float)
    np.testing.assert_allclose(np.sort(drawn[:, 0]), np.sort(x[np.isfinite(x)]), rtol=1e-12)


def test_an_island_too_small_to_see_is_drawn_magnified(tmp_path):
    """The damping chart's island (Omega in [27.632, 27.851] rad/s, zeta_xi in [0.02154, 0.02861])
    on a wide, coarse chart: its continued outline is drawn magnified in a panel beside the chart
    (not inside it, where it hid data); the chart without boundaries has none."""
    import tomllib

    from mechsweep.boundaries import run_boundaries
    from mechsweep.scene import load_scene

    d = tomllib.loads((REPO / "sweeps" / "autobalancer_damping.toml").read_text())
    d["scene"]["outputs"] = ["floquet_max", "stable_floquet"]
    d["axes"] = {"Omega": [27.0, 27.7, 27.75, 28.4, 40.0], "zeta_xi": [0.001, 0.025, 0.5]}
    d["boundaries"]["rtol"] = 1e-6
    d["storage"] = {"path": str(tmp_path / "wide.h5")}
    _, bds = run_boundaries(load_scene(d))
    ds = mechsweep.open_dataset(tmp_path / "wide.h5")
    art = figures.artists(ds, "stability_chart", boundaries=bds)
    inset = art["inset"]  # a panel beside the chart (inside it, it hid data)
    assert inset in art.figure.axes and inset is not art["axes"][0, 0]
    assert not (inset.get_position().overlaps(art["axes"][0, 0].get_position()))
    (x0, x1), (y0, y1) = inset.get_xlim(), inset.get_ylim()
    scale = float(ds["omega_xi"])
    assert x0 < 27.632 / scale and 27.851 / scale < x1 and x1 - x0 < 0.02  # the island, magnified
    assert y0 < 0.02154 and 0.02861 < y1 and y1 - y0 < 0.01
    assert any("continued" in line.get_label() for line in inset.lines)
    assert "inset" not in figures.artists(ds, "stability_chart")


# ----------------------------------------------------------------------------- fig= / ax= and returned artists
MODEL_FIGURES = [("quickstart", "amplitude_period"), ("quickstart", "kinematic_coefficients"),
                 ("torsional_circuit_nomogram", "coefficients"), ("torsional_circuit_truncation", "truncation_error"),
                 ("autobalancer_damping", "stability_chart"), ("autobalancer_residual", "residual"),
                 ("fourbar_methods", "moment_methods"), ("fourbar_geometry_family", "balancing_map"),
                 ("fourbar_pareto", "pareto"), ("slidercrank_partial", "slider_residual")]


@pytest.mark.parametrize("name,kind", MODEL_FIGURES)
def test_every_figure_draws_into_the_users_subfigure_or_axes_and_returns_its_artists(datasets, name, kind):
    from matplotlib.artist import Artist
    from matplotlib.figure import Figure

    ds = datasets[name]
    # fig=: a SubFigure of the user's layout; the user's other subfigure is left alone
    user = Figure(figsize=(16, 10))
    mine, theirs = user.subfigures(1, 2)
    keep = theirs.subplots()
    art = figures.artists(ds, kind, fig=mine)
    assert art.figure is mine and art["axes"].size >= 1
    assert all(a in mine.axes for a in art["axes"].ravel()) and theirs.axes == [keep]
    def flat(v):
        if isinstance(v, dict):
            return [x for w in v.values() for x in flat(w)]
        if isinstance(v, (list, tuple)):
            return [x for w in v for x in flat(w)]
        return [v] if isinstance(v, Artist) and v is not mine else []

    drawn = flat({k: v for k, v in art.items() if k not in ("figure", "axes")})
    assert drawn and all(a.get_figure(root=False) is mine for a in drawn)
    # ax=: exactly the user's Axes, one per panel, and no title or caption set on the user's figure
    n = art["axes"].size
    user2 = Figure(figsize=(8, 4 * n))
    given = list(user2.subplots(n, 1, squeeze=False).ravel())
    art2 = figures.artists(ds, kind, ax=given if n > 1 else given[0])
    assert list(art2["axes"].ravel()) == given and art2.figure is user2
    assert user2._suptitle is None and user2._supxlabel is None
    assert any(a.has_data() for a in given)
    with pytest.raises(ValueError, match=f"this figure draws {n} panel"):
        figures.artists(ds, kind, ax=list(Figure().subplots(1, n + 1).ravel()))


def test_units_render_from_udunits_strings():
    assert units_text("rad s-1") == "rad s$^{-1}$"
    assert units_text("kg m2") == "kg m$^{2}$"
    assert units_text("kg m^2") == "kg m$^{2}$"
    assert units_text("rad-2 s-2") == "rad$^{-2}$ s$^{-2}$"
    assert units_text("N m s rad-1") == "N m s rad$^{-1}$"
    assert units_text("1") == units_text("") == units_text("-") == ""
    assert units_text("1/(rad^2 s^2)") == "1/(rad^2 s^2)"  # not token by token: kept as written
    assert units_text("%") == "%"


def test_labels_never_wrap_inside_parentheses_and_show_units():
    import xarray as xr

    from mechsweep.figures._style import label

    da = xr.DataArray([1.0], dims="x", name="kv", attrs={
        "long_name": "velocity coefficient v_max T / A (2 pi when linear)", "units": "1"})
    text = label(da, width=30)
    assert all(line.count("(") == line.count(")") for line in text.split("\n")), text
    da.attrs["units"] = "rad s-1"
    assert label(da, width=200).endswith("[rad\u00a0s$^{-1}$]")


def test_a_bracketed_part_longer_than_a_line_wraps_and_short_ones_inside_it_stay_whole():
    """A long name whose parenthesis cannot fit on one line (a Floquet verdict's) was kept whole and
    ran off the figure; now only the parts that fit a line stay unbroken."""
    from mechsweep.figures._style import wrap

    text = ("1 if mu < 1 - margin, 0 if > 1 + margin (margin = max(floquet_margin, 100 rtol); NaN and "
            "status undecided within it)")
    lines = wrap(text, 34).split("\n")
    assert all(len(line) <= 34 for line in lines), lines
    assert any("max(floquet_margin, 100 rtol)" in line for line in lines)  # the inner part: whole


def _wp(names):
    import xarray as xr

    rtol = np.array([1e-4, 1e-6, 1e-8])
    t = np.array([[1e-5, 2e-5, 4e-5]] * len(names))
    return xr.Dataset(
        {"time_per_point": (("integrator", "rtol"), t * np.arange(1, len(names) + 1)[:, None],
                            {"units": "s", "long_name": "time per point"}),
         "error_max": (("integrator", "rtol"), np.tile(rtol, (len(names), 1)), {"units": "1"})},
        coords={"integrator": list(names), "rtol": rtol},
        attrs={"mechsweep_kind": "workprecision", "model": "m", "norm": "relative error", "scipy_points": 4,
               "reference": "r", "points": 4, "scene": "s.toml"})


def test_a_methods_colour_is_the_same_in_every_work_precision_figure():
    from matplotlib.colors import to_hex

    from mechsweep.figures import workprecision as wp

    one = figures.artists(_wp(["mechsweep dop853", "mechsweep radau", "scipy DOP853"]), "workprecision")
    two = figures.artists(_wp(["scipy LSODA", "scipy DOP853", "mechsweep auto", "mechsweep dop853",
                               "numbalsoda rk_new"]), "workprecision")
    c1 = {k: to_hex(v.get_color()) for k, v in one["lines"].items()}
    c2 = {k: to_hex(v.get_color()) for k, v in two["lines"].items()}
    assert c1["scipy DOP853"] == c2["scipy DOP853"] == c1["mechsweep dop853"] == c2["mechsweep dop853"]
    assert c1["mechsweep radau"] != c1["mechsweep dop853"]
    assert len(set(c2.values())) == len({wp.method_key(k) for k in c2}) == 4  # one colour per method
    assert wp.method_color("numbalsoda rk_new") == wp.method_color("diffrax rk_new")  # an unknown method too


def test_what_an_engineer_reads_off_each_figure_is_there(datasets):
    """Issue 16 items 8-11, one check each: the closed form drawn over the markers and the rtol
    inside the error panel's range; natural frequencies as top ticks (not lines on the P = 0
    curves) and the first approximation's boundary ticked on its stable side; one legend entry per drawn curve;
    every Pareto-optimal design drawn; no map drawn twice; the textbook band shaded."""
    from mechsweep.balancing import pareto_front

    art = figures.artists(datasets["quickstart"], "amplitude_period")
    assert art["closed_form"].get_zorder() > art["integrated"].get_zorder()
    lo, hi = art["axes"][1, 0].get_ylim()
    assert lo < datasets["quickstart"].attrs["solver_rtol"] < hi and hi / lo < 1e9
    ds = datasets["autobalancer_damping"]
    art = figures.artists(ds, "stability_chart")
    top = art["frequencies"]
    assert [t.get_text() for t in top.get_xticklabels()] and not any("ω" in str(line.get_label())
                                                                     for line in art["axes"][0, 0].lines)
    # the first approximation's boundary, ticked on the side it calls stable
    assert art["P_ticks"] and "ticked on the side it calls stable" in " ".join(
        t.get_text().replace("\n", " ") for t in art["legend"].get_texts())
    art = figures.artists(datasets["autobalancer_residual"], "residual")
    assert len(art["legend"].get_texts()) == len({lab for _, lab in art["lines"]})
    ds = datasets["fourbar_pareto"]
    F = np.stack([ds[n].where(ds["status"] == 0).values.ravel() for n in ("Fx_range", "Fy_range", "M_range",
                                                                          "T_range")], axis=1)
    assert len(figures.artists(ds, "pareto")["front"].get_segments()) == int(pareto_front(F).sum())
    panels = figures.artists(datasets["fourbar_geometry_family"], "balancing_map")["panels"]
    meshes = [np.ma.filled(p["mesh"].get_array(), np.nan) for p in panels.values()]
    assert not any(np.array_equal(a, b, equal_nan=True) for i, a in enumerate(meshes) for b in meshes[:i])
    band = figures.artists(datasets["slidercrank_partial"], "slider_residual")["textbook"]
    np.testing.assert_allclose([band.get_x(), band.get_x() + band.get_width()], [1 / 3, 1 / 2])
