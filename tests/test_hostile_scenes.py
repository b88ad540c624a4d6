"""Hostile scenes: malformed, absurd or malicious input must be refused clearly, before any work.

For every scene of ``tests/hostile/`` (and for the path attacks built here in tmp_path):
``mechsweep run`` exits with code 2, prints an error that names the bad key and/or value,
no Python traceback, and creates or changes no file. Nothing here runs a sweep: the
engine's first write and first computation are replaced by a tripwire.
"""
from __future__ import annotations

import math
import os
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from mechsweep import runner
from mechsweep.cli import main
from mechsweep.models import MODELS

HOSTILE = Path(__file__).resolve().parent / "hostile"

# file -> fragments the error message must contain (the bad key and/or value, and the rule)
CORPUS = {
    # file level: encoding, syntax, bombs
    "non_utf8.toml": ["not UTF-8", "byte 19"],
    "utf16.toml": ["not UTF-8", "byte 0"],
    "binary_garbage.toml": ["not UTF-8"],
    "utf8_bom.toml": ["byte-order mark", "without BOM"],
    "nul_byte_in_text.toml": ["TOML syntax error", "'\\x00'", "line 3"],
    "empty_file.toml": ["missing section [scene]"],
    "toml_syntax_error.toml": ["TOML syntax error", "line 2"],
    "unterminated_string.toml": ["TOML syntax error", "line 3"],
    "duplicate_key.toml": ["TOML syntax error", "Cannot overwrite a value", "line 13"],
    "duplicate_section.toml": ["TOML syntax error", "('fixed',) twice"],
    "toml_bomb_deep_arrays.toml": ["TOML nesting too deep"],
    "toml_bomb_deep_inline_tables.toml": ["TOML nesting too deep"],
    "toml_bomb_dotted_keys.toml": ["TOML nesting too deep", "line 13", "more than 32 levels"],
    "toml_bomb_deep_table_header.toml": ["TOML nesting too deep", "line 17"],
    "huge_integer.toml": ["fixed.mu", "too large for a float", "(-inf, inf)"],
    "huge_integer_digits.toml": ["TOML value not readable", "5001 digits"],
    "huge_list_value.toml": ["fixed.mu", "[1, 1, 1, 1, 1, 1, ...] is not a number"],
    # top level and [scene]
    "top_level_key.toml": ["name", "unknown section 'name'", "scene, axes, fixed, solver, storage"],
    "unknown_section.toml": ["unknown section 'axis'", "did you mean 'axes'"],
    "missing_scene_section.toml": ["missing section [scene]", "scene.model: missing"],
    "scene_not_table.toml": ["scene: expected a table [scene], got int 3"],
    "scene_array_of_tables.toml": ["scene: expected a table [scene], got list"],
    "empty_name.toml": ["scene.name", "'   '", "non-empty string"],
    "name_int.toml": ["scene.name: 42", "non-empty string"],
    "unknown_scene_key.toml": ["scene.descripton", "did you mean 'description'"],
    "unknown_model.toml": ["scene.model", "'dufing'", "did you mean 'duffing'"],
    "model_int.toml": ["scene.model", "unknown model 7", "slidercrank_balancing"],
    "missing_model.toml": ["scene.model: missing", "torsional_circuit"],
    "outputs_string.toml": ["scene.outputs", "'period' is not allowed", "non-empty list"],
    "outputs_empty.toml": ["scene.outputs", "[] is not allowed", "non-empty list"],
    "output_unknown.toml": ["scene.outputs", "'perod'", "did you mean 'period'"],
    "output_int.toml": ["scene.outputs", "unknown output of model 'duffing' 1"],
    "output_duplicate.toml": ["scene.outputs", "'epsilon' is listed twice"],
    "output_of_other_model.toml": ["scene.outputs", "'chi'", "period_exact"],
    "torsional_output_needs_optional.toml": ["output 'period' needs parameter(s) A, R, c, I"],
    "fourbar_unknown_output.toml": ["unknown output of model 'fourbar_balancing' 'floquet_max'"],
    # [axes]
    "empty_axis.toml": ["axes.A", "empty list"],
    "gigantic_axis.toml": ["axes.A.num", "1000000000", "[1, 10000000]"],
    "gigantic_grid.toml": ["axes", "1e+24 points", "A 100000000 x mu 100000000 x omega 100000000", "at most"],
    "nan_axis.toml": ["axes.A[1]", "nan is not finite", "[0, inf)"],
    "inf_axis_start.toml": ["axes.A.start", "inf is not finite"],
    "nan_axis_stop.toml": ["axes.A.stop", "nan is not finite"],
    "axis_span_overflow.toml": ["axes.mu", "-1e+308", "overflows"],
    "axis_values_repeat_at_float_precision.toml": ["axes.A", "num = 100", "repeat at float precision"],
    "axis_start_equals_stop.toml": ["axes.A", "start = stop = 0.5", "repeat"],
    "axis_num_zero.toml": ["axes.A.num", "0 is not allowed", "whole number"],
    "axis_num_negative.toml": ["axes.A.num", "-5 is not allowed"],
    "axis_num_float.toml": ["axes.A.num", "10.0 is not allowed", "whole number"],
    "axis_num_bool.toml": ["axes.A.num", "True is not allowed"],
    "axis_num_string.toml": ["axes.A.num", "'ten' is not allowed"],
    "axis_missing_stop.toml": ["axes.A.stop: missing"],
    "axis_unknown_key.toml": ["axes.A.step", "unknown axis key 'step'", "start, stop, num, spacing"],
    "axis_spacing_unknown.toml": ["axes.A.spacing", "'cubic'", "linear, log"],
    "log_axis_nonpositive.toml": ["axes.A", "log spacing needs start > 0", "start = 0"],
    "axis_scalar.toml": ["axes.A", "3.0 is not allowed", "list of values or a table"],
    "axis_string.toml": ["axes.A", "'0.1 .. 1.0'", "list of values or a table"],
    "axis_list_of_strings.toml": ["axes.A[0]", "'0.1' is not a number"],
    "axis_nested_list.toml": ["axes.A[0]", "[0.1, 0.2] is not a number"],
    "axis_duplicate_values.toml": ["axes.A", "values repeat"],
    "axis_list_collapses_at_float_precision.toml": ["axes.A", "9007199254740992 and 9007199254740993",
                                                    "same value at float precision"],
    "axis_list_collapses_huge_ints.toml": ["axes.mu", "same value at float precision"],
    "axis_unknown_param.toml": ["axes.omgea", "did you mean 'omega'"],
    "axis_and_fixed_same_param.toml": ["fixed.A", "both as an axis and as a fixed value"],
    "axes_not_table.toml": ["axes: expected a table [axes], got list [1, 2]"],
    "categorical_range_axis.toml": ["axes.spring", "categorical", "'tension', 'compression'"],
    "categorical_bad_choice.toml": ["axes.spring[1]", "'compresion'", "'tension', 'compression'"],
    "autobalancer_axis_zero_speed.toml": ["axes.Omega.start", "0.0 rad s-1", "(0, inf)"],
    "slidercrank_axis_k_beyond.toml": ["axes.k.stop", "3.0", "[0, 2]"],
    "fourbar_axis_delta_one.toml": ["axes.delta[1]", "1.0", "(-1, 1)"],
    # [fixed]
    "negative_mass.toml": ["fixed.m: -1.0 kg", "outside the physical range", "(0, inf)"],
    "negative_platform_mass.toml": ["fixed.M: -20.0 kg", "(0, inf)"],
    "fourbar_zero_coupler_mass.toml": ["fixed.m2: 0.0 kg", "(0, inf)"],
    "fourbar_negative_length.toml": ["fixed.a1: -0.1 m", "(0, inf)"],
    "fourbar_theta_beyond_2pi.toml": ["fixed.theta1: 7.0 rad", "[-6.283185307179586, 6.283185307179586]"],
    "slidercrank_negative_slider_mass.toml": ["fixed.m3: -1.5 kg", "[0, inf)"],
    "slidercrank_gravity_too_big.toml": ["fixed.g: 1000.0", "[0, 100]"],
    "slidercrank_l_and_lambda.toml": ["fixed.lambda", "not both"],
    "slidercrank_missing_l.toml": ["fixed.l: missing", "lambda"],
    "autobalancer_omega_xi_and_c_xi.toml": ["c_xi", "both omega_xi = 20 and c_xi = 8000"],
    "autobalancer_missing_platform.toml": ["omega_eta: missing", "c_eta"],
    "autobalancer_A1_without_l3.toml": ["l3: missing", "A1 = 0.02", "l4: missing"],
    "torsional_amplitude_beyond_pi.toml": ["fixed.A: 4.0 rad", "[0, 3.141592653589793]"],
    "torsional_spring_number.toml": ["fixed.spring: 1 is not allowed", "'tension', 'compression'"],
    "torsional_negative_lambda1.toml": ["fixed.lambda1: -0.8", "(0, inf)"],
    "string_for_float.toml": ["fixed.omega", "'fast' is not a number", "(0, inf)"],
    "bool_for_float.toml": ["fixed.omega", "True is not a number"],
    "nan_fixed.toml": ["fixed.omega", "nan is not finite"],
    "inf_fixed.toml": ["fixed.mu", "inf is not finite"],
    "negative_inf_fixed.toml": ["fixed.mu", "-inf is not finite"],
    "float_literal_overflow.toml": ["fixed.mu", "inf is not finite"],
    "zero_frequency.toml": ["fixed.omega: 0.0 rad s-1", "(0, inf)"],
    "fixed_table_value.toml": ["fixed.omega", "{'value': 1.0} is not a number"],
    "fixed_list_value.toml": ["fixed.omega", "[1.0] is not a number"],
    "fixed_datetime.toml": ["fixed.omega", "datetime", "is not a number"],
    "fixed_huge_string.toml": ["fixed.omega", "'xxx", "is not a number"],
    "fixed_unknown_param.toml": ["fixed.omegaa", "did you mean 'omega'"],
    "missing_required_param.toml": ["fixed.omega: missing", "(0, inf)"],
    "fixed_not_table.toml": ["fixed: expected a table [fixed], got int 3"],
    # [solver]
    "inf_rtol.toml": ["solver.rtol", "inf", "[1e-15, 0.1]"],
    "nan_atol.toml": ["solver.atol", "nan", "[1e-300, 1]"],
    "rtol_zero.toml": ["solver.rtol", "0.0 is outside the allowed range"],
    "rtol_string.toml": ["solver.rtol", "'1e-8' is not allowed"],
    "rtol_huge_integer.toml": ["solver.rtol", "outside the allowed range"],
    "max_steps_float.toml": ["solver.max_steps", "1000.5", "whole number"],
    "max_steps_bool.toml": ["solver.max_steps", "True is not allowed"],
    "max_steps_huge.toml": ["solver.max_steps", "1000000000000", "[1, 1e+09]"],
    "max_steps_negative.toml": ["solver.max_steps", "-1 is outside"],
    "unknown_method.toml": ["solver.method", "'euler'", "dop853"],
    "method_list.toml": ["solver.method", "['dop853']"],
    "unknown_solver_key.toml": ["solver.tol", "did you mean 'rtol'"],
    "duffing_setting_out_of_range.toml": ["solver.t_max_periods", "0.0", "[0.001, 1e+09]"],
    "torsional_setting_string.toml": ["solver.t_max_periods", "'long' is not allowed"],
    "autobalancer_setting_float_for_int.toml": ["solver.trajectory_samples", "10.5", "whole number"],
    "autobalancer_setting_of_other_model.toml": ["solver.t_max_periods", "unknown solver setting of 'autobalancer'"],
    "autobalancer_horizon_huge_int.toml": ["solver.horizon_revolutions", "too large for a float", "[1, 100000]"],
    "solver_not_table.toml": ["solver: expected a table [solver], got str 'dop853'"],
    "solver_garbage_without_integration.toml": ["solver.method", "'euler'", "solver.rtol", "-1",
                                                "solver.tolerance", "unknown solver setting"],
    "fourbar_solver_garbage.toml": ["solver.rtol", "'tight'", "solver.steps", "unknown solver setting"],
    "solver_not_table_without_integration.toml": ["solver: expected a table [solver], got int 5"],
    # [storage]
    "storage_path_int.toml": ["storage.path: 5 is not allowed"],
    "storage_path_empty.toml": ["storage.path: '' is not allowed"],
    "storage_path_nul.toml": ["storage.path", "NUL character"],
    "storage_path_trailing_slash.toml": ["storage.path", "'data/runs/new/'", "ends with a path separator"],
    "storage_unknown_key.toml": ["storage.format", "unknown storage key 'format'"],
    "chunk_size_zero.toml": ["storage.chunk_size: 0 is not allowed"],
    "chunk_size_float.toml": ["storage.chunk_size: 100.5 is not allowed"],
    "chunk_size_huge.toml": ["storage.chunk_size: 4294967296 is not allowed", "[1, 2147483648]"],
    "storage_not_table.toml": ["storage: expected a table [storage], got str"],
    "execution_unknown_key.toml": ["execution.workers", "unknown execution key 'workers'", "(allowed: scheduler, worker_timeout, lanes)"],
    "execution_scheduler_number.toml": ["execution.scheduler: 8786 is not allowed", "tcp://"],
    "execution_scheduler_spaces.toml": ["execution.scheduler", "is not an address", "tcp://"],
    "execution_scheduler_empty.toml": ["execution.scheduler", "is not allowed", "tcp://"],
    # user models (tests/user_models, copied next to the scene): functions writing what they may not
    # (model/writes.py), exits while a model loads, model files that are not Python files
    "model_event_writes_state.toml": ["scene.model", "event of FirstEvent 'apex' writes into its state argument y",
                                      "hostile_writes.py:37", "y[1] = -p[2] * y[1]", "state jumps are not supported"],
    "model_event_writes_state_in_module_helper.toml": [
        "event of FirstEvent 'apex' writes into its state argument y", "hostile_writes.py:56",
        "through negate, which writes it at", "hostile_helpers.py:10 (v[k] = -v[k])"],
    "model_event_writes_state_unseen.toml": ["event of FirstEvent 'apex' wrote into its state argument y (component(s) 1)",
                                             "when run at the probe point", "hostile_writes.py:60"],
    "model_rhs_writes_parameter.toml": ["rhs writes into its parameter argument p", "hostile_writes.py:72",
                                        "may write only its 4th argument (dydt)"],
    "model_prepare_writes_parameter.toml": ["prepare writes into its parameter argument p", "hostile_writes.py:100",
                                            "only the model's internal slots of p (p[3:4]"],
    "model_expression_writes_state.toml": ["expression of Extremum 'e_max' writes into its state argument y",
                                           "hostile_writes.py:84 (y[:] = np.abs(y))"],
    "model_closed_form_writes_parameter.toml": ["closed form 't_fall' writes into its parameter argument p",
                                                "hostile_writes.py:123"],
    "model_compute_writes_data.toml": ["compute writes into its shared data argument u", "hostile_writes.py:188",
                                       "only row, curves and scratch"],
    "model_sys_exit_at_import.toml": ["scene.model", "importing", "exit_sys.py", "SystemExit(0)", "exit_sys.py, line 5",
                                      "may not exit"],
    "model_base_exception_at_import.toml": ["Stop raised (a BaseException, not an Exception): no model today",
                                            "exit_base.py, line 9"],
    "model_helper_exits_at_import.toml": ["SystemExit(3)", "exit_helper_module.py, line 5",
                                          "reached from", "exit_via_helper.py, line 4"],
    "model_exits_at_probe.toml": ["running its functions at the probe point", "SystemExit(0)", "exit_probe.py, line 18"],
    "model_not_a_python_file.toml": ["model_not_a_python_file.toml is not a Python file", "ends in .py"],
    "model_file_is_a_folder.toml": ["data/runs is a folder, not a Python file"],
    "model_file_is_a_device.toml": ["/dev/null is a character device, not a Python file"],
}
USER_MODELS = Path(__file__).resolve().parent / "user_models"
# a model file of the corpus -> the modules it imports by name (copied beside it)
COMPANIONS = {"hostile_writes.py": ("hostile_helpers.py",), "exit_via_helper.py": ("exit_helper_module.py",)}

