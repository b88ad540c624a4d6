"""The command line as a user meets it: exit codes, messages without tracebacks, files."""
import subprocess
import sys

import pytest

from mechsweep.cli import main

from tests.conftest import REPO

BAD_SCENE = """
[scene]
name = "bad"
model = "duffing"
outputs = ["period"]
[axes]
A = { start = 0.1, stop = 1.0, num = 3 }
[fixed]
omega = -2.0
mu = 1.0
"""


def run_cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "mechsweep.cli", *args], capture_output=True, text=True, cwd=cwd)


def test_invalid_scene_exit_2_no_traceback_no_file(in_tmp):
    (in_tmp / "bad.toml").write_text(BAD_SCENE)
    before = sorted(p.name for p in (in_tmp / "data" / "runs").iterdir())
    out = run_cli("run", "bad.toml", cwd=in_tmp)
    assert out.returncode == 2
    assert "Traceback" not in out.stderr
    assert "fixed.omega: -2.0 rad s-1 is outside the physical range; expected a finite number in (0, inf)" in out.stderr
    assert sorted(p.name for p in (in_tmp / "data" / "runs").iterdir()) == before


def test_run_info_plot(in_tmp, capsys):
    scene = REPO / "sweeps" / "quickstart.toml"
    assert main(["run", str(scene), "-o", "data/runs/q.h5", "--no-progress", "--threads", "1"]) == 0
    assert f"wrote {in_tmp / 'data/runs/q.h5'}:" in capsys.readouterr().out
    assert main(["info", "data/runs/q.h5"]) == 0
    info = capsys.readouterr().out
    for piece in ("dimensions:", "A ", "[rad]", "status: ok 1000", "steps", "solver: method=dop853", "wall time",
                  "(compile ", ", compute ", "1 threads)"):
        assert piece in info, piece
    assert main(["plot", "data/runs/q.h5", "--list"]) == 0
    assert "amplitude_period" in capsys.readouterr().out
    assert main(["plot", "data/runs/q.h5", "--kind", "amplitude_period", "--format", "svg"]) == 0
    assert (in_tmp / "data/runs/q.svg").stat().st_size > 10_000


def test_plot_missing_dataset_is_a_clear_error(in_tmp, capsys):
    assert main(["plot", "nothing.h5"]) == 2
    assert "does not exist" in capsys.readouterr().err


@pytest.mark.parametrize("args", [["--help"], ["run", "--help"], ["plot", "--help"], ["bench", "--help"]])
def test_help_teaches(args, capsys):
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 0
    assert "mechsweep" in capsys.readouterr().out


def test_check_and_models(capsys):
    assert main(["check", *map(str, sorted((REPO / "sweeps").glob("*.toml")))]) == 0
    assert main(["models", "duffing"]) == 0
    text = capsys.readouterr().out
    assert "omega" in text and "[rad s-1]" in text


