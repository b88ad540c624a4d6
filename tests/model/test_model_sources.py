"""A result is computed from one version of the model: the dependency record (model/sources.py).

The record names the model file and every module of the user's that it imports, recursively (a
sibling file the model puts on sys.path, a package on PYTHONPATH, a from-import of a numba
function, a module imported by a helper), the third-party packages and mechsweep itself. It keys
the kernel caches (an edited helper gives a new kernel, never the stale one), and a resume whose
sources differ from those the run began with is refused, naming what changed.
"""
import hashlib
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

import mechsweep
from mechsweep import _jit
from mechsweep.store.journal import partial_path
from mechsweep.model import load, sources

HERE = Path(__file__).resolve().parents[1]

# x'' + K S w^2 x = 0 from x = A: period 2 pi / (w sqrt(K S)). K comes from kit.base through
# kit.springs.k_of (a numba function from-imported by the model), S from the sibling file.
MODEL = '''
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))  # the sibling file beside the model

import sibling
from kit.springs import k_of

from mechsweep.model import OdeModel, Param, Period


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -k_of(p) * sibling.S * p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = p[1]
    y0[1] = 0.0


OSC = OdeModel(name="osc", description="x'' + K S w^2 x = 0",
               params=(Param("w", "w", "rad s-1", "frequency", lo=0.0, lo_open=True),
                       Param("A", "A", "m", "amplitude", lo=0.0, lo_open=True)),
               states=("x", "v"), rhs=rhs, initial=initial, measurements=(Period("period", "x", t_max=100.0),))
'''
FILES = {
    "scenes/models/osc.py": MODEL,
    "scenes/models/sibling.py": "S = 1.0\n",
    "lib/kit/__init__.py": '"""A package of helpers on PYTHONPATH."""\n',
    "lib/kit/springs.py": "import numba\n\nfrom kit.base import K\n\n\n@numba.njit\ndef k_of(p):\n    return K\n",
    "lib/kit/base.py": "K = 1.0\n",
}
SCENE = '''
[scene]
name = "osc"
model = "models/osc.py:OSC"
outputs = ["period"]
[axes]
w = { start = 1.0, stop = 2.0, num = 8 }
[fixed]
A = 0.5
[solver]
rtol = 1e-12
atol = 1e-14
[storage]
chunk_size = 2
'''
MODULE_OF = {"scenes/models/sibling.py": "sibling", "lib/kit/__init__.py": "kit", "lib/kit/springs.py": "kit.springs",
             "lib/kit/base.py": "kit.base"}  # the model file is keyed by its path, not its module name


def _write(root: Path) -> None:
    for rel, text in FILES.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    (root / "scenes" / "osc.toml").write_text(SCENE)


