"""Committed figures stay true to the code and the scenes: the data every figure draws, regenerated
from the shipped scenes at reduced size, matches a stored fingerprint (tests/data/
figure_fingerprints.json, rewritten by tests/data/figure_fingerprints.py), and each of those figures
reads well (tests/figures/figure_checks.py: no tick labels running into one another, symbols in mathtext,
no literal underscores, legends off the data); every committed PNG was written by
docs/make_figures.py from the code and scene that are here now (docs/figures/MANIFEST.json);
importing and drawing change no matplotlib global state."""
import hashlib
import importlib.util
import json
import subprocess
import sys

import pytest

from . import figure_checks
from tests.conftest import REPO

FIGS = REPO / "docs" / "figures"


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


fingerprints = _load(REPO / "tests" / "data" / "figure_fingerprints.py", "figure_fingerprints")


@pytest.fixture(scope="module")
def shipped(tmp_path_factory):
    """(datasets, figures) of every shipped scene, each axis cut to a few values: run and drawn
    once for the tests of this module."""
    datasets = fingerprints.reduced_datasets(tmp_path_factory.mktemp("shipped"))
    return datasets, fingerprints.drawn_figures(datasets)


def test_every_figures_data_matches_its_fingerprint(shipped):
    """All shipped scenes, each axis cut to a few values: what each figure draws (lines, markers,
    meshes, contours) has the stored size, finite count and sums (rtol 1e-6)."""
    want = json.loads(fingerprints.STORE.read_text())
    got = fingerprints.fingerprints(None, drawn=shipped[1])
    bad = fingerprints.compare(got, want)
    assert not bad, ("figure data differ from tests/data/figure_fingerprints.json (if intended: "
                     "python tests/data/figure_fingerprints.py, and regenerate docs/figures):\n" + "\n".join(bad))


def test_every_default_figure_of_every_shipped_scene_reads_well(shipped):
    """On each figure of each shipped scene (at reduced size, so with few values on its axes): no two
    tick labels of an axis overlap (their rendered extents), no text prints an underscore, no legend
    lies over its panel's data, and every axis label naming a variable with a symbol shows it in
    mathtext."""
    datasets, drawn = shipped
    problems = [f"{stem} {kind}: {p}" for stem, figs in drawn.items() for kind, fig in figs.items()
                for p in figure_checks.check_readable(fig, datasets[stem])]
    assert not problems, "\n".join(problems)


def test_every_figure_title_says_what_it_shows_and_not_the_scene_name(shipped):
    """The scene's name is the file's, not a title: it is in the caption's last line (as code)."""
    datasets, drawn = shipped
    for stem, figs in drawn.items():
        name = str(datasets[stem].attrs.get("title", ""))
        for kind, fig in figs.items():
            head = fig._suptitle.get_text() if fig._suptitle is not None else ""
            assert head and name not in head, (stem, kind, head)


def test_fingerprint_comparison_sees_a_changed_value_and_forgives_the_last_ulp():
    want = {"s": {"f": [[3, 3, 6.0, 6.0]]}}
    assert fingerprints.compare({"s": {"f": [[3, 3, 6.0 * (1 + 4e-16), 6.0]]}}, want) == []
    assert fingerprints.compare({"s": {"f": [[3, 3, 6.001, 6.001]]}}, want)
    assert fingerprints.compare({"s": {"f": [[3, 2, 6.0, 6.0]]}}, want)
    assert fingerprints.compare({"s": {}}, want)


make_figures = _load(REPO / "docs" / "make_figures.py", "make_figures")


def test_committed_figures_are_not_older_than_the_code_that_draws_them():
    """Each PNG in docs/figures has a manifest entry whose hash of the drawing code and scene is
    that of the files here now, and whose PNG hash is the file's: regenerate with
    python docs/make_figures.py after changing a figure's code or scene."""
    manifest = json.loads(make_figures.MANIFEST.read_text())
    pngs = sorted(p.name for p in FIGS.glob("*.png"))
    assert sorted(manifest) == pngs, "docs/figures and MANIFEST.json list different figures"
    stale = []
    for name, e in manifest.items():
        missing = [f for f in e["files"] if not (REPO / f).is_file()]
        if missing:
            stale.append(f"{name}: drawn by {', '.join(missing)}, which no longer exist")
        elif make_figures.code_hash(e["files"]) != e["code_sha256"]:
            stale.append(f"{name}: {', '.join(e['files'])} changed since it was drawn")
        if hashlib.sha256((FIGS / name).read_bytes()).hexdigest() != e["png_sha256"]:
            stale.append(f"{name}: the PNG is not the one docs/make_figures.py wrote")
    assert not stale, "stale figures (python docs/make_figures.py regenerates them):\n" + "\n".join(stale)


def test_the_staleness_hash_sees_a_changed_file(tmp_path, monkeypatch):
    (tmp_path / "a.py").write_text("x = 1\n")
    monkeypatch.setattr(make_figures, "ROOT", tmp_path)
    before = make_figures.code_hash(["a.py"])
    (tmp_path / "a.py").write_text("x = 2\n")
    assert make_figures.code_hash(["a.py"]) != before


STATE = r"""
import sys, matplotlib
matplotlib.use("svg")  # the user's choice, made before importing mechsweep
before = dict(dict.items(matplotlib.rcParams))
import mechsweep, mechsweep.figures, mechsweep.cli
after_import = dict(dict.items(matplotlib.rcParams))
sys.path.insert(0, sys.argv[1])
from test_generic_figures import cam
from mechsweep import figures
for kind in figures.available(cam()):
    figures.draw(cam(), kind).savefig(sys.argv[2] + f"/{kind}.png")
after_draw = dict(dict.items(matplotlib.rcParams))
print(before == after_import, before == after_draw, matplotlib.get_backend(),
      "matplotlib.pyplot" in sys.modules)
"""


def test_import_and_drawing_leave_the_backend_and_rcparams_alone(tmp_path):
    """In a fresh interpreter: the backend the user chose and every rcParam are the same after
    importing mechsweep (figures and CLI) and after drawing and saving figures; pyplot is never
    imported."""
    import os
    from pathlib import Path

    import mechsweep

    here = str(Path(mechsweep.__file__).resolve().parents[1])  # the mechsweep under test, not another install
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([here, os.environ.get("PYTHONPATH", "")])}
    out = subprocess.run([sys.executable, "-c", STATE, str(REPO / "tests" / "figures"), str(tmp_path)], capture_output=True,
                         text=True, timeout=300, cwd=tmp_path, env=env)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.split() == ["True", "True", "svg", "False"], out.stdout
