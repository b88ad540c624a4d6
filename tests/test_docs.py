"""The documentation site builds (Sphinx + MyST, warnings are errors, as the README says) and
every internal link and anchor of the built pages, and every relative link of README.md,
resolves. Offline: the build runs with Python's sockets refused anything but this machine
(intersphinx reads the inventories of docs/_intersphinx, MathJax is served from the site), and
the tutorials (docs/tutorial, notebooks executed by the build) compute only small grids."""
import re
import subprocess
import sys
import tomllib
from html import unescape
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

from .conftest import REPO

README = (REPO / "README.md").read_text()
BUILD = ["-m", "sphinx", "-W", "--keep-going", "-b", "html"]


class _Refs(HTMLParser):
    def __init__(self):
        super().__init__()
        self.ids, self.links = set(), []

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        for key in ("id", "name"):
            if a.get(key):
                self.ids.add(a[key])
        for key in ("href", "src"):
            if a.get(key) is not None:
                self.links.append(a[key])


def broken_links(html_root: Path) -> list[str]:
    """Every href/src of the built site that is not external and does not resolve to a file (and,
    with a #fragment, to an element with that id in it)."""
    pages = {p: _Refs() for p in html_root.rglob("*.html")
             if "_static" not in p.relative_to(html_root).parts}  # the theme's templates are not pages
    for p, refs in pages.items():
        refs.feed(p.read_text(encoding="utf-8"))
    bad = []
    for p, refs in pages.items():
        for link in refs.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc or link.startswith("javascript:"):
                continue  # external: not checked (offline)
            target = (p.parent / unquote(parts.path)).resolve() if parts.path else p
            if not target.exists():
                bad.append(f"{p.relative_to(html_root)}: {link} (no such file)")
            elif parts.fragment and target.suffix == ".html":
                if unquote(parts.fragment) not in pages[target].ids:
                    bad.append(f"{p.relative_to(html_root)}: {link} (no such anchor)")
    return bad