# a valid, algebraic (instant) scene for the attacks on the output path
VALID = """\
[scene]
name = "target"
model = "duffing"
outputs = ["period_exact"]

[axes]
A = { start = 0.1, stop = 1.0, num = 3 }

[fixed]
omega = 1.0
mu = 1.0

[storage]
path = "data/runs/hostile.h5"
"""


# ----------------------------------------------------------------------------- helpers
@pytest.fixture
def work(tmp_path, monkeypatch):
    """An empty working directory with data/runs; the engine's first write or computation fails loudly."""
    (tmp_path / "data" / "runs").mkdir(parents=True)
    monkeypatch.chdir(tmp_path)

    def tripwire(*args, **kwargs):
        raise AssertionError("work started: the scene was not refused before the run")

    monkeypatch.setattr(runner.RunLock, "acquire", tripwire)
    monkeypatch.setattr(runner.Journal, "create", tripwire)
    monkeypatch.setattr(runner, "_save_chunks", tripwire)
    monkeypatch.setattr(runner, "evaluate_chunk", tripwire)
    return tmp_path


def snapshot(root: Path) -> dict:
    """Every file and folder under root: kind, size, mtime and (for small files) content."""
    state = {}
    for p in sorted(root.rglob("*")):
        st = p.lstat()
        data = p.read_bytes() if p.is_file() and st.st_size < 1 << 20 else None
        state[str(p.relative_to(root))] = (p.is_dir(), st.st_size, st.st_mtime_ns, st.st_mode, data)
    return state


