"""`mechsweep bench` needs no repository: the scenes it samples are the shipped example scenes
(mechsweep.examples: the repository's sweeps/, installed with the package as mechsweep/sweeps/),
found through the package, not through a path relative to the working directory."""
import shutil
import subprocess
import sys

import pytest

from mechsweep import examples
from mechsweep.bench import workprecision

from tests.conftest import REPO

# every built-in model declares the scene of its work-precision report (OdeModel / ClosedFormModel
# workprecision=...): a shipped sweeps/NAME.toml, found through the package
DECLARED = {name: workprecision.resolve_model(name).declaration.workprecision.scene for name in workprecision.all_cases()}


def test_every_bench_case_finds_its_shipped_scene_through_the_package(tmp_path, monkeypatch):
    assert sorted(DECLARED) == sorted(["duffing", "torsional_circuit", "autobalancer", "fourbar_balancing",
                                       "slidercrank_balancing"])
    assert all(scene.startswith("sweeps/") for scene in DECLARED.values())
    monkeypatch.chdir(tmp_path)  # no sweeps/ folder here
    for name, scene in DECLARED.items():  # the declared scene resolves to the shipped one, named as shipped
        path, label = workprecision.declared_scene(workprecision.resolve_model(name).declaration.workprecision)
        assert path == examples.path(scene.removeprefix("sweeps/")) and label == scene
        assert path.read_bytes() == (REPO / scene).read_bytes()


def test_an_unknown_shipped_scene_is_refused_by_name():
    with pytest.raises(FileNotFoundError, match="no_such.toml"):
        examples.path("no_such.toml")


def test_bench_scenes_load_from_an_installed_package_without_the_repository(tmp_path):
    """Build the package as an install does (setuptools build_py with this pyproject.toml: the
    .py files and the declared package data, the shipped scenes among them), put it where no sweeps/
    folder is near, and load
    every bench case's default scene there in a fresh interpreter."""
    src = tmp_path / "project"
    shutil.copytree(REPO / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    shutil.copytree(REPO / "sweeps", src / "sweeps")  # the package data mechsweep.sweeps
    shutil.copy(REPO / "pyproject.toml", src)
    shutil.copy(REPO / "README.md", src)
    site = tmp_path / "site"
    subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()", "-q", "build_py",
                    "--build-lib", str(site)], cwd=src, check=True, capture_output=True)
    shutil.rmtree(src)  # nothing of the source tree is left
    code = ("import mechsweep, pathlib\n"
            "from mechsweep.bench import workprecision as w\n"
            "from mechsweep.scene import load_scene\n"
            "assert pathlib.Path(mechsweep.__file__).is_relative_to(pathlib.Path.cwd()), mechsweep.__file__\n"
            "for name in w.all_cases():\n"
            "    path, _ = w.declared_scene(w.resolve_model(name).declaration.workprecision)\n"
            "    assert pathlib.Path(path).is_relative_to(pathlib.Path.cwd()), path\n"
            "    s = load_scene(path)\n"
            "    assert s.model.name == name, (name, s.model.name)\n"
            "    print(name)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=site, env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(site),
                         "MECHSWEEP_NO_CACHE": "1", "HOME": str(tmp_path)}, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert sorted(line.split()[0] for line in out.stdout.splitlines()) == sorted(DECLARED)