# The README's build command, with Python's sockets refused any address but this machine's (the
# notebooks' kernels talk to the build over loopback): a build that fetched anything would fail.
OFFLINE = """
import socket, sys
LOCAL = ("127.", "localhost", "::1", "0.0.0.0")
def local(host):
    return not isinstance(host, str) or host.startswith(LOCAL) or host == ""
connect, getaddrinfo = socket.socket.connect, socket.getaddrinfo
def guarded_connect(self, address):
    if self.family in (socket.AF_INET, socket.AF_INET6) and not local(address[0]):
        raise OSError(f"the docs build tried the network: {address}")
    return connect(self, address)
def guarded_getaddrinfo(host, *args, **kwargs):
    if not local(host if not isinstance(host, bytes) else host.decode()):
        raise OSError(f"the docs build tried the network: {host}")
    return getaddrinfo(host, *args, **kwargs)
socket.socket.connect, socket.getaddrinfo = guarded_connect, guarded_getaddrinfo
from sphinx.cmd.build import main
sys.exit(main(sys.argv[1:]))
"""
TUTORIALS = ("first-sweep", "read-a-nomogram", "own-model", "boundaries", "cluster")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("build") / "html"
    args = BUILD[BUILD.index("sphinx") + 1:]  # the README's options, run through OFFLINE
    run = subprocess.run([sys.executable, "-c", OFFLINE, *args, "-q", "-d", str(out.parent / ".doctrees"),
                          str(REPO / "docs"), str(out)], capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, f"sphinx-build -W failed:\n{run.stderr[-20000:]}"
    return out


def test_docs_build_without_warnings_and_every_internal_link_resolves(site):
    assert (site / "index.html").is_file()
    for page in ("quickstart", "scenes", "cli", "datasets", "cluster", "gallery", "glossary", "api", "physics",
                 "numerics", "performance", "performance-duffing", "performance-startup", "boundaries", "testing",
                 "your-own-model", "model-layer", "architecture", "tutorial/index", *(f"tutorial/{t}" for t in TUTORIALS)):
        assert (site / f"{page}.html").is_file(), page
    assert broken_links(site) == []


def test_the_site_has_a_maintained_theme_and_renders_math_without_the_network(site):
    index = (site / "index.html").read_text()
    assert "pydata-sphinx-theme" in index or "pydata_sphinx_theme" in index
    physics = (site / "physics.html").read_text()
    assert physics.count('class="math notranslate nohighlight"') >= 30  # formulas, not ASCII
    mathjax = re.findall(r'<script[^>]*src="([^"]*tex-chtml[^"]*)"', physics)
    assert mathjax and all(not urlsplit(src).scheme for src in mathjax), mathjax  # served from the site
    assert (site / "_static" / "mathjax" / "tex-chtml.js").is_file()
    glossary = (site / "glossary.html").read_text()
    assert r"\(\varepsilon = \mu A^2/\omega^2\)" in glossary  # symbols are math too


def test_names_of_other_projects_link_to_their_documentation(site):
    """intersphinx, from the inventories shipped in docs/_intersphinx (no fetch)."""
    api = (site / "api.html").read_text() + (site / "tutorial" / "first-sweep.html").read_text()
    for url in ("https://docs.xarray.dev/en/stable/generated/xarray.Dataset.html",
                "https://numpy.org/doc/stable/reference/generated/numpy.ndarray.html",
                "https://matplotlib.org/stable/api/_as_gen/matplotlib.figure.Figure.html",
                "https://docs.python.org/3/library/pathlib.html"):
        assert f'href="{url}' in api, url
    conf = (REPO / "docs" / "conf.py").read_text()
    readme = (REPO / "docs" / "_intersphinx" / "README.md").read_text()
    for name in ("python", "numpy", "xarray", "matplotlib", "numba"):
        assert (REPO / "docs" / "_intersphinx" / f"{name}.inv").is_file() and f"`{name}.inv`" in readme, name
        assert f'"{name}": "https://' in conf, name


def test_command_lines_copy_as_typed(site):
    """No smart quotes or dashes: `--resume` stays two hyphens wherever it is written."""
    def text(page):
        return unescape(re.sub(r"<[^>]+>", "", page.read_text(encoding="utf-8")))

    assert "--resume" in text(site / "cli.html") and "--resume" in text(site / "datasets.html")
    for page in site.rglob("*.html"):
        text = page.read_text(encoding="utf-8")
        assert "\u2013resume" not in text and "\u2014resume" not in text, page.name
        assert "\u201c" not in text and "\u201d" not in text, page.name  # curly double quotes


def test_the_tutorials_ran_in_the_build_and_show_their_results(site):
    """Each tutorial page is a notebook executed by the build: its cells' outputs are on the page,
    with the figures drawn, and nothing but the compile note went to stderr (a warning in a tutorial is a
    defect)."""
    for name in TUTORIALS:
        html = (site / "tutorial" / f"{name}.html").read_text()
        assert html.count('class="cell_output') >= 2, name
        assert "Traceback" not in html, name
        for block in re.findall(r'class="output stderr.*?<pre>(.*?)</pre>', html, re.S):
            lines = [x for x in re.sub(r"<[^>]+>", "", block).splitlines() if x.strip()]
            # the compile note and its timing (every front end shows them) are the only stderr allowed
            assert all(x.startswith("mechsweep: ") and "compil" in x for x in lines), (name, lines)
        if name != "cluster":
            assert re.search(r'<img [^>]*src="[^"]*_images/[0-9a-f]{16,}\.png"', html), name
    assert "bitwise identical: True" in (site / "tutorial" / "cluster.html").read_text()
    order = re.findall(r'href="(first-sweep|read-a-nomogram|own-model|boundaries|cluster)\.html"',
                       (site / "tutorial" / "index.html").read_text())
    assert list(dict.fromkeys(order)) == list(TUTORIALS)  # the tutorial path, in order


PUBLIC = ["mechsweep.run", "mechsweep.compute", "mechsweep.open_dataset", "mechsweep.load_scene",
          "mechsweep.figures.available", "mechsweep.figures.on_request", "mechsweep.figures.draw",
          "mechsweep.figures.artists", "mechsweep.figures.save"]
DECLARATIONS = ["Param", "Setting", "Output", "ExtraDim", "OdeModel", "ClosedFormModel", "Crossing", "Period",
                "StateAt", "Extremum", "Floquet", "FirstEvent", "ClosedForm", "Steady", "Kick", "History"]


def _documented(doc: str, section: str) -> set[str]:
    """The names a numpy-style section (Parameters, Attributes) of ``doc`` documents with a type."""
    body = doc.split(f"\n{section}\n{'-' * len(section)}\n", 1)
    assert len(body) == 2, f"no {section} section"
    names = set()
    for line in body[1].splitlines():
        if re.match(r"^\S", line) and " : " in line:
            names.update(n.strip() for n in line.split(" : ")[0].split(","))
        elif re.match(r"^[A-Z][a-z]+$", line):
            break
    return names


def test_the_public_api_has_numpy_style_docstrings_with_types(site):
    import dataclasses
    import importlib
    import inspect

    import mechsweep
    from mechsweep import model

    for dotted in PUBLIC:
        module, name = dotted.rsplit(".", 1)
        func = getattr(importlib.import_module(module), name)
        doc = inspect.getdoc(func)
        params = [p for p in inspect.signature(func).parameters if p not in ("self",)]
        documented = _documented(doc, "Parameters")
        assert set(params) <= documented, (dotted, set(params) - documented)
        assert "\nReturns\n-------\n" in doc, dotted
    for name in DECLARATIONS:
        cls = getattr(model, name)
        fields = {f.name for f in dataclasses.fields(cls)}
        documented = _documented(inspect.getdoc(cls), "Parameters")
        assert fields <= documented, (name, fields - documented)
    scene_fields = {f.name for f in dataclasses.fields(mechsweep.Scene)}
    assert scene_fields <= _documented(inspect.getdoc(mechsweep.Scene), "Attributes")
    api = (site / "api.html").read_text()
    for anchor in ("mechsweep.run", "mechsweep.compute", "mechsweep.model.Param", "mechsweep.figures.draw",
                   "mechsweep.model.Floquet"):
        start = api.index(f'id="{anchor}"')
        assert "Parameters" in api[start:start + 20000], anchor
    for name in scene_fields:  # Attributes: one entry with its type each
        assert f'id="mechsweep.Scene.{name}"' in api, name


def test_the_package_ships_its_type_annotations():
    """PEP 561: py.typed in the package, and in the wheel's package data."""
    assert (REPO / "src" / "mechsweep" / "py.typed").is_file()
    data = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "py.typed" in data["mechsweep"]


# History stays in git: what the docs and the code say is for their readers.
HISTORY = [(re.compile(r"\b[Ii]ssues? #?\d+"), "an issue number"),
           (re.compile(r"\b\d{1,2}:\d{2}(?::\d{2})?(?:\s*-\s*\d{1,2}:\d{2})?\s*UTC\b"), "a UTC time"),
           (re.compile(r"\b20\d\d-[01]\d-[0-3]\d\b"), "a date"),
           (re.compile(r"\bthis session\b|\bsession's\b|\bdocs-only trial\b"), "session history")]


def history_in(text: str) -> list[str]:
    return [f"{what}: {m.group(0)!r}" for pattern, what in HISTORY for m in pattern.finditer(text)]


def test_docs_and_code_carry_no_issue_numbers_dates_or_session_history():
    files = [REPO / "README.md", *(REPO / "docs").rglob("*.md"), *(REPO / "docs").rglob("*.py"),
             *(REPO / "src").rglob("*.py"), *(REPO / "sweeps").rglob("*.toml"),
             *(REPO / "benchmarks").rglob("*.py"), *(REPO / "tests" / "reference").rglob("*.py")]
    found = []
    for path in files:
        rel = path.relative_to(REPO)
        if rel.parts[:2] == ("docs", "_build") or rel.parts[:2] == ("docs", "jupyter_execute"):
            continue
        text = path.read_text(encoding="utf-8")
        if rel.as_posix() == "docs/_intersphinx/README.md":  # when each inventory was obtained: its provenance
            text = HISTORY[2][0].sub("", text)
        found += [f"{rel}: {h}" for h in history_in(text)]
    assert found == []


def test_the_history_check_finds_what_it_looks_for():
    text = "as issue 13 asks (2026-11-24, 16:54-17:06 UTC); measured in this session"
    assert [h.split(":")[0] for h in history_in(text)] == ["an issue number", "a UTC time", "a date",
                                                           "session history"]
    assert history_in("step 12:30 of the run; version 2.4; issues of the model; a session of dask") == []


def test_glossary_symbols_are_written_as_math():
    from mechsweep.docs import symbol_math

    assert symbol_math("ε = μ A² / ω²") == r"$\varepsilon = \mu \,A^2 / \omega ^2$"
    assert symbol_math("|T - T_exact| / T_exact") == r"$\vert T - T_{\mathrm{exact}}\vert / T_{\mathrm{exact}}$"
    assert symbol_math("λ1") == r"$\lambda_{1}$" and symbol_math("S0/R") == r"$S_{0}/R$"
    assert symbol_math("stable (Floquet)") == "stable (Floquet)"  # words stay words
    assert symbol_math("", "") == "-"
    assert symbol_math("w", r"$\omega_{\mathrm{p}}$") == r"$\omega_{\mathrm{p}}$"  # a declaration's own LaTeX


def test_api_reference_is_generated_from_the_docstrings(site):
    html = (site / "api.html").read_text()
    import mechsweep

    first_line = mechsweep.run.__doc__.strip().splitlines()[0]
    assert 'id="mechsweep.run"' in html and first_line.split()[0] in html
    assert 'id="mechsweep.model.OdeModel"' in html and 'id="mechsweep.balancing.rms_axis_offset"' in html


def test_gallery_shows_every_committed_figure_of_a_shipped_scene(site):
    gallery = (REPO / "docs" / "gallery.md").read_text()
    shown = set(re.findall(r"\]\(figures/([^)]+\.png)\)", gallery))
    for name in shown:
        assert (REPO / "docs" / "figures" / name).is_file(), name
        assert (site / "_images" / name).is_file(), name  # copied into the built site
    for scene in (REPO / "sweeps").glob("*.toml"):
        assert any(name.startswith(scene.stem + "_") or name == scene.stem + ".png" for name in shown), scene.name


def test_the_link_check_finds_a_broken_link_and_anchor(tmp_path):
    (tmp_path / "a.html").write_text('<a id="x" href="b.html#y">b</a><a href="a.html#x">self</a>'
                                     '<img src="gone.png"><a href="https://example.org/">ext</a>')
    (tmp_path / "b.html").write_text('<p id="z">b</p>')
    assert sorted(broken_links(tmp_path)) == ["a.html: b.html#y (no such anchor)", "a.html: gone.png (no such file)"]


def _slug(heading: str) -> str:
    """GitHub's (and MyST's myst_heading_anchors) anchor of a markdown heading."""
    text = re.sub(r"[^\w\- ]", "", heading.strip().lower())
    return text.replace(" ", "-")


def test_readme_relative_links_resolve():
    links = re.findall(r"\]\(([^)\s]+)\)", README)
    assert len(links) >= 20
    for link in links:
        parts = urlsplit(link)
        if parts.scheme:
            continue
        target = REPO / parts.path
        assert target.exists(), link
        if parts.fragment:
            headings = re.findall(r"^#{1,6} (.+)$", target.read_text(), re.M)
            assert parts.fragment in {_slug(h) for h in headings}, link


def test_readme_build_command_is_the_tested_one():
    assert "python " + " ".join(BUILD) + " docs docs/_build/html" in README
