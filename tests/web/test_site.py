"""The site writer and the page template, without a browser: whole-or-nothing writes, what it refuses to replace,
escaping of text from input, relative links."""

from __future__ import annotations

import html
import re
from pathlib import Path
from urllib.parse import unquote

import pytest

from urdf_pipeline.errors import UserError
from urdf_pipeline.web import MARKER, PAGE_POLICY, ViewerAssets, html_text, page, relative_href, viewer_href, write_site

HOSTILE = [
    '<script>alert("x")</script>',
    "a\nb\x1b[31m\u202e",
    "' onmouseover='x",
    '"><img src=x onerror=alert(1)>',
    "x" * 5000,
    "::error::forged",
]


def _site(target: Path, title: str = "t", body: str = "<p>ok</p>") -> None:
    with write_site(target, viewer=False) as site:
        site.write_page("index.html", title, body)


@pytest.mark.parametrize("text", HOSTILE)
def test_text_from_input_is_inert_html(text: str) -> None:
    shown = html_text(text)
    assert "<" not in shown and ">" not in shown and '"' not in shown and "'" not in shown
    assert "\n" not in shown and "\x1b" not in shown and "\u202e" not in shown
    assert len(shown) < 300  # shortened, with its length
    assert html.unescape(shown).startswith(text[:10].replace("\n", "\\n").replace("\x1b", "\\x1b")[:10])


def test_a_page_escapes_its_title_and_links_only_relatively() -> None:
    text = page('<script>alert("x")</script>', "<p>body</p>", at="segments/a/b.html", scripts=("browse.js",))
    assert "<script>alert" not in text and "&lt;script&gt;alert" in text
    assert '<link rel="stylesheet" href="../../style.css">' in text
    assert '<script src="../../browse.js" defer></script>' in text
    assert 'href="../../index.html"' in text
    assert f'content="{PAGE_POLICY}"' in text
    assert "<script>" not in text  # no inline script
    for link in re.findall(r'(?:href|src)="([^"]*)"', text):
        assert not link.startswith(("/", "http:", "https:", "//")), link


def test_viewer_links_are_relative_and_survive_odd_file_names() -> None:
    href = viewer_href("index.html", ["recordings/episode 0#1&x=%.rrd", "recordings/demo.rbl"])
    assert href == "viewer/index.html#url=../recordings/episode%25200%25231%2526x%253D%2525.rrd&url=../recordings/demo.rbl"
    # what boot.js does: the fragment's parameters decoded once, then each resolved as a URL path (decoded again)
    values = [unquote(part.removeprefix("url=")) for part in href.split("#", 1)[1].split("&")]
    assert [unquote(value) for value in values] == ["../recordings/episode 0#1&x=%.rrd", "../recordings/demo.rbl"]
    assert viewer_href("segments/a.html", ["recordings/a.rrd"]) == "../viewer/index.html#url=../recordings/a.rrd"
    assert viewer_href("index.html", []) == "viewer/index.html"
    joined = viewer_href("index.html", ["recordings/a.rrd"], "recordings/shared/model.rrd", 'ep 0&url=//x.org/"<')
    assert (
        joined == "viewer/index.html#url=../recordings/a.rrd&asset=../recordings/shared/model.rrd&into=ep%200%26url%3D%2F%2Fx.org%2F%22%3C"
    )
    assert html.escape(href) == href.replace("&", "&amp;")  # nothing else in it needs escaping in an attribute


def test_relative_links_stay_inside_the_site() -> None:
    assert relative_href("index.html", "viewer/index.html") == "viewer/index.html"
    assert relative_href("a/b/c.html", "a/d.png") == "../d.png"
    for outside in ("/etc/passwd", "../x", "a/../../x"):
        with pytest.raises(ValueError):
            relative_href("index.html", outside)


