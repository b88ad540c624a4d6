"""The example scenes that ship with mechsweep: every scene of the repository's ``sweeps/`` folder
and the user-model example they use (``models/vibrating_pendulum.py``).

One copy exists: the repository's ``sweeps/`` folder. A wheel carries it as the package data
``mechsweep/sweeps/`` (pyproject.toml maps that package to ``sweeps/``); a source checkout (an
editable install, or ``PYTHONPATH=src``) reads the repository's folder itself. ``mechsweep
examples DIR`` copies them into DIR, so that a pip-installed user can run the quickstart::

    mechsweep examples my-study && cd my-study && mechsweep run sweeps/quickstart.toml
"""
from __future__ import annotations

import importlib.util
import shutil
from pathlib import Path

PACKAGE = "mechsweep.sweeps"  # the package data of a wheel (pyproject.toml: package-dir)
PATTERNS = ("*.toml", "models/*.py")  # what ships: the scenes and the user models they name


def folder() -> Path:
    """The folder of the shipped scenes: the installed package data, else the repository's sweeps/."""
    try:
        spec = importlib.util.find_spec(PACKAGE)
    except ModuleNotFoundError:
        spec = None
    if spec is not None and spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    repo = Path(__file__).resolve().parents[2] / "sweeps"
    if repo.is_dir():
        return repo
    raise FileNotFoundError(f"the example scenes are not installed (no package {PACKAGE}, no {repo})")


def files() -> list[Path]:
    """Every shipped file, relative to ``folder()``, sorted."""
    base = folder()
    return sorted({p.relative_to(base) for pattern in PATTERNS for p in base.glob(pattern) if p.is_file()})


def path(name: str) -> Path:
    """The shipped file ``name`` (e.g. ``quickstart.toml``)."""
    found = folder() / name
    if Path(name) not in files():
        raise FileNotFoundError(f"no shipped example scene {name!r} in {folder()}")
    return found


def copy(dest: str | Path) -> list[Path]:
    """Copy every shipped scene and user model into ``dest``/sweeps/ (made if missing), beside a
    ``data/runs`` folder for the datasets the scenes write by default; an existing file of the same
    name is never replaced (FileExistsError names it, before anything is copied). Returns the
    files written."""
    dest = Path(dest)
    target = dest / "sweeps"
    todo = [(folder() / f, target / f) for f in files()]
    existing = [str(t) for _, t in todo if t.exists() or t.is_symlink()]
    if existing:
        raise FileExistsError(f"{len(existing)} example file(s) exist already, e.g. {existing[0]}; nothing copied "
                              "(choose an empty folder, or remove them)")
    for src, dst in todo:
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)
    (dest / "data" / "runs").mkdir(parents=True, exist_ok=True)
    return [t for _, t in todo]
