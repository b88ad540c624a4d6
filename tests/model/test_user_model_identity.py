"""A scene names a user model by its name AND the source it is declared in: two model files
declaring a model of the same name are two scenes (a re-run or --resume never mixes them), the
same file is the same scene (re-runs stay idempotent), and datasets of older versions, whose
canonical form named the model by its name only, are still recognised through their scene text."""
import json

import pytest

import mechsweep
from mechsweep.errors import StoreError
from mechsweep.execution.checks import same_scene
from mechsweep.scene import load_scene, load_scene_text

MODEL = '''
from mechsweep.model import OdeModel, Param, StateAt


def rhs(t, y, p, dydt):
    dydt[0] = y[1]
    dydt[1] = -{k} * p[0] * p[0] * y[0]


def initial(p, y0):
    y0[0] = 1.0
    y0[1] = 0.0


OSC = OdeModel(name="osc", description="x'' + {k} w^2 x = 0", params=(Param("w", "w", "rad/s", "frequency", lo=0.0),),
               states=("x", "v"), rhs=rhs, initial=initial, measurements=(StateAt("x1", "x", t=1.0),))
'''

SCENE = '''
[scene]
name = "osc"
model = "m.py:OSC"
outputs = ["x1"]
[axes]
w = [0.5, 1.0, 2.0]
[storage]
path = "osc.h5"
'''


@pytest.fixture
def two_files(tmp_path):
    """Two folders, each a model file m.py declaring OSC (name "osc") with different physics, and
    the same scene text beside it."""
    scenes = []
    for folder, k in (("a", "1.0"), ("b", "2.0")):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "m.py").write_text(MODEL.replace("{k}", k))
        (tmp_path / folder / "scene.toml").write_text(SCENE)
        scenes.append(tmp_path / folder / "scene.toml")
    return scenes


def _old_form(scene) -> str:
    """The canonical form older versions wrote: the model by its name only."""
    form = json.loads(scene.canonical())
    del form["model_source_sha256"]
    return json.dumps(form, sort_keys=True)


def test_two_files_declaring_one_model_name_are_two_scenes(two_files, monkeypatch):
    a, b = (load_scene(p) for p in two_files)
    assert a.model.name == b.model.name == "osc" and a.text == b.text
    assert a.canonical() != b.canonical()
    assert not a.same_as(b.canonical()) and not b.same_as(a.canonical())
    assert not same_scene({"scene_canonical": a.canonical(), "scene": a.text, "scene_folder": a.base}, b)
    # the same file is the same scene, however the scene names it and from wherever it is loaded
    monkeypatch.chdir(two_files[0].parent.parent)
    again = load_scene(str(two_files[0].relative_to(two_files[0].parent.parent)))
    assert again.canonical() == a.canonical()
    text = SCENE.replace('"m.py:OSC"', json.dumps(str(two_files[0].parent / "m.py") + ":OSC"))
    assert load_scene_text(text).canonical() == a.canonical()


def test_built_in_models_keep_their_canonical_form():
    scene = load_scene({"scene": {"name": "q", "model": "duffing", "outputs": ["period"]},
                        "axes": {"A": [0.1]}, "fixed": {"omega": 1.0, "mu": 1.0}})
    assert scene.model_key == "" and "model_source_sha256" not in json.loads(scene.canonical())


def test_a_dataset_of_an_older_version_is_recognised_by_its_scene_text(two_files):
    a, b = (load_scene(p) for p in two_files)
    old = {"scene_canonical": _old_form(a), "scene": a.text, "scene_folder": a.base}
    assert not a.same_as(old["scene_canonical"])  # the form changed ...
    assert same_scene(old, a)  # ... the text, re-read against its folder, says it is this scene
    assert not same_scene(old, b)  # and not the other file's


@pytest.mark.slow  # compiles a kernel for a fresh model file: ~10-60 s depending on the load
def test_rerun_is_idempotent_and_another_file_is_refused(two_files, tmp_path):
    out = tmp_path / "osc.h5"
    a, b = (load_scene(p) for p in two_files)
    first = mechsweep.run(a, output=out, progress=False).load()
    again = mechsweep.run(a, output=out, progress=False).load()  # same scene: replaced, no flag needed
    assert (first["x1"].values == again["x1"].values).all()
    with pytest.raises(StoreError, match="different scene"):
        mechsweep.run(b, output=out, progress=False)
    assert (mechsweep.open_dataset(out)["x1"].values == first["x1"].values).all()  # kept
