"""Parse YAML while keeping the line and column of every key, so every later error can point at them."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .errors import UserError, Where

PathKey = tuple[str | int, ...]


def format_path(path: PathKey) -> str:
    """`('robots', 'arm', 'edges', 0)` -> `robots.arm.edges[0]`: the YAML path shown in messages."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


class Lines(dict[PathKey, int]):
    """The 1-based line of every YAML path (a plain dict of lines, as before) with, in `columns`, its 1-based column.

    Both are where the path's entry starts: its key for a mapping entry (so a problem with the key or with its value
    points at the key), the item itself for a sequence item (after `- `), the root node for `()`. Columns ride along
    with the lines, so a Document built from another document's `lines` (a JSON sidecar) has them too."""

    def __init__(self) -> None:
        super().__init__()
        self.columns: dict[PathKey, int] = {}

    def mark(self, path: PathKey, mark: yaml.Mark) -> None:
        self[path] = mark.line + 1
        self.columns[path] = mark.column + 1


@dataclass(frozen=True)
class Document:
    """A parsed YAML file: plain data plus the 1-based line (and column, see `Lines`) of every node, by YAML path."""

    file: Path
    data: Any
    lines: dict[PathKey, int] = field(default_factory=dict)

    def where(self, *path: str | int) -> Where:
        """The location of `path` (line and column of its key or item), or of its nearest existing ancestor (for keys
        that are missing). The column is 0 (unknown) when `lines` is a plain dict without columns."""
        probe: PathKey = tuple(path)
        while probe and probe not in self.lines:
            probe = probe[:-1]
        column = self.lines.columns.get(probe, 0) if isinstance(self.lines, Lines) else 0
        return Where(self.file, self.lines.get(probe, 1), format_path(tuple(path)), column)

    def get(self, *path: str | int, default: Any = None) -> Any:
        node = self.data
        for part in path:
            try:
                node = node[part]
            except (KeyError, IndexError, TypeError):
                return default
        return node


class _Loader(yaml.SafeLoader):
    """YAML 1.1 as PyYAML reads it, except that 1e-3 is a number (as in YAML 1.2 and JSON), not the string '1e-3'."""


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def load_document(file: Path) -> Document:
    """Read and parse a YAML (or JSON) file; syntax errors and duplicate keys are user errors with a line."""
    try:
        text = file.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError("config file not found", Where(file, 0)) from None
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read the config file: {exc}", Where(file, 0)) from None
    return parse_document(text, file)


def parse_document(text: str, file: Path) -> Document:
    loader = _Loader(text)
    try:
        root = loader.get_single_node()
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line, column = (mark.line + 1, mark.column + 1) if mark else (1, 0)
        problem = " ".join(part for part in (exc.context, exc.problem) if part)
        raise UserError(f"YAML syntax error: {problem}", Where(file, line, column=column)) from None
    finally:
        loader.dispose()
    lines = Lines()
    if root is None:
        return Document(file, None, lines)
    lines.mark((), root.start_mark)
    data = _convert(root, (), lines, file, _Loader(""))
    return Document(file, data, lines)


def _at(file: Path, mark: yaml.Mark, path: PathKey) -> Where:
    return Where(file, mark.line + 1, format_path(path), mark.column + 1)


def _convert(node: yaml.Node, path: PathKey, lines: Lines, file: Path, loader: yaml.SafeLoader) -> Any:
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, (str, int, float, bool)) and key is not None:
                raise UserError("mapping keys must be scalars", _at(file, key_node.start_mark, path))
            key = key if isinstance(key, str) else str(key)
            child = (*path, key)
            if key in result:
                raise UserError(
                    f"duplicate key '{key}' (first at line {lines[child]}); YAML would silently keep only the last",
                    _at(file, key_node.start_mark, child),
                )
            lines.mark(child, key_node.start_mark)
            result[key] = _convert(value_node, child, lines, file, loader)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            lines.mark((*path, index), item.start_mark)
            items.append(_convert(item, (*path, index), lines, file, loader))
        return items
    return loader.construct_object(node, deep=True)
