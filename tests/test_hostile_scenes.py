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
import sys
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from mechsweep.execution import execute, runner
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
    "scene_name_nul.toml": ["scene.name: 'sweep\\x00one'", "NUL character", "HDF5"],
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
    "atol_below_floor.toml": ["solver.atol: 1e-300", "usable range of method 'dop853', [1e-150, 1]", "nonfinite",
                              "give atol >= 1e-150"],
    "torsional_radau_atol_below_floor.toml": ["solver.atol: 1e-160", "method 'radau', [1e-150, 1]", "overflows"],
    "autobalancer_auto_atol_below_floor.toml": ["solver.atol: 1e-200", "method 'auto', [1e-150, 1]"],
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
    monkeypatch.setattr(execute, "evaluate_chunk", tripwire)
    yield tmp_path
    # the user modules a scene imported by name from this folder (hostile_helpers, ...) must not be
    # found by a later test that imports the same names from tests/user_models
    for name, module in list(sys.modules.items()):
        if str(getattr(module, "__file__", None) or "").startswith(str(tmp_path)):
            del sys.modules[name]


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


# ----------------------------------------------------------------------------- scenes that are not small files
class Hung(BaseException):
    """Raised by the alarm: a read blocked (no Exception subclass, so no handler of the CLI takes it)."""


@pytest.fixture
def alarm():
    """Fail a command that blocks (e.g. on a pipe nobody writes) instead of hanging the suite."""
    import signal

    def ring(signum, frame):
        raise Hung("the command blocked")

    previous = signal.signal(signal.SIGALRM, ring)
    signal.alarm(20)
    yield
    signal.alarm(0)
    signal.signal(signal.SIGALRM, previous)


def _unix_socket(path: Path) -> None:
    import socket

    s = socket.socket(socket.AF_UNIX)
    s.bind(str(path))
    s.close()  # the socket file stays


def make_special(kind: str, work: Path) -> str:
    """A scene path that is not a small regular file (created in work)."""
    path = work / "scene.toml"
    if kind == "fifo":
        os.mkfifo(path)
    elif kind == "link_to_fifo":
        os.mkfifo(work / "pipe")
        path.symlink_to("pipe")
    elif kind == "socket":
        _unix_socket(path)
    elif kind == "folder":
        path.mkdir()
    elif kind == "huge":  # a sparse file: its size without its bytes on the disk
        with open(path, "wb") as f:
            f.truncate(200 * 2**20)
    elif kind == "just_too_big":
        from mechsweep.scene import MAX_SCENE_BYTES

        path.write_text(VALID + "#" * (MAX_SCENE_BYTES + 1 - len(VALID)))
    elif kind == "symlink_loop":
        path.symlink_to("scene.toml")
    elif kind == "broken_link":
        path.symlink_to("nowhere.toml")
    return path.name


SPECIAL = {
    "fifo": ["'scene.toml' is a named pipe (FIFO), not a scene file"],
    "link_to_fifo": ["'scene.toml' is a named pipe (FIFO), not a scene file"],
    "socket": ["'scene.toml' is a socket, not a scene file"],
    "folder": ["'scene.toml' is a directory, not a scene file"],
    "huge": ["'scene.toml' is 200 MiB", "at most 16 MiB", "range"],
    "just_too_big": ["'scene.toml' is 16 MiB", "at most 16 MiB"],
    "symlink_loop": ["'scene.toml' is a symbolic link loop"],
    "broken_link": ["'scene.toml' is a broken symbolic link (to 'nowhere.toml')"],
}
COMMANDS = {"run": ["run", "{}", "--no-progress"], "check": ["check", "{}"], "boundaries": ["boundaries", "{}"],
            "models": ["models", "--scene", "{}"]}


@pytest.mark.parametrize("command", sorted(COMMANDS))
@pytest.mark.parametrize("kind", sorted(SPECIAL))
def test_a_scene_that_is_not_a_small_regular_file_is_refused_without_reading_it(kind, command, work, capsys, alarm):
    """Every command that reads a scene: a pipe nobody writes would block, a device never ends, a
    big file would be read whole before it is found not to be a scene."""
    name = make_special(kind, work)
    refused(capsys, [a.format(name) for a in COMMANDS[command]], work, *SPECIAL[kind])


