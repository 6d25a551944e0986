"""The documentation: the site of docs/ builds strictly (every page in a table of contents, every link and anchor
found), the links of README.md, ARCHITECTURE.md and CONTRIBUTING.md into the repository resolve on GitHub, and what
the README shows of the code stays what the code says."""

from __future__ import annotations

import importlib.util
import re
import shutil
import subprocess
import sys
import tomllib
import unicodedata
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
STRICT = ["-W", "--keep-going", "-n", "-q", "-b", "html"]  # as `make docs`
LINK = re.compile(r"(?<!!)\[[^\]]*\]\(([^)\s]+)\)")
FENCE = re.compile(r"^(`{3,}|~{3,}).*?^\1[ \t]*$", re.MULTILINE | re.DOTALL)
CODE_SPAN = re.compile(r"(`+).+?\1", re.DOTALL)
HEADING = re.compile(r"^#{1,6}[ \t]+(.+?)[ \t]*#*[ \t]*$", re.MULTILINE)

needs_sphinx = pytest.mark.skipif(
    any(importlib.util.find_spec(name) is None for name in ("sphinx", "myst_parser", "furo")),
    reason="the docs tools are not installed (pip install -e '.[docs]')",
)


def _sphinx(source: Path, out: Path) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-m", "sphinx", *STRICT, "-d", str(out / "doctrees"), str(source), str(out / "html")]
    return subprocess.run(command, capture_output=True, text=True, timeout=300)


@needs_sphinx
def test_the_site_builds_strictly(tmp_path: Path) -> None:
    result = _sphinx(DOCS, tmp_path)
    assert result.returncode == 0, f"`make docs` fails:\n{result.stderr}"
    pages = {p.stem for p in DOCS.glob("*.md")}
    assert pages <= {p.stem for p in (tmp_path / "html").glob("*.html")}
    contributing = (tmp_path / "html" / "contributing.html").read_text(encoding="utf-8")
    assert "/blob/main/ARCHITECTURE.md#where-do-i-change" in contributing, "a link out of docs/ goes to the file on GitHub"


@needs_sphinx
def test_the_build_fails_on_a_broken_link_a_missing_page_or_an_orphan(tmp_path: Path) -> None:
    repo = tmp_path / "repo"
    shutil.copytree(DOCS, repo / "docs", ignore=shutil.ignore_patterns("_build"))
    for name in ("pyproject.toml", "README.md", "ARCHITECTURE.md", "urdf_pipeline/package.py", "configs/demo.yaml"):
        (repo / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / name, repo / name)
    with (repo / "docs" / "sources.md").open("a", encoding="utf-8") as page:
        page.write("\n[a](commands.md#no-such-heading) [b](no-such-page.md) [c](../NO_SUCH_FILE.md) [d](../no_such_file.txt)\n")
    (repo / "docs" / "orphan.md").write_text("# In no table of contents\n", encoding="utf-8")
    result = _sphinx(repo / "docs", tmp_path / "out")
    assert result.returncode != 0
    for expected in ("'no-such-heading'", "no-such-page.md", "NO_SUCH_FILE.md", "no_such_file.txt", "orphan.md"):
        assert expected in result.stderr, f"{expected} is not reported:\n{result.stderr}"


def _slug(heading: str) -> str:
    """GitHub's anchor for a heading (myst_heading_anchors makes the same)."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).replace("`", "").strip().lower()
    kept = "".join(c for c in text if c in " -_" or unicodedata.category(c)[0] in "LNM")
    return kept.replace(" ", "-")


def _anchors(page: Path) -> set[str]:
    text = FENCE.sub("", page.read_text(encoding="utf-8"))
    anchors: set[str] = set()
    for heading in HEADING.findall(text):
        slug, n = _slug(heading), 1
        while slug in anchors:
            slug, n = f"{_slug(heading)}-{n}", n + 1
        anchors.add(slug)
    return anchors


def _links(page: Path) -> list[str]:
    text = CODE_SPAN.sub("", FENCE.sub("", page.read_text(encoding="utf-8")))
    return [target for target in LINK.findall(text) if not re.match(r"[a-z][a-z0-9+.-]*:", target)]


@pytest.mark.parametrize("page", ["README.md", "ARCHITECTURE.md", "CONTRIBUTING.md", *sorted(f"docs/{p.name}" for p in DOCS.glob("*.md"))])
def test_relative_links_and_their_anchors_resolve(page: str) -> None:
    """As GitHub reads the page: the file exists, and an anchor into a Markdown file names one of its headings."""
    source = REPO / page
    if not source.exists():
        pytest.skip(f"{page} does not exist")
    broken = []
    for target in _links(source):
        path_part, _, anchor = target.partition("#")
        path = (source.parent / path_part).resolve() if path_part else source
        if not path.exists() or REPO not in (path, *path.parents):
            broken.append(f"{target}: no such file in the repository")
        elif anchor and path.suffix == ".md" and anchor not in _anchors(path):
            broken.append(f"{target}: no heading of {path.relative_to(REPO)} has the anchor #{anchor}")
    assert not broken, f"{page}: " + "; ".join(broken)


def test_the_readme_links_into_the_docs() -> None:
    readme = _links(REPO / "README.md")
    assert "docs/contributing.md" in readme and "docs/config-reference.md" in readme
    linked = {target.partition("#")[0] for target in readme}
    missing = sorted(f"docs/{p.name}" for p in DOCS.glob("*.md") if p.name != "index.md" and f"docs/{p.name}" not in linked)
    assert not missing, f"the README's Documentation list lacks {missing}"


def test_the_readme_example_is_configs_demo_yaml() -> None:
    """The README shows configs/demo.yaml (which the tests run), minus its leading comments; docs/configuration.md
    includes the file itself."""
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    shown = re.search(r"^```yaml\n(version: 1\n.*?)^```$", readme, re.MULTILINE | re.DOTALL)
    assert shown, "the README's example config (a ```yaml block starting with `version: 1`) is missing"
    demo = (REPO / "configs" / "demo.yaml").read_text(encoding="utf-8")
    assert shown.group(1) == demo[demo.index("version: 1\n") :], "the README's example differs from configs/demo.yaml"


def test_the_readme_test_command_is_what_ci_runs() -> None:
    readme = (REPO / "README.md").read_text(encoding="utf-8")
    assert "\nmake test   # " in readme
    assert "make test" in (REPO / ".ci" / "run").read_text(encoding="utf-8")


def test_the_test_extra_brings_the_docs_tools() -> None:
    extras = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))["project"]["optional-dependencies"]
    assert set(extras["docs"]) <= set(extras["test"]), "tests/docs builds the site: the test extra needs the docs extra's tools"


def test_the_readme_gives_the_loop_for_one_test_file_and_make_test_says_why_tests_skip() -> None:
    loop = re.search(r"`\.venv/bin/python -m pytest (tests/\S+\.py) -q`", (REPO / "README.md").read_text(encoding="utf-8"))
    assert loop and (REPO / loop.group(1)).is_file()
    assert re.search(r"^test:.*\n(?:#.*\n)*\t\$\(BIN\)/python -m pytest -rs$", (REPO / "Makefile").read_text(), re.MULTILINE)
