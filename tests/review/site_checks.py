"""What every page of a `plan --html` / `diff --html` site must be, read as a browser reads it (html.parser): only the
tags and attributes the tool writes, no script, no event handler, no comment, and every link relative, inside the
site, to a file that is there (the viewer's `#url=` recordings too)."""

from __future__ import annotations

import re
from html.parser import HTMLParser
from pathlib import Path
from posixpath import dirname, join, normpath
from urllib.parse import unquote

TAGS = {
    "html", "head", "meta", "title", "link", "body", "header", "nav", "main", "footer", "section", "h1", "h2", "h3", "p",
    "a", "code", "pre", "span", "strong", "ul", "li", "table", "thead", "tbody", "tr", "th", "td", "figure", "img",
    "figcaption", "iframe",
}  # fmt: skip
ATTRIBUTES = {
    "lang", "charset", "http-equiv", "content", "name", "rel", "href", "src", "class", "id", "title", "alt", "width",
    "height", "loading",
}  # fmt: skip
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


class _Page(HTMLParser):
    """A page as a browser's parser splits it: its tags with their attributes, its comments, its text."""

    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.comments: list[str] = []
        self.text: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))

    def handle_comment(self, data: str) -> None:
        self.comments.append(data)

    def handle_data(self, data: str) -> None:
        self.text.append(data)


def read_page(path: Path) -> _Page:
    page = _Page()
    page.feed(path.read_text(encoding="utf-8"))
    page.close()
    return page


def _inside(site: Path, page: str, link: str) -> str:
    """The site path a relative link of the page at site path `page` names (AssertionError when it leaves the site)."""
    assert not SCHEME.match(link) and not link.startswith(("/", "\\")), f"{page}: not a relative link: {link!r}"
    target = normpath(join(dirname(page), unquote(link.split("#", 1)[0])))
    assert not target.startswith(".."), f"{page}: {link!r} leaves the site"
    assert (site / target).is_file(), f"{page}: {link!r} names no file of the site"
    return target


def assert_inert_page(site: Path, page: str = "index.html") -> _Page:
    """The page holds only the tool's own markup; its links are relative and inside the site; returns it, parsed."""
    parsed = read_page(site / page)
    assert parsed.comments == [], parsed.comments
    for tag, attributes in parsed.tags:
        assert tag in TAGS, f"{page}: a <{tag}> tag"
        assert set(attributes) <= ATTRIBUTES, f"{page}: <{tag}> with {sorted(set(attributes) - ATTRIBUTES)}"
        for name in ("href", "src"):
            link = attributes.get(name)
            if link is None or (tag == "link" and link == "data:,"):  # the page's empty icon
                continue
            target = _inside(site, page, link)
            if target == "viewer/index.html" and "#" in link:  # the recordings it opens, relative to the viewer page
                for part in link.split("#", 1)[1].split("&"):
                    assert part.startswith("url="), link
                    _inside(site, target, unquote(part.removeprefix("url=")))
    return parsed


def links(parsed: _Page, tag: str = "a", name: str = "href") -> list[str]:
    return [value for t, attributes in parsed.tags if t == tag and (value := attributes.get(name)) is not None]