def refused(capsys, argv, root: Path, *fragments) -> str:
    """Run the CLI in-process; assert exit 2, the fragments, no traceback, no file touched."""
    before = snapshot(root)
    code = main(argv)
    out, err = capsys.readouterr()
    assert code == 2, f"exit code {code}, stderr:\n{err}"
    assert "Traceback" not in out + err
    for piece in fragments:
        assert piece in err, f"{piece!r} missing from:\n{err}"
    assert len(err) < 4000, f"message of {len(err)} characters is not readable"
    assert snapshot(root) == before, "a file was created or changed"
    return err


def existing_dataset(path: Path) -> bytes:
    """A small finished-looking dataset at path (written directly, no sweep)."""
    ds = xr.Dataset({"period_exact": ("A", np.array([6.2, 6.1, 5.9])), "status": ("A", np.zeros(3, np.int8))},
                    coords={"A": [0.1, 0.5, 1.0]},
                    attrs={"title": "earlier run", "model": "duffing", "outputs": "period_exact",
                           "scene_canonical": "{}", "scene": ""})
    ds.to_netcdf(path, engine="h5netcdf")
    return path.read_bytes()


# ----------------------------------------------------------------------------- the corpus
def test_corpus_is_complete():
    files = {p.name for p in HOSTILE.glob("*.toml")}
    assert files == set(CORPUS), f"without expectation: {files - set(CORPUS)}; missing: {set(CORPUS) - files}"
    assert len(files) >= 60
    texts = [p.read_bytes() for p in HOSTILE.glob("*.toml")]
    for model in MODELS:
        assert any(f'model = "{model}"'.encode() in t for t in texts), f"no hostile scene for {model}"
    for section in ("[scene]", "[axes]", "[fixed]", "[solver]", "[storage]"):
        assert sum(section.encode() in t for t in texts) >= 5, section


