"""CF conventions of the datasets mechsweep writes.

The CF checker itself runs in tests/test_cf_checker.py. Checked here, on files written by `run`
and `boundaries`: every unit is parsed by UDUNITS-2 itself (cf-units ships the library and its
unit database in its wheel), strings carry no units, the global attributes CF asks for
(Conventions, source, history, references), the status flags (flag_values / flag_meanings, the
standard name status_flag, named by every output's ancillary_variables), the `coordinates`
attribute, and the log-spaced axis marking."""
import numpy as np
import pytest
import xarray as xr

cf_units = pytest.importorskip("cf_units")

import mechsweep  # noqa: E402
from mechsweep import cf  # noqa: E402
from mechsweep.boundaries import run_boundaries  # noqa: E402
from mechsweep.model import user  # noqa: E402
from mechsweep.models import MODELS  # noqa: E402
from mechsweep.execution.runner import run  # noqa: E402

from .conftest import SWEEPS  # noqa: E402


def declared_units(spec):
    for p in spec.params:
        yield f"{spec.name}.{p.name}", p.unit
    for o in spec.outputs:
        yield f"{spec.name}.{o.name}", o.unit
        for d in o.extra_dims:
            yield f"{spec.name}.{o.name}.{d.name}", d.unit
    for s in spec.settings:
        yield f"{spec.name}.solver.{s.name}", s.unit


def udunits_problem(unit) -> str | None:
    """Why ``unit`` is not a CF unit string (UDUNITS-2 grammar, written the CF way), or None."""
    if not isinstance(unit, str) or not unit.strip():
        return f"{unit!r} is empty (CF: '1' for dimensionless)"
    if unit.strip() == "-" or "/" in unit or "^" in unit or "**" in unit:
        return f"{unit!r} is not written the CF way ('kg m2', 'rad s-1', 'rad-2 s-2')"
    try:
        parsed = cf_units.Unit(unit)
    except ValueError as exc:
        return f"{unit!r} is not a UDUNITS-2 unit: {exc}"
    if parsed.is_unknown() or parsed.is_no_unit():
        return f"{unit!r} is not a physical unit"
    return None


def all_specs():
    shipped = user.resolve(str(SWEEPS / "models" / "vibrating_pendulum.py") + ":VIBRATING_PENDULUM")
    return [*MODELS.values(), shipped]


@pytest.mark.parametrize("spec", all_specs(), ids=lambda s: s.name)
def test_every_declared_unit_is_a_udunits_string(spec):
    bad = {where: udunits_problem(u) for where, u in declared_units(spec) if udunits_problem(u)}
    assert not bad, bad


def test_the_unit_check_rejects_what_the_declarations_used_to_say():
    for old in ("kg m^2", "1/(rad^2 s^2)", "-", "", "rad/s", "no_such_unit"):
        assert udunits_problem(old), old
    for new in ("kg m2", "rad-2 s-2", "1", "rad s-1", "N m s rad-1", "%"):
        assert udunits_problem(new) is None, new


def check_cf_file(path, model) -> None:
    """The CF checks a written file must pass (read raw: no decoding)."""
    ds = xr.open_dataset(path, engine="h5netcdf", decode_cf=False)
    try:
        assert ds.attrs["Conventions"] == cf.CONVENTIONS == "CF-1.8"
        assert ds.attrs["source"] == cf.source(model, mechsweep.__version__), ds.attrs["source"]
        history = ds.attrs["history"]
        assert history.startswith(ds.attrs["created"]) and "mechsweep " in history, history
        refs = ds.attrs["references"]
        assert refs == cf.references(model) and refs.strip(), refs
        for name, var in ds.variables.items():
            if var.dtype.kind in "fiu" and "flag_values" not in var.attrs:  # CF: flags need no units
                assert "units" in var.attrs, f"{path}: {name} has no units"
                assert udunits_problem(var.attrs["units"]) is None, (name, udunits_problem(var.attrs["units"]))
            if "flag_values" in var.attrs and name == "status":
                assert var.attrs["standard_name"] == "status_flag", var.attrs
            if "flag_values" in var.attrs:
                values = np.atleast_1d(var.attrs["flag_values"])
                meanings = str(var.attrs["flag_meanings"]).split()
                assert len(values) == len(meanings) and len(set(meanings)) == len(meanings), name
                assert values.dtype == var.dtype, (name, values.dtype, var.dtype)
            if var.dtype.kind in "SOU":  # categorical values: strings have no units (CF), stored as characters
                assert "units" not in var.attrs and var.dtype == "S1", (name, var.attrs, var.dtype)
            if name in ds.attrs.get("outputs", "").split():
                assert var.attrs["ancillary_variables"] == "status", name
            for other in str(var.attrs.get("coordinates", "")).split():
                assert other in ds.variables, (name, other)
        for dim in ds.dims:
            if dim in ds.variables and ds[dim].attrs.get("spacing") == "log":
                assert "xscale=\"log\"" in ds[dim].attrs["comment"], dim
                v = np.asarray(ds[dim].values, dtype=float)
                np.testing.assert_allclose(v[1:] / v[:-1], v[1] / v[0], rtol=1e-9)  # really log-spaced
    finally:
        ds.close()


