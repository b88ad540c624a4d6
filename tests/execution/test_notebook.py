"""Progress where users work: a Jupyter notebook (executed with nbclient in a real kernel) that
shows a scene and runs it gets the scene as an HTML table, the compile note naming the model, and
a progress bar (tqdm.auto: a widget when ipywidgets is installed, else text). Off a terminal, a run
writes a progress line now and then, with the points done and an ETA; `Scene` has a short repr."""
from __future__ import annotations

import json
import sys

import pytest

import mechsweep
from mechsweep.execution import progress

SCENE = {"scene": {"name": "nb", "model": "duffing", "outputs": ["period_exact", "kv"]},
         "axes": {"A": {"start": 0.1, "stop": 1.0, "num": 30}, "mu": {"start": 0.1, "stop": 10.0, "num": 20}},
         "fixed": {"omega": 2.0}}


def test_a_notebook_shows_the_scene_the_compile_note_and_a_progress_bar(tmp_path, monkeypatch):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    pytest.importorskip("ipykernel")
    monkeypatch.setenv("MECHSWEEP_NO_CACHE", "1")  # the kernel compiles (a cache hit may be too quick to announce)
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(f"import mechsweep\nscene = mechsweep.load_scene({SCENE!r})\nscene"),
                nbformat.v4.new_code_cell("ds = mechsweep.run(scene, output='nb.h5')\nprint(dict(ds.sizes))")]
    nbclient.NotebookClient(nb, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(tmp_path)}}).execute()
    shown = nb.cells[0].outputs[0]["data"]
    assert "<table>" in shown["text/html"] and "duffing" in shown["text/html"], shown
    assert shown["text/plain"].startswith("<Scene 'nb': model duffing, 600 points (A 30 x mu 20)"), shown
    outputs = nb.cells[1].outputs
    text = "".join(o.get("text", "") for o in outputs if o["output_type"] == "stream")
    assert "compiling kernels for model duffing (first run; cached afterwards)" in text, outputs
    assert "{'A': 30, 'mu': 20}" in text, outputs
    widgets = [o for o in outputs if "application/vnd.jupyter.widget-view+json" in o.get("data", {})]
    bar_text = "nb: 100%" in text or "600/600" in text
    assert widgets or bar_text, json.dumps([dict(o) for o in outputs], indent=1, default=str)[:3000]


def test_off_a_terminal_a_run_reports_progress_now_and_then(in_tmp, monkeypatch, capsys):
    monkeypatch.setattr(progress, "PROGRESS_LOG_EVERY", 0.0)  # a line at every chunk
    monkeypatch.setattr(sys.stderr, "isatty", lambda: False, raising=False)
    scene = {**SCENE, "storage": {"chunk_size": 200}}
    mechsweep.run(scene, output="log.h5")  # progress=None: stderr is no terminal -> a log
    lines = [line for line in capsys.readouterr().err.splitlines() if line.startswith("mechsweep: nb: ")]
    assert lines[:2] == ["mechsweep: nb: 200 / 600 points, 33.3 %, ETA 0 s",
                         "mechsweep: nb: 400 / 600 points, 66.7 %, ETA 0 s"][:len(lines[:2])], lines
    assert len(lines) == 3 and lines[-1].startswith("mechsweep: nb: 600 / 600 points, 100 %, in "), lines
    mechsweep.run(scene, output="quiet.h5", progress=False)
    assert "mechsweep: nb:" not in capsys.readouterr().err


def test_the_progress_line_and_its_eta(monkeypatch, capsys):
    now = [100.0]
    monkeypatch.setattr(progress.time, "monotonic", lambda: now[0])
    log = progress.LogProgress("big", 1_000_000)
    now[0] += 10.0
    log.update(5_000)  # 10 s since the start: too early for a line
    now[0] += 25.0
    log.update(7_000)  # 35 s: 12,000 points at 343 points/s -> 988,000 left: 48 min
    assert capsys.readouterr().err == "mechsweep: big: 12,000 / 1,000,000 points, 1.2 %, ETA 48 min\n"
    log.close()  # not finished: no closing line
    assert capsys.readouterr().err == ""
    assert progress.duration(40) == "40 s" and progress.duration(180) == "3 min" and progress.duration(9000) == "2.5 h"


def test_scene_repr_is_one_line():
    scene = mechsweep.load_scene(SCENE)
    assert repr(scene) == "<Scene 'nb': model duffing, 600 points (A 30 x mu 20), outputs period_exact, kv>"
    html = scene._repr_html_()
    assert html.count("<tr>") == 7 and "[rad s-1]" in html and "data/runs/nb.h5" in html, html