def with_user_models(name: str, work: Path, monkeypatch) -> None:
    """Copy the model file a scene names (and the modules it imports) from tests/user_models beside
    it, importable by name from there, with no bytecode written (nothing in the folder may change)."""
    for ref in re.findall(r'^model = "([\w.]+\.py):', (HOSTILE / name).read_text(errors="replace"), re.M):
        for file in (ref,) + COMPANIONS.get(ref, ()):
            shutil.copy(USER_MODELS / file, work / file)
    monkeypatch.setattr("sys.dont_write_bytecode", True)
    monkeypatch.syspath_prepend(str(work))


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_hostile_scene_is_refused(name, work, capsys, monkeypatch):
    shutil.copy(HOSTILE / name, work / name)
    with_user_models(name, work, monkeypatch)
    out = work / "data" / "runs" / "out.h5"
    refused(capsys, ["run", name, "-o", str(out), "--no-progress"], work, *CORPUS[name])
    refused(capsys, ["run", name, "--no-progress"], work, *CORPUS[name])  # to its own [storage] path
    refused(capsys, ["check", name], work, *CORPUS[name])


def test_existing_dataset_is_unchanged_by_hostile_scenes(work, capsys):
    target = work / "data" / "runs" / "hostile.h5"  # the [storage] path of every corpus scene
    original = existing_dataset(target)
    for name in ("negative_mass.toml", "nan_axis.toml", "toml_bomb_deep_arrays.toml", "non_utf8.toml",
                 "gigantic_grid.toml", "inf_rtol.toml", "storage_path_trailing_slash.toml"):
        shutil.copy(HOSTILE / name, work / name)
        refused(capsys, ["run", name, "--no-progress"], work, *CORPUS[name])
        refused(capsys, ["run", name, "-o", str(target), "--restart", "--no-progress"], work, *CORPUS[name])
    assert target.read_bytes() == original


