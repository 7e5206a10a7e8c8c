"""The user guide (docs/guide/, built by MkDocs from docs/mkdocs.yml) and the README's links into it.

- The guide builds with ``mkdocs build --strict``: no broken link or anchor, no page left out of the nav,
  no link to a file the repository does not have (docs/hooks.py).
- The strictness is real: a broken link and a page outside the nav make the same build fail.
- Every page is in the nav, and the README (the front door) links to every page; its links and their
  anchors resolve.
"""

import importlib.util
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
GUIDE = DOCS / "guide"
CONFIG = DOCS / "mkdocs.yml"
MARKDOWN_LINK = re.compile(r"!?\[[^\]]*\]\(([^)\s]+)\)")

needs_mkdocs = pytest.mark.skipif(importlib.util.find_spec("mkdocs") is None,
                                  reason="mkdocs is not installed (it is in the [test] extras: pip install -e '.[test]')")


def build(config: Path, site: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(config),
                           "--site-dir", str(site)], capture_output=True, text=True, timeout=300)


def guide_pages() -> set[str]:
    return {p.relative_to(GUIDE).as_posix() for p in GUIDE.rglob("*.md")}


def heading_anchors(page: Path) -> set[str]:
    """The anchors GitHub (and MkDocs' toc, for these headings) gives a page's headings."""
    headings = re.findall(r"^#+\s+(.+?)\s*$", page.read_text(), flags=re.M)
    return {re.sub(r"[^\w\- ]", "", h.lower()).replace(" ", "-") for h in headings}


def nav_pages(nav) -> set[str]:
    """Every page a MkDocs nav names, at any depth."""
    if isinstance(nav, str):
        return {nav}
    if isinstance(nav, dict):
        return set().union(*(nav_pages(v) for v in nav.values()))
    return set().union(*(nav_pages(item) for item in nav))


@needs_mkdocs
def test_guide_builds_strictly(tmp_path):
    done = build(CONFIG, tmp_path / "site")
    assert done.returncode == 0, done.stdout + done.stderr
    assert (tmp_path / "site" / "index.html").exists()
    assert (tmp_path / "site" / "img" / "live-view.png").exists()


@needs_mkdocs
def test_strict_build_fails_on_a_broken_link_and_a_page_outside_the_nav(tmp_path):
    copy = tmp_path / "docs"
    shutil.copytree(DOCS, copy, ignore=shutil.ignore_patterns("site"))
    with open(copy / "guide" / "quality.md", "a") as page:
        page.write("\nSee [the missing page](no-such-page.md).\n")
    (copy / "guide" / "stray.md").write_text("# A page nobody listed\n")
    done = build(copy / "mkdocs.yml", tmp_path / "site")
    output = done.stdout + done.stderr
    assert done.returncode != 0
    assert "no-such-page.md" in output
    assert "stray.md" in output


def test_every_guide_page_is_in_the_nav():
    yaml = pytest.importorskip("yaml", reason="PyYAML comes with mkdocs, which is not installed")

    class Loader(yaml.SafeLoader):  # mkdocs.yml may use MkDocs' own tags (!ENV ...): read them as text
        pass

    Loader.add_multi_constructor("!", lambda loader, suffix, node: None)
    config = yaml.load(CONFIG.read_text(), Loader=Loader)
    assert config["docs_dir"] == "guide"
    assert nav_pages(config["nav"]) == guide_pages()


def test_readme_links_resolve_and_reach_every_guide_page():
    readme = (REPO / "README.md").read_text()
    targets = [t for t in MARKDOWN_LINK.findall(readme) if "://" not in t and not t.startswith(("#", "mailto:"))]
    missing = [t for t in targets if not (REPO / t.split("#")[0]).exists()]
    assert not missing, f"README.md links to files that do not exist: {missing}"
    broken_anchors = [t for t in targets if "#" in t and t.split("#")[0].endswith(".md")
                      and t.split("#")[1] not in heading_anchors(REPO / t.split("#")[0])]
    assert not broken_anchors, f"README.md links to headings that do not exist: {broken_anchors}"
    linked = {t.split("#")[0] for t in targets}
    unlinked = sorted(p for p in guide_pages() if f"docs/guide/{p}" not in linked)
    assert not unlinked, f"README.md does not link to these guide pages: {unlinked}"
