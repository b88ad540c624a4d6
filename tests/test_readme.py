"""README.md promises: the glossary matches the models, and the two set-up commands exist."""
import re

from mechsweep.cli import model_markdown
from mechsweep.models import MODELS

from .conftest import REPO

README = (REPO / "README.md").read_text()


def test_glossary_is_generated_from_the_models():
    for spec in MODELS.values():
        assert model_markdown(spec) in README, f"regenerate with `mechsweep models --markdown` ({spec.name})"


def test_ci_runs_the_readme_test_command():
    ci = (REPO / ".ci" / "run").read_text()
    command = re.search(r"^pip install -e \"\.\[test\]\".*$", ci, re.M).group(0)
    assert command in README


def test_every_shipped_scene_is_mentioned():
    for path in (REPO / "sweeps").glob("*.toml"):
        assert f"sweeps/{path.name}" in README, path.name
