"""Parse YAML while keeping the line of every key, so every later error can point at its line."""

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


@dataclass(frozen=True)
class Document:
    """A parsed YAML file: plain data plus the 1-based line of every node, by YAML path."""

    file: Path
    data: Any
    lines: dict[PathKey, int] = field(default_factory=dict)

    def where(self, *path: str | int) -> Where:
        """The location of `path`, or of its nearest existing ancestor (for keys that are missing)."""
        probe: PathKey = tuple(path)
        while probe and probe not in self.lines:
            probe = probe[:-1]
        return Where(self.file, self.lines.get(probe, 1), format_path(tuple(path)))

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
        line = mark.line + 1 if mark else 1
        problem = " ".join(part for part in (exc.context, exc.problem) if part)
        raise UserError(f"YAML syntax error: {problem}", Where(file, line)) from None
    finally:
        loader.dispose()
    if root is None:
        return Document(file, None, {})
    lines: dict[PathKey, int] = {(): root.start_mark.line + 1}
    data = _convert(root, (), lines, file, _Loader(""))
    return Document(file, data, lines)


def _convert(node: yaml.Node, path: PathKey, lines: dict[PathKey, int], file: Path, loader: yaml.SafeLoader) -> Any:
    if isinstance(node, yaml.MappingNode):
        loader.flatten_mapping(node)
        result: dict[Any, Any] = {}
        for key_node, value_node in node.value:
            key = loader.construct_object(key_node, deep=True)
            if not isinstance(key, (str, int, float, bool)) and key is not None:
                raise UserError("mapping keys must be scalars", Where(file, key_node.start_mark.line + 1, format_path(path)))
            key = key if isinstance(key, str) else str(key)
            child = (*path, key)
            if key in result:
                raise UserError(
                    f"duplicate key '{key}' (first at line {lines[child]}); YAML would silently keep only the last",
                    Where(file, key_node.start_mark.line + 1, format_path(child)),
                )
            lines[child] = key_node.start_mark.line + 1
            result[key] = _convert(value_node, child, lines, file, loader)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            lines[(*path, index)] = item.start_mark.line + 1
            items.append(_convert(item, (*path, index), lines, file, loader))
        return items
    return loader.construct_object(node, deep=True)
