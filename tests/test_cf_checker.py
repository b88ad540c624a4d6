"""The CF checker (PyPI ``cfchecker``, CF up to 1.8) finds no error in a dataset of every shipped
scene, nor in a boundaries dataset: run offline, with the CF tables shipped in tests/data/cf
(README there: their source and version), through tests/data/cf/cfcheck.py in a subprocess (it
may load the UDUNITS-2 library of the cf-units wheel, which must not happen in this process).
The scenes are cut as tests/data/figure_fingerprints.py cuts them (each axis to a few values:
the same variables and attributes; the same kernels as the figure-data test, compiled once)."""
from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
import tomllib

import h5py
import pytest

from .conftest import REPO, SWEEPS

CF = REPO / "tests" / "data" / "cf"


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


cfcheck = _load(CF / "cfcheck.py", "cfcheck")


def _why_not() -> str | None:
    if importlib.util.find_spec("cfchecker") is None:
        return "the CF checker is not installed (pip install cfchecker; it is in the test extra)"
    if cfcheck.udunits()[0] is None:
        return ("no UDUNITS-2 library for the CF checker: neither the system's (libudunits2) nor the one "
                "the cf-units wheel ships")
    return None


pytestmark = pytest.mark.skipif(_why_not() is not None, reason=str(_why_not()))


def check(*paths) -> dict:
    """{path: cfcheck's report} for each netCDF file."""
    out = subprocess.run([sys.executable, str(CF / "cfcheck.py"), *map(str, paths)], capture_output=True, text=True,
                         timeout=300)
    assert out.returncode == 0, out.stderr
    reports = [json.loads(line) for line in out.stdout.splitlines() if line.startswith("{")]
    assert [r["file"] for r in reports] == [str(p) for p in paths], out.stdout + out.stderr
    return {r["file"]: r for r in reports}


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """A dataset of each shipped scene, cut to a few points per axis."""
    import mechsweep
    from mechsweep.scene import load_scene_text, to_toml

    fp = _load(REPO / "tests" / "data" / "figure_fingerprints.py", "figure_fingerprints")
    folder = tmp_path_factory.mktemp("cf")
    paths = []
    for path in sorted(SWEEPS.glob("*.toml")):
        data = fp.reduce_scene(tomllib.loads(path.read_text()))
        data.setdefault("storage", {})["path"] = str(folder / f"{path.stem}.h5")
        scene = load_scene_text(to_toml(data), label=path.name, base=path.parent)
        mechsweep.run(scene, output=folder / f"{path.stem}.h5", progress=False)
        paths.append(folder / f"{path.stem}.h5")
    return paths


def test_every_shipped_scenes_dataset_passes_the_cf_checker(shipped):
    assert len(shipped) == len(list(SWEEPS.glob("*.toml"))) >= 13
    reports = check(*shipped)
    bad = {p: r["messages"] for p, r in reports.items() if r["counts"]["FATAL"] or r["counts"]["ERROR"]}
    assert not bad, json.dumps(bad, indent=1)
    assert {r["version"] for r in reports.values()} == {"CF-1.8"}  # read from the files' Conventions


def test_a_boundaries_dataset_with_a_categorical_axis_passes_the_cf_checker(in_tmp):
    from mechsweep.boundaries import run_boundaries

    scene = {"scene": {"name": "sep", "model": "torsional_circuit", "outputs": ["chi", "xi"]},
             "axes": {"lambda2": {"start": 0.1, "stop": 2.0, "num": 6}, "spring": ["tension", "compression"]},
             "fixed": {"lambda1": 0.8, "s0_over_r": 0.2},
             "boundaries": {"along": "lambda2", "criterion": "xi", "level": 0.0}, "storage": {"path": "sep.h5"}}
    path, _ = run_boundaries(scene, output="sep.boundaries.h5")
    report = check(path)[str(path)]
    assert report["counts"]["ERROR"] == report["counts"]["FATAL"] == 0, report["messages"]


def test_the_checker_sees_what_it_must_refuse(shipped, tmp_path):
    """Not blind: a CF version label it cannot verify, and a standard name not in the table, are errors."""
    nomogram = next(p for p in shipped if p.stem == "torsional_circuit_nomogram")
    label, name = tmp_path / "label.h5", tmp_path / "name.h5"
    shutil.copy(nomogram, label)
    shutil.copy(nomogram, name)
    with h5py.File(label, "r+") as f:
        f.attrs["Conventions"] = "CF-1.10"
    with h5py.File(name, "r+") as f:
        f["status"].attrs["standard_name"] = "no_such_standard_name"
    reports = check(label, name)
    assert any(m.startswith("ERROR global") for m in reports[str(label)]["messages"]), reports[str(label)]
    assert "ERROR status: (3.3): Invalid standard_name: no_such_standard_name" in reports[str(name)]["messages"]
