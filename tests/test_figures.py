"""Figures draw from stored datasets and label every axis with its unit."""
import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import mechsweep  # noqa: E402
from mechsweep import figures  # noqa: E402

from .conftest import REPO  # noqa: E402


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
                    if var.attrs.get("long_name", "@") in flat and unit not in ("", "1"):
                        assert f"[{unit}]" in flat, (kind, flat, unit)


def test_figures_do_not_draw_flagged_points(datasets):
    ds = datasets["quickstart"].copy(deep=True)
    ds["status"].values[0, 0] = 4  # pretend one point was flagged infeasible
    fig = figures.draw(ds, "amplitude_period")
    drawn = fig.axes[0].lines[1].get_ydata()  # integrated markers
    assert np.isnan(drawn).sum() >= 1
    texts = [t.get_text() for t in fig.axes[0].texts]
    assert any("1 flagged point" in t for t in texts)


def test_save_writes_files(datasets, tmp_path):
    written = figures.save(datasets["torsional_circuit_nomogram"], tmp_path / "nomo.png")
    assert [p.name for p in written] == ["nomo.png"] and written[0].stat().st_size > 20_000


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
    pts = np.vstack([c.get_offsets() for c in ax.collections if "located along Omega" in c.get_label()])
    np.testing.assert_allclose(np.sort(pts[:, 0]), np.sort(x[np.isfinite(x)] / scale), rtol=1e-12)
    curves = [line for line in ax.lines if "continued in (Omega, zeta_xi)" in line.get_label()]
    assert curves
    cx = np.asarray(bds["curve_Omega"].isel(curve=0).values, dtype=float)
    np.testing.assert_allclose(curves[0].get_xdata(), cx[np.isfinite(cx)] / scale, rtol=1e-12)
    legend = [t.get_text().replace("\n", " ") for t in ax.get_legend().get_texts()]
    assert any("contour of the grid" in t for t in legend)
    assert any("located along Omega" in t and "rtol 1e-08" in t for t in legend)
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
    on a wide, coarse chart: its continued outline is drawn in an inset zoomed on it; the chart
    without boundaries has no inset."""
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
    ax = figures.draw(ds, "stability_chart", boundaries=bds).axes[0]
    assert len(ax.child_axes) == 1
    inset = ax.child_axes[0]
    (x0, x1), (y0, y1) = inset.get_xlim(), inset.get_ylim()
    scale = float(ds["omega_xi"])
    assert x0 < 27.632 / scale and 27.851 / scale < x1 and x1 - x0 < 0.02  # the island, magnified
    assert y0 < 0.02154 and 0.02861 < y1 and y1 - y0 < 0.01
    assert any("continued" in line.get_label() for line in inset.lines)
    assert not figures.draw(ds, "stability_chart").axes[0].child_axes
