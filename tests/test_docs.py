"""The documentation site builds (Sphinx + MyST, warnings are errors, as the README says) and
every internal link and anchor of the built pages, and every relative link of README.md,
resolves. Offline: nothing is fetched."""
import re
import subprocess
import sys
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
    pages = {p: _Refs() for p in html_root.rglob("*.html")}
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


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("html")
    run = subprocess.run([sys.executable, *BUILD, "-q", "-d", str(out / ".doctrees"), str(REPO / "docs"), str(out)],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, f"sphinx-build -W failed:\n{run.stderr}"
    return out


def test_docs_build_without_warnings_and_every_internal_link_resolves(site):
    assert (site / "index.html").is_file()
    for page in ("quickstart", "scenes", "cli", "datasets", "cluster", "gallery", "glossary", "api", "physics",
                 "numerics", "performance", "boundaries", "testing", "your-own-model", "model-layer"):
        assert (site / f"{page}.html").is_file(), page
    assert broken_links(site) == []


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