def _sha(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _shown(root: Path, rel: str) -> str:
    """A file's path as the record shows it: relative to the scene's folder under it, else absolute."""
    return rel.removeprefix("scenes/") if rel.startswith("scenes/") else str((root / rel).resolve())


@pytest.fixture
def project(tmp_path, monkeypatch):
    """The files above; in this process, the model imported by its path as a scene loads it (no
    compile), and afterwards the modules, sys.path and the record's memos as they were."""
    _write(tmp_path)
    monkeypatch.setattr(sys, "path", [str(tmp_path / "lib"), *sys.path])
    before = set(sys.modules)
    sources._forget()
    path = (tmp_path / "scenes" / "models" / "osc.py").resolve()
    module = load.import_module(load.module_name(path), str(path))
    yield tmp_path, module
    for name in set(sys.modules) - before:
        del sys.modules[name]
        sources.FILES.pop(name, None)
    sources._forget()


def _fresh_record(module):
    """The record a new process would make now (the edited files hashed again)."""
    sources._forget()
    return sources.record(module.OSC)


# ----------------------------------------------------------------------------- the record
def test_the_record_names_the_model_file_and_every_module_it_imports(project):
    root, module = project
    rec = sources.record(module.OSC)
    base = root / "scenes"
    stored = rec.stored(base)
    by_path = {f["path"]: f for f in stored["files"]}
    assert set(by_path) == {_shown(root, rel) for rel in FILES}, by_path
    for rel in FILES:
        entry = by_path[_shown(root, rel)]
        assert (entry["sha256"], entry["module"]) == (_sha(root / rel), MODULE_OF.get(rel, "")), rel
        assert entry["role"] == ("model" if rel == "scenes/models/osc.py" else "module")
    # third-party packages by version (numba is imported by kit.springs; numpy and numba always), mechsweep
    # by version and sources; the standard library and mechsweep's files are not listed
    assert stored["packages"]["numba"] and stored["packages"]["numpy"] == np.__version__
    assert (stored["mechsweep"], stored["mechsweep_sources"]) == (mechsweep.__version__, _jit.package_hash())
    attrs = rec.attrs(base)
    assert json.loads(attrs["dependencies"]) == stored
    for line in attrs["source_files"].splitlines():  # sha256sum's format, checkable from the scene folder
        sha, name = line.split("  ", 1)
        assert sha == _sha(base / name if not os.path.isabs(name) else Path(name))
    assert sources.record(module.OSC) is rec  # once per model and process
    assert sources.record(module.OSC.spec()).digest == rec.digest  # a ModelSpec made from it (run(models=...))


def test_a_built_in_model_depends_on_mechsweep_alone():
    from mechsweep.models import MODELS

    rec = sources.record(MODELS["duffing"])
    assert rec.files == ()
    stored = rec.stored()
    assert stored["mechsweep_sources"] == _jit.package_hash()
    older = {**stored, "mechsweep_sources": "0123456789abcdef"}
    assert sources.differences(older, rec) == [
        f"mechsweep changed since this run began (version {mechsweep.__version__} -> {mechsweep.__version__}, "
        f"sources 0123456789abcdef -> {_jit.package_hash()})"]


@pytest.mark.parametrize("rel", sorted(FILES))
def test_an_edit_of_any_dependency_is_named_and_changes_the_kernel_keys(project, rel):
    root, module = project
    base = root / "scenes"
    before = sources.record(module.OSC)
    digests = {name: sources.module_digest(name) for name in ("kit.springs", module.__name__)}
    old = _sha(root / rel)
    with open(root / rel, "a") as f:
        f.write("# edited\n")
    after = _fresh_record(module)
    changed = sources.differences(before.stored(base), after, base)
    shown = _shown(root, rel)
    what = f"the module {MODULE_OF[rel]} ({shown})" if rel in MODULE_OF else f"the model file {shown}"
    assert changed == [f"{what} changed since this run began (sha256 {old[:12]}... -> {_sha(root / rel)[:12]}...)"]
    assert after.digest != before.digest  # the generated kernels' names
    # the names of the user's functions the engine compiles (load.jitted): the model's always, kit.springs'
    # (k_of, recompiled with the engine's options) when it or what it imports changed
    assert sources.module_digest(module.__name__) != digests[module.__name__]
    assert (sources.module_digest("kit.springs") != digests["kit.springs"]) == (rel in (
        "lib/kit/springs.py", "lib/kit/base.py", "lib/kit/__init__.py"))


def test_a_constant_computed_at_import_counts_by_its_value(project):
    """numba freezes a global into the code reading it: a value read from a data file or the environment
    at import changes the kernel with no edit of any source (here: K as a new process would read it)."""
    root, module = project
    base = root / "scenes"
    before = sources.record(module.OSC)
    digest = sources.module_digest("kit.springs")
    monkeypatch = pytest.MonkeyPatch()
    try:
        monkeypatch.setattr(sys.modules["kit.base"], "K", 4.0)
        monkeypatch.setattr(sys.modules["kit.springs"], "K", 4.0)  # its from-import of K
        after = _fresh_record(module)
        assert after.digest != before.digest and sources.module_digest("kit.springs") != digest
        reason = ("changed since this run began, its source did not (is it read from a file or the environment at "
                  "import?)")
        assert sources.differences(before.stored(base), after, base) == [
            f"the value of K in module {name} ({(root / rel).resolve()}) {reason}"
            for name, rel in (("kit.base", "lib/kit/base.py"), ("kit.springs", "lib/kit/springs.py"))]
    finally:
        monkeypatch.undo()


def test_unchanged_sources_give_the_same_record_in_every_process(project):
    root, module = project
    first = sources.record(module.OSC)
    again = _fresh_record(module)
    assert again.digest == first.digest and sources.differences(first.stored(root), again, root) == []


def test_a_new_or_dropped_dependency_and_a_package_version_are_named(project):
    root, module = project
    rec = sources.record(module.OSC)
    stored = rec.stored(root / "scenes")
    extra = {"module": "old_helper", "path": "/x/old_helper.py", "sha256": "ab" * 32, "role": "module"}
    dropped = {**stored, "files": [f for f in stored["files"] if f["module"] != "kit.base"] + [extra],
               "packages": {**stored["packages"], "numpy": "1.0.0"}}
    changed = sources.differences(dropped, rec, root / "scenes")
    assert f"the module kit.base ({(root / 'lib/kit/base.py').resolve()}) is a new dependency (not used when " \
           "this run began)" in changed
    assert "the module old_helper (/x/old_helper.py), used when this run began, is no longer a dependency" in changed
    assert f"package numpy changed since this run began (1.0.0 -> {np.__version__})" in changed
    assert len(changed) == 3
    assert sources.differences("{not json", rec) == ["its dependency record is not readable JSON"]


def test_a_dask_worker_with_other_sources_refuses_the_chunk():
    """A worker that would compute with other sources than the client's raises instead."""
    from mechsweep.execution.cluster import compute_chunk
    from mechsweep.errors import InputError
    from mechsweep.chunks import plan_chunks
    from mechsweep.models import MODELS
    from mechsweep.execution.plan import make_plan

    scene = mechsweep.load_scene({"scene": {"name": "q", "model": "duffing", "outputs": ["period_exact"]},
                                  "axes": {"A": [0.1, 0.2]}, "fixed": {"omega": 1.0, "mu": 1.0}})
    stored = sources.record(MODELS["duffing"]).stored()
    other = json.dumps({**stored, "mechsweep_sources": "0123456789abcdef"})
    with pytest.raises(InputError, match="the dask worker would compute from other sources than the client's: "
                                         "mechsweep changed since the run began on the client"):
        compute_chunk(make_plan(scene), plan_chunks(scene.shape, 2)[0], 1, other)


# ----------------------------------------------------------------------------- end to end
STOP_AFTER_FIRST_CHUNK = textwrap.dedent("""
    import sys
    import mechsweep
    from mechsweep.execution import execute, runner

    real, calls = execute.evaluate_chunk, [0]

    def first_only(*args):
        calls[0] += 1
        if calls[0] > 1:
            raise KeyboardInterrupt  # as Ctrl-C after the first chunk
        return real(*args)

    execute.evaluate_chunk = first_only
    try:
        mechsweep.run(sys.argv[1], output=sys.argv[2], progress=False)
    except runner.RunInterrupted as exc:
        print(exc)
""")


def _cache_entries(cache: Path) -> set:
    return {p for p in cache.rglob("*") if p.suffix in (".nbi", ".nbc")}


def test_edits_between_runs_never_mix_models_nor_reuse_a_stale_kernel(tmp_path):
    """The issue's cases, each in a new process as a user meets them: a run interrupted after its
    first chunk; the model file, then a module imported by a helper, edited; --resume refused naming
    the file, the journal untouched; a fresh run with the edited helper computes with it (period
    halved: K = 4), not with the cached kernel of the old one; the sources restored, --resume completes
    the run loading every kernel from the cache (no new cache entry) with one model throughout; after
    another edit, --resume of the finished dataset is refused too."""
    _write(tmp_path)
    cache = tmp_path / "cache"
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join([str(HERE.parent / "src"), str(tmp_path / "lib")]))
    scenes, out = tmp_path / "scenes", tmp_path / "scenes" / "osc.h5"
    part = partial_path(out)

    def cli(*args):
        return subprocess.run([sys.executable, "-m", "mechsweep", *args, "--no-progress", "--threads", "1"],
                              capture_output=True, text=True, env=env, cwd=scenes)

    res = subprocess.run([sys.executable, "-c", STOP_AFTER_FIRST_CHUNK, "osc.toml", str(out)], capture_output=True,
                         text=True, env=env, cwd=scenes)
    assert "journal kept (1 of 4 chunks saved" in res.stdout, res.stdout + res.stderr
    journal = sorted((p.name, p.read_bytes()) for p in part.rglob("*") if p.is_file())
    w = np.linspace(1.0, 2.0, 8)

    for rel, edit in (("scenes/models/osc.py", ("-k_of(p)", "-4.0 * k_of(p)")), ("lib/kit/base.py", ("1.0", "4.0"))):
        original = (tmp_path / rel).read_text()
        old = _sha(tmp_path / rel)
        (tmp_path / rel).write_text(original.replace(*edit))
        res = cli("run", "osc.toml", "-o", str(out), "--resume")
        assert res.returncode == 2, res.stdout + res.stderr
        shown = "models/osc.py" if rel.endswith("osc.py") else str((tmp_path / rel).resolve())
        what = "the model file models/osc.py" if rel.endswith("osc.py") else f"the module kit.base ({shown})"
        assert (f"cannot resume {part}: {what} changed since this run began (sha256 {old[:12]}... -> "
                f"{_sha(tmp_path / rel)[:12]}...); start over with --restart, or restore it and resume") in res.stderr
        assert "Traceback" not in res.stderr
        assert sorted((p.name, p.read_bytes()) for p in part.rglob("*") if p.is_file()) == journal
        if rel == "lib/kit/base.py":  # a fresh run (another output) computes with the edited helper
            res = cli("run", "osc.toml", "-o", str(tmp_path / "edited.h5"))
            assert res.returncode == 0, res.stderr
            edited = mechsweep.open_dataset(tmp_path / "edited.h5")
            np.testing.assert_allclose(edited["period"].values, np.pi / w, rtol=1e-9)  # K = 4, not 1
        (tmp_path / rel).write_text(original)

    entries = _cache_entries(cache)
    res = cli("run", "osc.toml", "-o", str(out), "--resume")
    assert res.returncode == 0, res.stderr
    assert _cache_entries(cache) == entries  # the kernel of these sources came from the cache: nothing compiled
    done = mechsweep.open_dataset(out)
    np.testing.assert_allclose(done["period"].values, 2 * np.pi / w, rtol=1e-9)  # one model: K = 1 throughout
    stored = json.loads(done.attrs["dependencies"])
    assert {f["path"]: f["sha256"] for f in stored["files"]}["models/osc.py"] == _sha(scenes / "models" / "osc.py")
    assert "models/osc.py" in done.attrs["source_files"]
    done.close()

    (tmp_path / "lib/kit/base.py").write_text("K = 2.0\n")
    before = out.read_bytes()
    res = cli("run", "osc.toml", "-o", str(out), "--resume")
    assert res.returncode == 2, res.stdout + res.stderr
    assert f"{out} is finished, but computed from other sources: the module kit.base" in res.stderr
    assert "changed since this dataset was computed" in res.stderr and "`mechsweep run` without --resume" in res.stderr
    assert out.read_bytes() == before