def test_models_of_a_file_without_a_name_lists_what_the_file_defines(capsys, tmp_path):
    """`mechsweep models file.py` (no :NAME): the models the file defines, each described, and how a
    scene names one; a missing file or one without models: exit 2 naming it."""
    path = REPO / "tests" / "user_models" / "oscillators.py"
    assert main(["models", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{path} defines 3 model(s): LINEAR, PENDULUM, PENDULUM_CHECKED; a scene names one as "
                          f"{path}:NAME")
    assert f"source: {path}:LINEAR" in out and f"source: {path}:PENDULUM\n" in out
    assert f"source: {path}:PENDULUM_CHECKED" in out
    assert main(["models", str(tmp_path / "none.py")]) == 2
    assert "none.py" in capsys.readouterr().err
    (tmp_path / "empty.py").write_text("x = 1\n")
    assert main(["models", str(tmp_path / "empty.py")]) == 2
    assert "defines no mechsweep.model.OdeModel or ClosedFormModel" in capsys.readouterr().err


def test_output_cut_short_by_a_pipe_is_not_an_error():
    """`mechsweep models | head -1`: the reader leaves early; no traceback, exit 0."""
    import subprocess
    import sys

    proc = subprocess.run(f"{sys.executable} -m mechsweep.cli models | head -1", shell=True, capture_output=True,
                          text=True, timeout=120)
    assert proc.stdout.startswith("duffing")
    assert "Traceback" not in proc.stderr and "BrokenPipe" not in proc.stderr


def _dataset(model, outputs, kinds=True, notes=None):
    """A small run-like dataset built by hand: a grid of 6 points, outputs named by the caller."""
    import json

    import numpy as np
    import xarray as xr

    from mechsweep import status as st

    status = np.array([st.OK, st.OK, st.OK, st.UNDECIDED, st.NO_EVENT, st.OK], dtype=st.DTYPE)
    values = {"v1": [1.0, 0.0, 1.0, np.nan, np.nan, 1.0], "v2": [1.0, 1.0, 1.0, 0.0, np.nan, np.nan],
              "x": [0.5, 0.25, 2.0, 3.0, np.nan, 1.0]}
    ds = xr.Dataset(coords={"k": ("k", np.arange(6.0), {"units": "1"})},
                    attrs={"title": "t", "model": model, "outputs": " ".join(outputs)})
    for name, value in zip(outputs, values.values()):
        kind = {"mechsweep_kind": "verdict"} if kinds and name != outputs[-1] else {}
        ds[name] = ("k", np.array(value), {"units": "1", "long_name": name, **kind})
    ds["status"] = ("k", status, {"status_notes": json.dumps(notes)} if notes else {})
    return ds


def test_info_compares_any_two_verdicts_and_says_where_values_are_missing():
    """A model info has never heard of: its verdict outputs (declared kind) are compared, every
    output says how many points hold a value and why the others do not, and the model's own
    status notes stored with the dataset are shown."""
    from mechsweep.describe import describe

    ds = _dataset("some_user_model", ["ok_a", "ok_b", "x"], notes={"undecided": "the pendulum dithers"})
    text = describe(ds)
    assert ("verdicts: ok_a and ok_b agree at 2 of 3 points with both verdicts; disagree at 1 (ok_a 1, ok_b 0: 0; "
            "ok_a 0, ok_b 1: 1); 1 points have ok_a only, 1 ok_b only") in text
    assert "values at 4 of 6 points; missing: no_event 1, undecided 1" in text  # ok_a
    assert "values at 5 of 6 points; missing: no_event 1" in text  # x
    assert "undecided: the pendulum dithers" in text
    assert "verdicts: ok_a and x" not in text  # x is not a verdict


def test_info_cost_of_an_unfinished_run_is_per_computed_point():
    """Pending points (an interrupted run) took no steps: the mean is over the computed points."""
    import numpy as np

    from mechsweep import status as st
    from mechsweep.describe import describe

    ds = _dataset("some_user_model", ["x"])
    ds["status"][:4] = st.PENDING
    ds["n_steps"] = ("k", np.array([0, 0, 0, 0, 30, 10]))
    ds["n_rhs"] = ("k", np.array([0, 0, 0, 0, 300, 100]))
    assert "cost: 40 steps, 400 rhs evaluations, mean 20.0 steps/point computed (2 of 6)" in describe(ds)
    ds["status"][:] = st.PENDING
    assert "no point computed yet" in describe(ds)


def test_info_ranges_cover_every_value_also_at_points_whose_status_is_not_ok():
    """The range of an output is over all its finite values: a value at a point whose status is
    not ok (e.g. a multiplier > 1 where another output failed) is shown; the range over the ok
    points beside it when it differs, and how many values sit at such points."""
    from mechsweep.describe import describe

    text = describe(_dataset("some_user_model", ["ok_a", "ok_b", "x"]))
    lines = text.splitlines()
    x = next(i for i, line in enumerate(lines) if line.startswith("  x "))
    assert "[1]  0.25 .. 3 (at ok points 0.25 .. 2)  x" in lines[x]  # 3.0 at the undecided point
    assert lines[x + 1].strip() == "values at 5 of 6 points; missing: no_event 1; 1 held at points whose status is not ok"
    b = next(i for i, line in enumerate(lines) if line.startswith("  ok_b "))
    assert "[1]  0 .. 1 (at ok points 1 .. 1)  ok_b" in lines[b]  # a verdict 0 only at a non-ok point
    a = next(i for i, line in enumerate(lines) if line.startswith("  ok_a "))
    assert "[1]  0 .. 1  ok_a" in lines[a]  # every value at an ok point: one range
    assert "held at points" not in lines[a + 1]


def test_info_shows_a_missing_unit_as_a_dash():
    """An output or axis stored without units (a user model's output declared without one) reads
    [-] in info, as a parameter without a unit does in `mechsweep models`, not an empty []."""
    from mechsweep.describe import describe

    ds = _dataset("some_user_model", ["x"])
    del ds["x"].attrs["units"]
    del ds["k"].attrs["units"]
    lines = describe(ds).splitlines()
    assert "[-]  0 .. 1" in next(line for line in lines if line.startswith("  x "))
    assert "[-]" in next(line for line in lines if line.startswith("  k "))
    assert "[]" not in "\n".join(lines)


def test_info_reads_the_declared_kinds_of_a_built_in_model_for_an_old_dataset():
    """A dataset written before kinds were stored: the built-in declaration says which outputs are
    verdicts (none is named in the reader), and its status notes are shown."""
    from mechsweep.describe import describe

    ds = _dataset("autobalancer", ["stable_floquet", "stable_sim", "floquet_max"], kinds=False)
    text = describe(ds)
    assert "verdicts: stable_floquet and stable_sim agree at 2 of 3" in text
    assert "undecided: the simulation neither settled nor diverged" in text


def test_status_texts_name_no_model():
    """The generic status texts (status.py) name no model, none of a built-in model's parameters or
    outputs; what a status means for one model is that model's status_notes."""
    import re

    from mechsweep import status as st
    from mechsweep.models import MODELS

    text = " ".join(st.DESCRIPTIONS.values()).lower()
    names = {"duffing", "autobalancer", "pendulum", "lever", "spring", "phi", "crank", "linkage"}
    for spec in MODELS.values():
        names |= {spec.name.lower(), *spec.name.lower().split("_")}
        names |= {n.lower() for n in spec.param_names() + spec.output_names() if len(n) > 2 or "_" in n}
    found = sorted(n for n in names if re.search(rf"(?<![\w.]){re.escape(n)}(?!\w)", text))
    assert not found, found
    assert all(spec.status_notes for spec in MODELS.values())


def test_the_command_line_modules_name_no_model():
    """cli.py and the command modules name no built-in model, none of their parameters or outputs
    (their help examples were a model's name and axes); a shipped scene's path may stand in a
    help text (sweeps/NAME.toml: the scene, not the model), and the bench examples are the bench
    package's own."""
    import re
    from pathlib import Path

    import mechsweep.cli
    from mechsweep.models import MODELS

    names = set()
    for spec in MODELS.values():
        names |= {spec.name, *spec.name.split("_")}
        names |= {n for n in spec.param_names() + spec.output_names() if len(n) > 2 or "_" in n}
    folder = Path(mechsweep.cli.__file__).parent
    for path in [folder / "cli.py", *sorted((folder / "commands").glob("*.py"))]:
        source = path.read_text()
        found = sorted(n for n in names if re.search(rf"(?<![\w./]){re.escape(n)}(?!\w)", source))
        assert not found, (path.name, found)


def test_a_run_stores_its_model_status_notes_and_info_shows_those_it_met(in_tmp, capsys):
    import json

    import mechsweep
    from mechsweep import status as st

    scene = {"scene": {"name": "notes", "model": "duffing", "outputs": ["period"]},
             "axes": {"A": [0.0, 0.5, 2.0]}, "fixed": {"omega": 1.0, "mu": -1.0}}
    ds = mechsweep.run(mechsweep.load_scene(scene), output=in_tmp / "notes.h5", progress=False)
    assert sorted(ds["status"].values.tolist()) == [st.OK, st.NOT_OSCILLATORY, st.NO_MOTION]
    notes = json.loads(ds["status"].attrs["status_notes"])
    spec = mechsweep.load_scene(scene).model
    assert notes == {st.MEANINGS[c]: t for c, t in spec.status_notes}
    assert main(["info", str(in_tmp / "notes.h5")]) == 0
    info = capsys.readouterr().out
    assert f"  not_oscillatory: {spec.status_note(st.NOT_OSCILLATORY)}" in info
    assert f"  no_motion: {spec.status_note(st.NO_MOTION)}" in info
    assert "values at 1 of 3 points; missing: not_oscillatory 1, no_motion 1" in info


def test_info_gives_a_boundary_next_to_zero_its_bracket_width_absolute():
    """A boundary located at (or within 1e-6 of the axis span of) 0 has no meaningful width relative
    to |x|: `info` gives those brackets' widths in the axis's units, and the relative width only for
    boundaries away from 0 (the locator's own scale: its tolerance is rtol max(|x|, 1e-6 span))."""
    import numpy as np
    import xarray as xr

    from mechsweep.boundaries import PARAMETER
    from mechsweep.describe import describe_boundaries

    loc = np.array([[2.0, 1e-12, 0.5], [-4.0, np.nan, 3e-7]])  # axis span 10: scale 1e-5
    width = np.array([[2e-10, 3e-15, 1e-10], [8e-10, np.nan, 4e-13]])
    ds = xr.Dataset({"boundary": (("q", "crossing"), loc, {"units": "m"}),
                     "boundary_width": (("q", "crossing"), width, {"units": "m"}),
                     "boundary_bound": (("q", "crossing"), np.full(loc.shape, PARAMETER, np.int8))},
                    attrs={"mechsweep_kind": "boundaries", "along": "a", "criterion": "g", "level": 0.0,
                           "along_span": 10.0})
    text = describe_boundaries(ds)
    assert "bracket width relative to the boundary (3 with |a| > 1.0e-05 = 1e-06 x axis span): median 2.0e-10, " \
           "largest 2.0e-10" in text
    assert "bracket width absolute next to a = 0 (2 with |a| <= 1.0e-05): median 2.0e-13 m, largest 4.0e-13 m" in text
    # a dataset written before the span was stored: relative wherever x != 0, as before
    del ds.attrs["along_span"]
    old = describe_boundaries(ds)
    assert "bracket width relative to the boundary (5 with a != 0): median 2.0e-10, largest 3.0e-03" in old
    assert "absolute" not in old