# ----------------------------------------------------------------------------- attacks on the paths
@pytest.fixture
def valid(work):
    (work / "valid.toml").write_text(VALID)
    return "valid.toml"


def test_output_is_a_directory(work, valid, capsys):
    refused(capsys, ["run", valid, "-o", "data/runs"], work, "data/runs is a directory")


def test_output_with_trailing_separator(work, valid, capsys):
    refused(capsys, ["run", valid, "-o", "data/runs/new/"], work, "ends with a path separator")


def test_output_parent_missing(work, valid, capsys):
    refused(capsys, ["run", valid, "-o", "data/nothing/here/out.h5"], work, "data/nothing/here", "does not exist")


def test_output_inside_a_file(work, valid, capsys):
    (work / "notes.txt").write_text("not a folder")
    refused(capsys, ["run", valid, "-o", "notes.txt/out.h5"], work, "notes.txt", "is a file, not a folder")


def test_output_overwrites_a_file_that_is_not_a_dataset(work, valid, capsys):
    refused(capsys, ["run", valid, "-o", valid], work, "valid.toml exists and is not an HDF5 dataset")
    (work / "notes.txt").write_text("keep me")
    refused(capsys, ["run", valid, "-o", "notes.txt"], work, "notes.txt exists and is not an HDF5 dataset")