@pytest.mark.parametrize("model, outputs, axes, fixed", [
    ("duffing", ["period", "period_exact", "kv"],
     {"A": {"start": 0.1, "stop": 1.0, "num": 3}, "mu": {"start": 1e-2, "stop": 1e2, "num": 5, "spacing": "log"}},
     {"omega": 2.0}),
    ("torsional_circuit", ["chi", "xi", "mu", "omega2"],
     {"lambda2": {"start": 0.1, "stop": 2.0, "num": 4}, "spring": ["tension", "compression"]},
     {"lambda1": 0.8, "s0_over_r": 0.2, "R": 0.05, "c": 2000.0, "I": 1e-3}),
])
def test_written_datasets_follow_cf(in_tmp, model, outputs, axes, fixed):
    scene = {"scene": {"name": "cf", "model": model, "outputs": outputs}, "axes": axes, "fixed": fixed}
    run(scene, output="cf.h5", progress=False)
    check_cf_file("cf.h5", MODELS[model])
    if "mu" in axes:  # the documented way to draw a log-spaced axis with xarray (docs/datasets.md)
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        ds = xr.open_dataset("cf.h5", engine="h5netcdf")
        lines = ds["period"].plot(x="mu", hue="A", xscale="log")
        assert lines[0].axes.get_xscale() == "log" and ds["mu"].attrs["spacing"] == "log"
        plt.close("all")
        ds.close()


def test_boundaries_dataset_follows_cf(in_tmp):
    scene = {"scene": {"name": "sep", "model": "duffing", "outputs": ["period_exact"]},
             "axes": {"A": {"start": 0.1, "stop": 3.0, "num": 12}, "mu": [-0.5, -1.3]}, "fixed": {"omega": 2.0},
             "boundaries": {"along": "A", "status_change": ["ok", "not_oscillatory"]},
             "storage": {"path": "sep.h5"}}
    path, _ = run_boundaries(scene, output="sep.boundaries.h5")
    check_cf_file(path, MODELS["duffing"])


def test_history_names_the_command_line(monkeypatch):
    token = cf.CLI_ARGS.set(("run", "my scene.toml", "-o", "x.h5"))  # as cli.main sets it while it runs
    try:
        assert cf.history("2026-01-01T00:00:00+00:00", "mechsweep.run(scene 'x')", "9.9") == \
            "2026-01-01T00:00:00+00:00: mechsweep run 'my scene.toml' -o x.h5 (mechsweep 9.9)"
    finally:
        cf.CLI_ARGS.reset(token)
    monkeypatch.setattr("sys.argv", ["notebook.py"])
    assert cf.history("T", "mechsweep.run(scene 'x')", "9.9") == "T: mechsweep.run(scene 'x') (Python, notebook.py) (mechsweep 9.9)"
    # `python -m pytest` (or any other __main__.py) is not the mechsweep command
    monkeypatch.setattr("sys.argv", ["/site-packages/pytest/__main__.py", "-x"])
    assert cf.history("T", "mechsweep.run(scene 'x')", "9.9") == "T: mechsweep.run(scene 'x') (Python, __main__.py) (mechsweep 9.9)"


def test_references_come_from_the_declaration():
    assert "Synthesis of motion laws of the rocking link" in cf.references(MODELS["duffing"])
    assert "Dzhavakhyan & Arakelyan" in cf.references(MODELS["fourbar_balancing"])
    ab = MODELS["autobalancer"]  # declares no references: its source stands in
    assert cf.references(ab) == ("\n".join(ab.references) if ab.references else ab.source)