def test_a_site_is_written_whole_and_replaces_only_its_own_kind(tmp_path: Path) -> None:
    target = tmp_path / "site"
    _site(target, body="<p>first</p>")
    assert (target / MARKER).is_file() and (target / "style.css").is_file() and (target / ".nojekyll").is_file()
    assert "first" in (target / "index.html").read_text()
    _site(target, body="<p>second</p>")  # a site written before is replaced
    assert "second" in (target / "index.html").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]  # no partial or old folder left beside it


def test_a_failed_build_leaves_the_old_site_as_it_was(tmp_path: Path) -> None:
    target = tmp_path / "site"
    _site(target, body="<p>kept</p>")
    with pytest.raises(RuntimeError), write_site(target, viewer=False) as site:
        site.write_page("index.html", "t", "<p>new</p>")
        raise RuntimeError("stopped half way")
    assert "kept" in (target / "index.html").read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["site"]


def test_a_site_needs_an_index_page(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match="index.html"), write_site(tmp_path / "site", viewer=False) as site:
        site.write_page("other.html", "t", "")
    assert list(tmp_path.iterdir()) == []


def test_a_folder_that_is_not_a_site_is_refused(tmp_path: Path) -> None:
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(UserError, match="not a site urdf-pipeline wrote") as refused:
        _site(mine)
    assert refused.value.where is not None and refused.value.where.file == mine
    assert (mine / "thesis.tex").read_text() == "years of work"
    a_file = tmp_path / "file.html"
    a_file.write_text("x")
    with pytest.raises(UserError, match="not a folder"):
        _site(a_file)
    empty = tmp_path / "empty"
    empty.mkdir()
    _site(empty)  # an empty folder holds nothing to lose
    assert (empty / MARKER).is_file()


def test_paths_outside_the_site_are_refused(tmp_path: Path) -> None:
    source = tmp_path / "a.rrd"
    source.write_bytes(b"rrd")
    with write_site(tmp_path / "site", viewer=False) as site:
        for bad in ("../x.html", "/etc/x", "a//b", "", "a/./b"):
            with pytest.raises(ValueError):
                site.write_text(bad, "x")
        for name in ("../a.rrd", "a/b.rrd", ".hidden.rrd", ""):
            with pytest.raises(ValueError):
                site.add_recording(source, name)
        with pytest.raises(UserError, match="cannot put it into the site") as missing:
            site.add_recording(tmp_path / "missing.rrd")
        assert missing.value.where is not None and missing.value.where.file == tmp_path / "missing.rrd"
        assert site.add_recording(source) == "recordings/a.rrd"
        assert site.add_recording(source, "episode 1.rrd") == "recordings/episode 1.rrd"
        site.write_page("index.html", "t", "")
    assert (tmp_path / "site" / "recordings" / "episode 1.rrd").read_bytes() == b"rrd"


def test_the_viewer_is_in_a_site_once_and_our_page_starts_it(tmp_path: Path, viewer_cache: ViewerAssets) -> None:
    with write_site(tmp_path / "site") as site:
        site.write_page("index.html", "t", "")
    viewer = tmp_path / "site" / "viewer"
    assert sorted(p.name for p in viewer.iterdir()) == ["boot.js", "favicon.ico", "index.html", "re_viewer.js", "re_viewer_bg.wasm"]
    assert (viewer / "re_viewer_bg.wasm").stat().st_size == viewer_cache.path("re_viewer_bg.wasm").stat().st_size
    assert len(list((tmp_path / "site").rglob("*.wasm"))) == 1
    index = (viewer / "index.html").read_text()
    assert "'wasm-unsafe-eval'" in index and "connect-src 'self'" in index
    assert "googleapis" not in index and "<script>" not in index  # no web font, no inline script
    assert re.findall(r'<script src="([^"]+)"', index) == ["re_viewer.js", "boot.js"]
    assert "{" not in index  # every placeholder filled
    assert f"Rerun {viewer_cache.rerun_version}" in index