def test_output_name_too_long(work, valid, capsys):
    refused(capsys, ["run", valid, "-o", "data/runs/" + "x" * 300 + ".h5"], work, "is too long", "bytes")
    refused(capsys, ["run", valid, "-o", ("d" * 200 + "/") * 30 + "out.h5"], work, "File name too long")


def test_read_only_target_file(work, valid, capsys):
    target = work / "data" / "runs" / "ro.h5"
    original = existing_dataset(target)
    target.chmod(0o444)
    try:
        refused(capsys, ["run", valid, "-o", str(target)], work, "ro.h5 exists and is read-only")
    finally:
        target.chmod(0o644)
    assert target.read_bytes() == original


def test_read_only_target_folder(work, valid, capsys):
    folder = work / "data" / "locked"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        refused(capsys, ["run", valid, "-o", "data/locked/out.h5"], work, "cannot write into data/locked")
    finally:
        folder.chmod(0o755)


def test_unfinished_run_is_not_touched(work, valid, capsys):
    (work / "data" / "runs" / "hostile.h5.partial").write_bytes(b"\x89HDF\r\n\x1a\n half a run")
    refused(capsys, ["run", valid], work, "an unfinished run of this output exists", "--resume")


def test_resume_over_a_different_scene(work, valid, capsys):
    original = existing_dataset(work / "data" / "runs" / "hostile.h5")
    refused(capsys, ["run", valid, "--resume"], work, "holds a finished run of a different scene")
    assert (work / "data" / "runs" / "hostile.h5").read_bytes() == original