def test_an_unreadable_scene_says_permission_denied(work, capsys, monkeypatch):
    """EACCES (injected: the tests may run as root, who reads any file)."""
    import errno

    (work / "valid.toml").write_text(VALID)
    real_open = os.open

    def denied(path, *args, **kwargs):
        if str(path).endswith("valid.toml"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", denied)
    for command in ("run", "check"):
        refused(capsys, [a.format("valid.toml") for a in COMMANDS[command]], work,
                "cannot read 'valid.toml': permission denied (EACCES)")


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_a_device_as_the_scene_is_refused_at_once_in_bounded_memory(device, tmp_path):
    """In a child with 2 GiB of address space and a time limit: reading /dev/zero used to grow
    without end (MemoryError at the limit)."""
    import resource
    import subprocess
    import sys

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (2 * 2**30, 2 * 2**30))

    for argv in (["run", device, "--no-progress"], ["check", device]):
        child = subprocess.run([sys.executable, "-m", "mechsweep", *argv], cwd=tmp_path, capture_output=True,
                               text=True, timeout=120, preexec_fn=limit)
        assert child.returncode == 2, child.stderr[-2000:]
        assert f"'{device}' is a character device, not a scene file" in child.stderr, child.stderr
        assert "Traceback" not in child.stderr


def test_a_scene_text_beyond_the_cap_is_refused_before_parsing():
    from mechsweep.scene import MAX_SCENE_BYTES, SceneError, load_scene, load_scene_text

    with pytest.raises(SceneError, match="the scene text is 16 MiB; a scene is at most 16 MiB"):
        load_scene_text("#" * (MAX_SCENE_BYTES + 1), label="stored scene")
    values = [float(i) for i in range(1, 2 * 10**6)]  # a dict scene whose TOML form is too long to store
    with pytest.raises(SceneError, match=r"TOML form is \d+(\.\d+)? MiB; a scene is at most 16 MiB"):
        load_scene({"scene": {"name": "s", "model": "duffing", "outputs": ["period_exact"]},
                    "axes": {"A": values}, "fixed": {"omega": 1.0, "mu": 1.0}})


@pytest.mark.parametrize("kind", ["fifo", "socket", "folder", "huge", "symlink_loop"])
def test_plot_boundaries_path_that_is_not_a_dataset_is_refused(kind, work, capsys, alarm):
    existing_dataset(work / "data" / "runs" / "d.h5")
    name = make_special(kind, work)
    what = {"fifo": "a named pipe (FIFO)", "socket": "a socket", "folder": "a directory",
            "huge": "it is a file of another format, not HDF5", "symlink_loop": "symbolic link loop (ELOOP)"}[kind]
    refused(capsys, ["plot", "data/runs/d.h5", "--boundaries", name], work, f"{name} is not a mechsweep dataset", what)


