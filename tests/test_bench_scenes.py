"""`mechsweep bench` needs no repository: the scenes it samples ship as package data
(mechsweep/bench/scenes, copies of sweeps/), found through the package, not through a path
relative to the source tree."""
import shutil
import subprocess
import sys

import pytest

from mechsweep.bench import scenes, workprecision

from .conftest import REPO

# every built-in model declares the scene of its work-precision report (OdeModel / ClosedFormModel
# workprecision=...): a shipped sweeps/NAME.toml, found through the package's copy
DECLARED = {name: workprecision.resolve_model(name).declaration.workprecision.scene for name in workprecision.all_cases()}


def test_every_bench_case_has_its_packaged_scene_identical_to_the_shipped_one():
    assert sorted(DECLARED) == sorted(["duffing", "torsional_circuit", "autobalancer", "fourbar_balancing",
                                       "slidercrank_balancing"])
    assert all(scene.startswith("sweeps/") for scene in DECLARED.values())
    assert set(scenes.names()) == {scene.removeprefix("sweeps/") for scene in DECLARED.values()}
    for name, scene in DECLARED.items():  # the declared scene resolves to the packaged copy, named as shipped
        path, label = workprecision.declared_scene(workprecision.resolve_model(name).declaration.workprecision)
        assert path == scenes.path(scene.removeprefix("sweeps/")) and label == scene
    for name in scenes.names():
        assert scenes.path(name).read_bytes() == (REPO / "sweeps" / name).read_bytes(), \
            f"src/mechsweep/bench/scenes/{name} differs from sweeps/{name}: copy it again"


def test_an_unknown_packaged_scene_is_refused_by_name():
    with pytest.raises(FileNotFoundError, match="no_such.toml"):
        scenes.path("no_such.toml")


def test_bench_scenes_load_from_an_installed_package_without_the_repository(tmp_path):
    """Build the package as an install does (setuptools build_py with this pyproject.toml: the
    .py files and the declared package data), put it where no sweeps/ folder is near, and load
    every bench case's default scene there in a fresh interpreter."""
    src = tmp_path / "project"
    shutil.copytree(REPO / "src", src / "src", ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
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
