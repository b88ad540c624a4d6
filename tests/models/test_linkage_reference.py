"""The two linkage models rebuilt on the closed-form layer (mechsweep.model.ClosedFormModel) give the
same bytes as the hand-written chunk kernels they replaced: tests/data/linkage_reference.npz was
recorded with those kernels (tests/data/make_linkage_reference.py, commit db5dda9), except the
four-bar's moved-axis outputs with gravity, recorded again when the counterweight's weight entered
them (make_linkage_reference.py says which). Where the recording code itself gives other bytes on
another machine (tests/data/linkage_reference_alternatives.npz, made by that code there), those
bytes are accepted too."""
from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).resolve().parents[1] / "data"
_spec = importlib.util.spec_from_file_location("make_linkage_reference", DATA / "make_linkage_reference.py")
mk = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mk)


@pytest.fixture(scope="module")
def ref():
    with np.load(DATA / "linkage_reference.npz") as f:
        return {k: f[k] for k in f.files}


@pytest.fixture(scope="module")
def alternatives():
    """{key: hashes the recording code gave for it on another machine}."""
    with np.load(DATA / "linkage_reference_alternatives.npz") as f:
        return {k: set(map(str, f[k])) for k in f.files if k != "machines"}


def compare(ref, got, prefix, alternatives):
    keys = [k for k in ref if k.startswith(prefix)]
    assert keys and set(keys) == {k for k in got if k.startswith(prefix)}
    for k in keys:
        if k.endswith("sha256"):
            if str(ref[k]) != str(got[k]) and str(got[k]) not in alternatives.get(k, ()):
                values = k[:-len("/sha256")]
                if values in ref:  # show where
                    np.testing.assert_array_equal(got[values], ref[values], err_msg=values)
                if values + "/sample" in ref:
                    np.testing.assert_array_equal(got[values + "/sample"], ref[values + "/sample"], err_msg=values)
                pytest.fail(f"{values}: not the same bytes as the recorded kernels")
        else:
            np.testing.assert_array_equal(got[k], ref[k], err_msg=k)


@pytest.mark.parametrize("model", ["fourbar_balancing", "slidercrank_balancing"])
def test_design_grids_are_bitwise_the_recorded_ones(model, ref, alternatives):
    """All outputs, each output alone (every wanted-flag path), the scenes' output lists and 4, 37
    and 1000 crank positions, on random designs of every status."""
    P = (ref[f"grid/{model}/P"], ref[f"grid/{model}/P_curves"])
    compare(ref, mk.record_grid(model, P), f"grid/{model}/", alternatives)


def test_alternatives_are_few_and_differ_from_the_recording(ref, alternatives):
    """The other machine's bytes are an exception for a few named arrays, never a second copy."""
    assert 0 < len(alternatives) <= 12
    for k, hashes in alternatives.items():
        assert k in ref and str(ref[k]) not in hashes


@pytest.mark.parametrize("scene", [pytest.param(s, marks=pytest.mark.slow) if "geometry_family" in s else s
                                   for s in mk.SCENES])
def test_shipped_scenes_are_bitwise_the_recorded_ones(scene, ref, alternatives, tmp_path):
    compare(ref, mk.record_scene(scene, tmp_path), f"scene/{scene}/", alternatives)