PACKAGE = {
    "mypkg/__init__.py": "",
    "mypkg/consts.py": "C = 1.0\n",
    "mypkg/helpers.py": "import numba\n\nfrom . import consts\n\n\n@numba.njit\ndef factor():\n    return consts.C\n",
    "mypkg/models.py": '''
from mechsweep.model import ClosedFormModel, Output, Param

from .helpers import factor


def compute(p, want, row, curves, slot, scratch):
    row[0] = factor() * p[0]
    return 0


CF = ClosedFormModel(name="scaled", description="y = C x", params=(Param("x", "x", "1", "input", lo=0.0),),
                     outputs=(Output("y", "y", "1", "output"),), compute=compute)
''',
}
BY_SCENE = """
import sys
import mechsweep
ds = mechsweep.run({"scene": {"name": "s", "model": "mypkg.models:CF", "outputs": ["y"]}, "axes": {"x": [1.0, 2.0]}},
                   output=None)
print(ds["y"].values.tolist())
"""
BY_OBJECT = BY_SCENE.replace('"model": "mypkg.models:CF"', '"model": "scaled_obj"').replace(
    "output=None)", "output=None, models={'scaled_obj': __import__('mypkg.models').models.CF})")


def _cache_state(cache: Path) -> dict:
    return {p: p.stat().st_mtime_ns for p in cache.rglob("*") if p.is_file()}


