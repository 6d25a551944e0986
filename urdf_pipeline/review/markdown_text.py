"""Text from a pull request (joint, link, frame, source and file names, YAML values, messages that quote them) inside
the Markdown that `plan` and `diff` write for a pull-request comment: inert, whatever it holds (a name a code span,
other text escaped, each one line; docs/security.md#text)."""

from __future__ import annotations

import re
from urllib.parse import quote

from ..errors import NAME_LIMIT, shown

PATH_LIMIT = 500  # characters of a path shown in Markdown (a name has errors.NAME_LIMIT)
_BACKTICKS = re.compile("`+")
_ENTITIES = {"&": "&amp;", "<": "&lt;", ">": "&gt;"}
# ASCII punctuation Markdown (CommonMark, GitHub's extensions: strikethrough, math) may read as syntax; `_` only at
# a word's edge (inside a word, `frame_index`, it is no emphasis). `|` matters in a table row only: `cell` escapes it.
_SYNTAX = re.compile(r"[\\`*\[\]#~$!{}]|(?<![0-9A-Za-z])_|_(?![0-9A-Za-z])|[&<>]")
_CELL_PIPE = re.compile(r"(\\*)\|")


def code(text: object, limit: int = NAME_LIMIT) -> str:
    """`text` as a code span: the fence one backtick longer than the longest run inside, padded with a space when the
    text starts or ends with a backtick or a space (which CommonMark would otherwise take as part of the fence or strip)."""
    inside = shown(text, limit)
    fence = "`" * (max((len(run) for run in _BACKTICKS.findall(inside)), default=0) + 1)
    pad = " " if inside[:1] in ("`", " ") or inside[-1:] in ("`", " ") else ""
    return f"{fence}{pad}{inside}{pad}{fence}"


def code_path(text: object) -> str:
    """A path as a code span: as `code`, shortened only past PATH_LIMIT characters."""
    return code(text, PATH_LIMIT)


def plain(text: object, limit: int = PATH_LIMIT) -> str:
    """Plain text that Markdown shows as written: no HTML, heading, link, image, emphasis, code or table border."""
    return _SYNTAX.sub(lambda m: _ENTITIES.get(m.group(), "\\" + m.group()), shown(text, limit))


def cell(text: str) -> str:
    """A table cell's Markdown: `|` escaped (a backslash run before it doubled, so the escape is not itself escaped),
    no newline."""
    return _CELL_PIPE.sub(lambda m: m.group(1) * 2 + "\\|", text).replace("\n", " ")


def fence_for(text: str, marker: str = "`") -> str:
    """A code block fence longer than any run of `marker` inside `text` (at least three)."""
    runs = re.findall(re.escape(marker) + "+", text)
    return marker * max(3, max((len(run) for run in runs), default=0) + 1)


def link_target(path: str) -> str:
    """A relative path as a link target: everything but letters, digits and `/._-~` percent-encoded, so no `)`, space
    or `<` in a file name ends or changes the link."""
    return quote(path, safe="/._-~")
