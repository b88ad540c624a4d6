"""`mechsweep bench` needs no repository: the scenes it samples ship as package data
(mechsweep/bench/scenes, copies of sweeps/), found through the package, not through a path
relative to the source tree."""
import shutil
import subprocess
import sys

import pytest

from mechsweep.bench import scenes, workprecision, workprecision_linkage

from .conftest import REPO

CASES = dict(workprecision_linkage.CASES)  # the integrated models: workprecision.GENERIC


def test_every_bench_case_has_its_packaged_scene_identical_to_the_shipped_one():
    generic = {scene for _, scene, _, _ in workprecision.GENERIC.values()}  # models on the generic route
    assert set(scenes.names()) == {case.scene for case in CASES.values()} | generic
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
            "from mechsweep.bench import workprecision as w, workprecision_linkage as l, scenes\n"
            "from mechsweep.scene import load_scene\n"
            "assert pathlib.Path(mechsweep.__file__).is_relative_to(pathlib.Path.cwd()), mechsweep.__file__\n"
            "named = {n: c.scene for n, c in l.CASES.items()}\n"
            "named.update({n: g[1] for n, g in w.GENERIC.items()})\n"
            "for name, scene in named.items():\n"
            "    s = load_scene(scenes.path(scene))\n"
            "    assert s.model.name == name, (name, s.model.name)\n"
            "    print(name)\n")
    out = subprocess.run([sys.executable, "-c", code], cwd=site, env={"PATH": "/usr/bin:/bin", "PYTHONPATH": str(site),
                         "MECHSWEEP_NO_CACHE": "1", "HOME": str(tmp_path)}, capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert sorted(line.split()[0] for line in out.stdout.splitlines()) == sorted({**CASES, **workprecision.GENERIC})