@pytest.mark.parametrize("threads", ["0", "-3", str(10**6)])
def test_bad_thread_count_creates_no_file(work, valid, capsys, threads):
    refused(capsys, ["run", valid, "--threads", threads], work, f"threads = {threads} is outside")


def test_scene_path_problems(work, capsys):
    refused(capsys, ["run", "missing.toml"], work, "'missing.toml' does not exist")
    refused(capsys, ["run", "data"], work, "'data' is a directory")
    refused(capsys, ["check", "data", "missing.toml"], work, "is a directory", "does not exist")


# ----------------------------------------------------------------------------- grids that cannot fit
HISTORIES = '["xi_history", "eta_history", "phase_error1_history", "phase_error2_history"]'


def huge_scene(points: int, chunk_size: int | None = None) -> str:
    """Autobalancer histories: 4 x 100000 samples = 3.2 MB of output per grid point."""
    storage = f"\nchunk_size = {chunk_size}" if chunk_size else ""
    return f"""\
[scene]
name = "huge"
model = "autobalancer"
outputs = {HISTORIES}

[axes]
Omega = {{ start = 6.0, stop = 60.0, num = {points} }}

[fixed]
M = 20.0
m = 1.0
a = 0.1
I_B = 0.012
A0 = 0.1
h = 0.02
omega_xi = 20.0
omega_eta = 30.0
zeta_xi = 0.05
zeta_eta = 0.05

[solver]
trajectory_samples = 100000

[storage]
path = "data/runs/huge.h5"{storage}
"""


SIZE = re.compile(r"\d+(\.\d+)?\s*([kMGTPE]i?B|bytes)")


def test_grid_beyond_the_disk_is_refused_with_its_size(work, capsys):
    points = 10**6  # 3.2 TB of output
    assert points * 3.2e6 > shutil.disk_usage(work).free
    (work / "huge.toml").write_text(huge_scene(points))
    err = refused(capsys, ["run", "huge.toml", "--no-progress"], work, "huge")
    assert SIZE.search(err), f"no size in:\n{err}"


def test_chunk_beyond_the_memory_is_refused_with_its_size(work, capsys):
    ram = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    points = math.ceil(2 * ram / 3.2e6)  # one chunk of twice the machine's memory
    if points * 3.2e6 * 1.5 > shutil.disk_usage(work).free:
        pytest.skip("the disk is too small to tell a memory refusal from a disk refusal")
    (work / "huge.toml").write_text(huge_scene(points, chunk_size=points))
    err = refused(capsys, ["run", "huge.toml", "--no-progress"], work, "memory")
    assert SIZE.search(err), f"no size in:\n{err}"
