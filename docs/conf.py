"""Sphinx configuration of the mechsweep documentation (MyST markdown pages in this folder).

    python -m sphinx -W --keep-going -b html docs docs/_build/html    # then open docs/_build/html/index.html

tests/test_docs.py runs the same build (warnings are errors) and checks every internal link and
anchor of the result offline. The build uses no network: intersphinx reads the inventories in
_intersphinx/ and MathJax is served from the built site (sphinx-mathjax-offline). The tutorial
pages (tutorial/*.md) are notebooks executed on every build (MyST-NB), at small sizes."""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT / "src"))  # the API reference documents this checkout's code
# ... and the tutorials' notebook kernels (child processes) run it
os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), *filter(None, [os.environ.get("PYTHONPATH")])])

project = "mechsweep"
author = "mechsweep developers"
copyright = "mechsweep developers"
extensions = [
    "myst_nb",  # MyST markdown pages, and the tutorials as executed notebooks
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",
]
source_suffix = {".md": "myst-nb"}
root_doc = "index"
exclude_patterns = ["_build", "_intersphinx", "figures", "jupyter_execute", ".jupyter_cache"]

# MyST: $...$ and $$...$$ math, \begin{align} environments; GitHub-style anchors for ## and ###
# headings, e.g. your-own-model.md#11-closed-form-models
myst_enable_extensions = ["dollarmath", "amsmath"]
myst_heading_anchors = 3
# Command lines must copy as typed: no "--resume" turned into an en dash, no curly quotes.
smartquotes = False

# Tutorials: executed on every build (no cache to go stale), in their own folder; an error fails the build.
nb_execution_mode = "force"
nb_execution_raise_on_error = True
nb_execution_timeout = 600
nb_execution_show_tb = True
nb_merge_streams = True

html_theme = "pydata_sphinx_theme"
html_title = "mechsweep"
html_static_path = []
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": [],
}
html_context = {"default_mode": "light"}
# The left sidebar lists a section's pages: only the tutorial has pages under it; elsewhere it would
# stand empty, and the top bar already links every page.
html_sidebars = {"**": [], **{f"tutorial/{page}": ["sidebar-nav-bs"] for page in
                              ("index", "first-sweep", "read-a-nomogram", "own-model", "boundaries", "cluster")}}

# API reference: numpy-style docstrings; types from the annotations where a parameter's docstring
# entry gives none.
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_description_target = "documented_params"
autodoc_typehints_format = "short"
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_rtype = False
napoleon_preprocess_types = True
nitpicky = False

# Offline: each inventory is a file of _intersphinx/ (its README says where each came from).
intersphinx_mapping = {
    name: (url, str(HERE / "_intersphinx" / f"{name}.inv"))
    for name, url in {
        "python": "https://docs.python.org/3/",
        "numpy": "https://numpy.org/doc/stable/",
        "xarray": "https://docs.xarray.dev/en/stable/",
        "matplotlib": "https://matplotlib.org/stable/",
        "numba": "https://numba.readthedocs.io/en/stable/",
    }.items()
}
intersphinx_disabled_reftypes = ["std:doc"]
intersphinx_timeout = 1


def _plain_text_docstrings(app, what, name, obj, options, lines):
    """The package's docstrings are plain text with ``literals``: a | there is an absolute value
    (|T - T_exact|), never a reStructuredText substitution reference."""
    for i, line in enumerate(lines):
        lines[i] = line.replace("|", "\\|")


def setup(app):
    app.connect("autodoc-process-docstring", _plain_text_docstrings)
