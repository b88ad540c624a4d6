"""What a pip user gets. The wheel carries the shipped scenes (and no tests): built from a copy of
this repository and installed into a fresh virtual environment (the dependencies come from this
environment: --system-site-packages, nothing downloaded), it runs the quickstart from an empty
folder with `mechsweep examples`, as the README says. The sdist holds every file of the repository,
so that its tests and docs run from it. `mechsweep examples DIR` copies the shipped scenes, which
are the repository's sweeps/ itself (one copy)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tarfile
import tomllib
import zipfile
from pathlib import Path

import pytest

from mechsweep import examples
from mechsweep.cli import main

from .conftest import REPO, SWEEPS

SHIPPED = sorted([p.name for p in SWEEPS.glob("*.toml")] + ["models/vibrating_pendulum.py"])


def _tracked() -> list[str] | None:
    """The repository's files (git ls-files), or None outside a git checkout (an unpacked sdist)."""
    if not (REPO / ".git").exists() or shutil.which("git") is None:
        return None
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True)
    return sorted(f for f in out.stdout.decode().split("\0") if f and (REPO / f).is_file())


def _copy_project(dest: Path) -> Path:
    """The repository's files (without build output, caches and run outputs) under ``dest``."""
    files = _tracked()
    if files is None:
        skip = {"build", "dist", ".git", "__pycache__", ".pytest_cache", ".hypothesis", "_build"}
        files = [str(p.relative_to(REPO)) for p in REPO.rglob("*") if p.is_file()
                 and not skip & set(p.relative_to(REPO).parts) and ".egg-info" not in str(p)
                 and not str(p.relative_to(REPO)).startswith(("data/runs/", "data/bench/"))]
    for f in files:
        (dest / f).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(REPO / f, dest / f)
    return dest


def _env(**extra) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # the installed package, not this checkout
    return {**env, "PIP_NO_INDEX": "1", "PIP_DISABLE_PIP_VERSION_CHECK": "1", **extra}


def test_the_package_list_is_every_package_of_src_and_the_scenes():
    from setuptools import find_packages

    conf = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert sorted(conf["packages"]) == sorted(find_packages(REPO / "src") + ["mechsweep.sweeps"])
    assert conf["package-dir"]["mechsweep.sweeps"] == "sweeps"


def test_examples_are_the_repositorys_sweeps_and_copy_into_a_folder(tmp_path, capsys):
    assert examples.folder().resolve() == SWEEPS.resolve()
    assert [str(f) for f in examples.files()] == SHIPPED
    assert main(["examples", str(tmp_path / "study")]) == 0
    out = capsys.readouterr().out
    assert "mechsweep run sweeps/quickstart.toml" in out, out
    for name in SHIPPED:
        assert (tmp_path / "study" / "sweeps" / name).read_bytes() == (SWEEPS / name).read_bytes(), name
    assert (tmp_path / "study" / "data" / "runs").is_dir()
    copied = sorted(str(p.relative_to(tmp_path / "study" / "sweeps")) for p in (tmp_path / "study" / "sweeps").rglob("*")
                    if p.is_file())
    assert copied == SHIPPED
    # a second copy replaces nothing: refused, exit 2, a message naming a file
    (tmp_path / "study" / "sweeps" / "quickstart.toml").write_text("# mine\n")
    assert main(["examples", str(tmp_path / "study")]) == 2
    assert "exist already" in capsys.readouterr().err
    assert (tmp_path / "study" / "sweeps" / "quickstart.toml").read_text() == "# mine\n"
    (tmp_path / "file").write_text("x")
    assert main(["examples", str(tmp_path / "file")]) == 2
    assert "not a folder" in capsys.readouterr().err


def test_the_sdist_holds_every_file_of_the_repository(tmp_path):
    files = _tracked()
    if files is None:
        pytest.skip("not a git checkout: the list of the repository's files is git's")
    project = _copy_project(tmp_path / "project")
    subprocess.run([sys.executable, "-c", "from setuptools import setup; setup()", "-q", "sdist", "-d",
                    str(tmp_path / "dist")], cwd=project, check=True, capture_output=True, env=_env())
    (sdist,) = (tmp_path / "dist").glob("mechsweep-*.tar.gz")
    with tarfile.open(sdist) as tar:
        names = {n.split("/", 1)[1] for n in tar.getnames() if "/" in n}
    missing = [f for f in files if f not in names]
    assert not missing, f"the sdist lacks {len(missing)} file(s) of the repository (MANIFEST.in): {missing[:10]}"


def test_the_wheel_runs_the_quickstart_from_an_empty_folder(tmp_path):
    project = _copy_project(tmp_path / "project")
    dist = tmp_path / "dist"
    build = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-w", str(dist),
                            str(project)], capture_output=True, text=True, env=_env(), timeout=600)
    assert build.returncode == 0, build.stdout[-2000:] + build.stderr[-2000:]
    (wheel,) = dist.glob("mechsweep-*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = set(z.namelist())
    assert {f"mechsweep/sweeps/{name}" for name in SHIPPED} <= names
    assert not [n for n in names if n.startswith(("tests/", "sweeps/", "mechsweep/sweeps/extreme"))], sorted(names)[:20]

    venv = tmp_path / "venv"  # pip of this environment runs in it (no pip of its own: nothing to download)
    subprocess.run([sys.executable, "-m", "venv", "--system-site-packages", "--without-pip", str(venv)], check=True)
    python, bindir = venv / "bin" / "python", venv / "bin"
    install = subprocess.run([str(python), "-m", "pip", "install", "--no-deps", str(wheel)], capture_output=True,
                             text=True, env=_env(), timeout=600)
    assert install.returncode == 0, install.stdout[-2000:] + install.stderr[-2000:]
    empty = tmp_path / "user"
    empty.mkdir()
    env = _env(PATH=f"{bindir}{os.pathsep}{os.environ.get('PATH', '')}")
    where = subprocess.run([str(python), "-c", "import mechsweep, mechsweep.examples as e; "
                            "print(mechsweep.__file__); print(e.folder())"], cwd=empty, capture_output=True, text=True,
                           env=env, check=True).stdout.split()
    assert all(Path(w).is_relative_to(venv) for w in where), where  # the wheel, not this checkout
    steps = (["mechsweep", "examples", "."], ["mechsweep", "run", "sweeps/quickstart.toml"],
             ["mechsweep", "plot", "data/runs/quickstart.h5"])
    for cmd in steps:
        out = subprocess.run(cmd, cwd=empty, capture_output=True, text=True, env=env, timeout=600)
        assert out.returncode == 0, (cmd, out.stdout[-2000:], out.stderr[-2000:])
    assert (empty / "data" / "runs" / "quickstart.h5").is_file()
    assert sorted(p.name for p in (empty / "data" / "runs").glob("*.png")) == [
        "quickstart_amplitude_period.png", "quickstart_kinematic_coefficients.png"]