@pytest.mark.parametrize("command", ["info", "plot"])
def test_an_unreadable_dataset_says_permission_denied(command, work, capsys, monkeypatch):
    import errno

    existing_dataset(work / "data" / "runs" / "d.h5")
    real_open = os.open

    def denied(path, *args, **kwargs):
        if str(path).endswith("d.h5"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(os, "open", denied)
    refused(capsys, [command, "data/runs/d.h5"], work, "data/runs/d.h5 is not a mechsweep dataset: it cannot be read "
            "(permission denied (EACCES))")


# ----------------------------------------------------------------------------- strings a dataset cannot store
USER = Path(__file__).resolve().parent / "user_models" / "unstorable.py"


def user_scene(model: str, output: str = "T", kind: str = "hard") -> str:
    return (f'[scene]\nname = "s"\nmodel = "{USER}:{model}"\noutputs = ["{output}"]\n'
            f'[axes]\nk = [1.0, 4.0]\nkind = [{json_str(kind)}]\n')


def json_str(text: str) -> str:
    import json

    return json.dumps(text)  # a TOML basic string (\\u0000 for a NUL)


UNSTORABLE = {
    "NUL_LONG_NAME": ("T", "hard", ["parameter 'k' long_name 'stiff\\x00ness'", "NUL character", "HDF5 cannot store"]),
    "SURROGATE_UNIT": ("T", "hard", ["parameter 'k': unit 's-2\\udcff'", "not a unit UDUNITS-2 reads"]),
    "NUL_CHOICE": ("T", "soft\0", ["choice of parameter 'kind' 'soft\\x00'", "NUL character"]),
    "NUL_NAME": ("T", "hard", ["model 'lin\\x00ear'", "NUL character"]),
    "SLASH_OUTPUT": ("T/2", "hard", ["output 'T/2'", "must be a Python identifier"]),
    "OUTPUT_NAMED_STATUS": ("status", "hard", ["output 'status' has the name of the run's own variable 'status'"]),
    "OUTPUT_NAMED_LIKE_PARAMETER": ("k", "hard", ["output 'k' has the name of parameter 'k'"]),
    "NUL_REFERENCE": ("T", "hard", ["reference 'a book\\x00'", "NUL character"]),
}


@pytest.mark.parametrize("model", sorted(UNSTORABLE))
def test_a_model_declaring_what_a_dataset_cannot_store_is_refused_at_load(model, work, capsys):
    """Such a string used to pass `check`, compute every point and fail writing the file (a
    traceback, exit 1), and every --resume the same way."""
    output, kind, fragments = UNSTORABLE[model]
    (work / "u.toml").write_text(user_scene(model, output, kind))
    refused(capsys, ["check", "u.toml"], work, "scene.model", *fragments)
    refused(capsys, ["run", "u.toml", "--no-progress"], work, "scene.model", *fragments)


def test_two_outputs_with_one_dimension_name_and_other_values_are_refused(work, capsys):
    """They used to compute, then fail writing the second output into the first's dimension."""
    (work / "u.toml").write_text(f'[scene]\nname = "s"\nmodel = "{USER}:TWO_HISTORIES_ONE_DIMENSION"\n'
                                 'outputs = ["x_history", "v_history"]\n[axes]\nk = [1.0, 4.0]\n')
    refused(capsys, ["check", "u.toml"], work, "outputs 'x_history' and 'v_history' both have a dimension 'period', "
            "with other values")
    (work / "u.toml").write_text(f'[scene]\nname = "s"\nmodel = "{USER}:TWO_HISTORIES_ONE_DIMENSION"\n'
                                 'outputs = ["x_history"]\n[axes]\nk = [1.0, 4.0]\n')
    assert main(["check", "u.toml"]) == 0, capsys.readouterr().err


def test_the_same_model_with_storable_strings_passes(work, capsys):
    (work / "u.toml").write_text(user_scene("FINE"))
    assert main(["check", "u.toml"]) == 0, capsys.readouterr().err


@pytest.mark.parametrize("where", ["scene.name", "scene.description", "fixed.spring"])
def test_a_dict_scene_with_a_lone_surrogate_is_refused(where):
    """From Python a string may hold a lone surrogate; its TOML text, stored with the dataset, could
    not be read back (and the title could not be written)."""
    from mechsweep.scene import SceneError, load_scene

    data = {"scene": {"name": "s", "model": "torsional_circuit", "outputs": ["chi"], "description": "d"},
            "axes": {"lambda2": {"start": 0.1, "stop": 1.0, "num": 3}},
            "fixed": {"spring": "tension", "lambda1": 0.8, "s0_over_r": 0.1}}
    section, key = where.split(".")
    data[section][key] = "bad\udcffvalue"
    with pytest.raises(SceneError, match=re.escape(f"{where}: 'bad\\udcffvalue' contains '\\udcff', a lone surrogate")):
        load_scene(data)


def test_a_model_file_in_a_folder_whose_name_is_not_utf8_is_refused(work):
    """The dataset stores where its model came from (its folder, to read the model again): a path
    with bytes that are not UTF-8 is refused when the scene is loaded, not after the computation."""
    from mechsweep.scene import SceneError, load_scene

    folder = work / os.fsdecode(b"models-\xff")
    folder.mkdir()
    shutil.copy(USER, folder / "m.py")
    (folder / "u.toml").write_text(user_scene("FINE").replace(str(USER), "m.py"))
    with pytest.raises(SceneError, match="the model's path .* lone surrogate .* a path whose name is UTF-8 text"):
        load_scene(folder / "u.toml")


def test_an_output_path_that_is_not_utf8_is_written_with_an_escaped_history(work, monkeypatch):
    """The command line goes into the CF history attribute: an argument whose bytes are not UTF-8
    (a file name) is stored as its escape, not a UnicodeEncodeError after the computation."""
    import h5py

    from mechsweep import cf

    monkeypatch.undo()  # a real run: no tripwires
    monkeypatch.chdir(work)
    (work / "valid.toml").write_text(VALID)
    out = os.fsdecode(b"data/runs/out-\xff.h5")
    token = cf.CLI_ARGS.set(("run", "valid.toml", "-o", out))  # as cli.main sets it
    try:
        runner.compute("valid.toml", output=out, progress=False)
    finally:
        cf.CLI_ARGS.reset(token)
    with h5py.File(out, "r") as f:
        assert "-o 'data/runs/out-\\udcff.h5'" in f.attrs["history"]
    assert os.listdir(work / "data" / "runs") == [os.path.basename(out)]
