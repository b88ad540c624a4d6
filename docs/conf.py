"""Sphinx configuration of the mechsweep documentation (MyST markdown pages in this folder).

    python -m sphinx -W --keep-going -b html docs docs/_build/html    # then open docs/_build/html/index.html

tests/test_docs.py runs the same build (warnings are errors) and checks every internal link and
anchor of the result offline."""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))  # the API reference documents this checkout's code

project = "mechsweep"
author = "mechsweep developers"
copyright = "mechsweep developers"
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build"]
myst_heading_anchors = 3  # GitHub-style anchors for ## and ### headings, e.g. your-own-model.md#11-closed-form-models
myst_enable_extensions = []
html_theme = "alabaster"
html_static_path = []
html_title = "mechsweep"
autodoc_member_order = "bysource"
autodoc_typehints = "none"
nitpicky = False


def _plain_text_docstrings(app, what, name, obj, options, lines):
    """The package's docstrings are plain text with ``literals``: a | there is an absolute value
    (|T - T_exact|), never a reStructuredText substitution reference."""
    for i, line in enumerate(lines):
        lines[i] = line.replace("|", "\\|")


def setup(app):
    app.connect("autodoc-process-docstring", _plain_text_docstrings)