def test_a_closed_form_package_model_gets_a_new_kernel_when_a_module_its_helper_imports_changes(tmp_path):
    """A package on PYTHONPATH (relative imports): models -> helpers (a numba function) -> consts. Each step
    a new process: the kernel follows consts.C; the same sources named from a scene and given as a Python
    object (run(models=...)) share one kernel, and going back to the first sources writes nothing to the
    cache (the first kernel is loaded, not the one of the other C)."""
    for rel, text in PACKAGE.items():
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text(text)
    cache = tmp_path / "cache"
    env = dict(os.environ, MECHSWEEP_CACHE_DIR=str(cache),
               PYTHONPATH=os.pathsep.join([str(HERE.parent / "src"), str(tmp_path)]))

    def y(script):
        res = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env, cwd=tmp_path)
        assert res.returncode == 0, res.stderr
        return json.loads(res.stdout.strip().splitlines()[-1])

    assert y(BY_SCENE) == [1.0, 2.0]
    state = _cache_state(cache)
    assert y(BY_OBJECT) == [1.0, 2.0]
    assert _cache_state(cache) == state  # the same kernel: nothing compiled, no file rewritten
    (tmp_path / "mypkg" / "consts.py").write_text("C = 3.0\n")
    assert y(BY_SCENE) == [3.0, 6.0]  # not the kernel compiled with C = 1
    (tmp_path / "mypkg" / "consts.py").write_text("C = 1.0\n")
    state = _cache_state(cache)
    assert y(BY_SCENE) == [1.0, 2.0] and y(BY_OBJECT) == [1.0, 2.0]
    assert _cache_state(cache) == state
