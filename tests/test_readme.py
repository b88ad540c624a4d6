"""README.md is the front door; the documentation site (docs/) holds the rest. The glossary page
matches the models word for word, the two set-up commands exist, every shipped scene is shown."""
import re

from mechsweep import docs
from mechsweep.models import MODELS

from .conftest import REPO

README = (REPO / "README.md").read_text()
GLOSSARY = REPO / "docs" / "glossary.md"
GALLERY = (REPO / "docs" / "gallery.md").read_text()


def test_glossary_page_is_generated_from_the_models():
    """The whole docs/glossary.md page, word for word, is what the declarations generate."""
    assert GLOSSARY.read_text() == docs.glossary(), \
        "docs/glossary.md differs from the declarations: regenerate it with `python -m mechsweep.docs docs/glossary.md`"
    assert docs.glossary_section(GLOSSARY.read_text()) == docs.glossary()


def test_glossary_covers_every_built_in_model_and_status():
    from mechsweep import status as st

    text = docs.glossary()
    for spec in MODELS.values():
        assert f"## `{spec.name}`" in text
        for name in spec.param_names() + spec.output_names():
            assert f"| `{name}` |" in text, (spec.name, name)
    for code, meaning in st.MEANINGS.items():
        assert f"| {code} | `{meaning}` | {st.DESCRIPTIONS[code]} |" in text


def test_glossary_of_a_model_it_has_never_heard_of():
    """A user model (tests/user_models/mathieu.py): its parameters, outputs, the setting its Floquet
    measurement adds and the statuses derived from its outputs (none declared)."""
    from mechsweep import status as st
    from mechsweep.model import user

    spec = user.resolve(str(REPO / "tests" / "user_models" / "mathieu.py") + ":MATHIEU")
    text = docs.glossary([spec])
    assert text.startswith("# Glossary\n") and f"## `{spec.name}`: {spec.description}" in text
    for name in spec.param_names() + spec.output_names() + tuple(s.name for s in spec.settings):
        assert f"| `{name}` |" in text, name
    derived = spec.possible_statuses()
    assert st.UNDECIDED in derived and st.INFEASIBLE in derived and st.MAX_STEPS in derived
    assert "Statuses (derived from its outputs): " + ", ".join(f"`{st.MEANINGS[c]}`" for c in derived) in text


def test_regenerating_the_glossary_page_restores_it(tmp_path):
    page = tmp_path / "glossary.md"
    original = GLOSSARY.read_text()
    page.write_text(original.replace("| `omega` | $\\omega$ |", "| `omega` | w |", 1))
    assert docs.glossary_section(page.read_text()) != docs.glossary()
    assert docs.write_page(page) is True
    assert page.read_text() == original
    assert docs.write_page(page) is False


def test_ci_runs_the_readme_test_command():
    ci = (REPO / ".ci" / "run").read_text()
    command = re.search(r"^pip install -e \"\.\[test\]\".*$", ci, re.M).group(0)
    assert command in README


def test_every_shipped_scene_is_mentioned_in_the_readme_and_shown_in_the_gallery():
    for path in (REPO / "sweeps").glob("*.toml"):
        assert f"sweeps/{path.name}" in README, path.name
        assert f"`sweeps/{path.name}`" in GALLERY, path.name


def test_readme_is_a_front_door():
    """At most ~250 lines, one figure per study, and it says how to build and open the docs."""
    assert len(README.splitlines()) <= 250
    assert README.count("![") <= 6
    assert "python -m sphinx -W --keep-going -b html docs docs/_build/html" in README
    assert "docs/_build/html/index.html" in README


def test_models_markdown_prints_the_glossary_page(capsys):
    from mechsweep.cli import main

    assert main(["models", "--markdown"]) == 0
    assert capsys.readouterr().out == GLOSSARY.read_text()
