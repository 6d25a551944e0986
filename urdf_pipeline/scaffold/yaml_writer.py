"""A tiny YAML emitter for init: nodes with comments -> text (block mappings and sequences, flow lists and mappings)."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass, field
from typing import Any

import yaml

from ..errors import escaped


@dataclass
class Item:
    key: str
    value: Any  # a scalar, a list (flow), a dict (flow), a Block or a Seq
    comment: str = ""


@dataclass
class Note:
    text: str


@dataclass
class Block:
    items: list[Item | Note] = field(default_factory=list)

    def add(self, key: str, value: Any, comment: str = "") -> None:
        self.items.append(Item(key, value, comment))

    def note(self, text: str) -> None:
        self.items.append(Note(text))


@dataclass
class Seq:
    items: list[tuple[Any, str]] = field(default_factory=list)  # (value, comment); value a scalar or a Block


_PLAIN = re.compile(r"^[A-Za-z0-9_./{}-][A-Za-z0-9_./:{}-]*$")


def scalar(value: Any, flow: bool = True) -> str:
    """A YAML scalar: plain when it reads back as the same string (in flow context: without `{}`), else double-quoted."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return number(value)
    if isinstance(value, int):
        return str(value)
    text = str(value)
    plain = bool(_PLAIN.match(text)) and not text.startswith(("{", "-")) and not text.endswith(":")
    if flow and ("{" in text or "}" in text):
        plain = False
    if text.startswith("."):  # ../x is plain, .inf is not
        plain = plain and text.startswith(("./", "../"))
    try:
        if plain and yaml.safe_load(f"k: {text}") == {"k": text}:
            return text
    except yaml.YAMLError:
        pass
    return json.dumps(text)  # a JSON string is a valid double-quoted YAML scalar


def number(value: float) -> str:
    """The shortest form that reads back as the same float, never in exponent form (YAML 1.1 reads 1e-05 as a string)."""
    text = repr(float(value))
    if "e" in text or "E" in text:
        text = f"{float(value):.15f}".rstrip("0")
        text = text + "0" if text.endswith(".") else text
    return text


def _flow(value: Any) -> str:
    if isinstance(value, dict):
        return "{" + ", ".join(f"{scalar(k)}: {_flow(v)}" for k, v in value.items()) + "}"
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_flow(v) for v in value) + "]"
    return scalar(value)


def _flow_lines(prefix: str, values: list[Any], indent: int, width: int = 110) -> list[str]:
    """`key: [a, b, c]`, wrapped onto continuation lines when long."""
    parts = [_flow(v) for v in values]
    one = prefix + "[" + ", ".join(parts) + "]"
    if len(one) <= width:
        return [one]
    lines, line = [], prefix + "["
    pad = " " * (indent + 2)
    for i, part in enumerate(parts):
        piece = part + ("," if i < len(parts) - 1 else "]")
        if i and len(line) + 1 + len(piece) > width:
            lines.append(line)
            line = pad + piece
        else:
            line += (" " if i else "") + piece
    lines.append(line)
    return lines


def _with_comments(bodies: list[tuple[str, str]]) -> list[str]:
    """Align the comments of one block's lines (a body longer than 60 characters is not waited for)."""
    widths = [len(body) for body, comment in bodies if comment and len(body) <= 60]
    column = max(widths, default=0) + 3
    out = []
    for body, comment in bodies:
        if not comment:
            out.append(body)
        else:
            gap = max(column - len(body), 3)
            out.append(body + " " * gap + "# " + escaped(comment))  # a newline in a name would end the comment
    return out


def render_block(block: Block, indent: int = 0) -> list[str]:
    pad = " " * indent
    bodies: list[tuple[str, str]] = []
    nested: list[list[str]] = []  # lines following each body (nested blocks), aligned separately

    for item in block.items:
        if isinstance(item, Note):
            bodies.append((pad + "# " + escaped(item.text), ""))
            nested.append([])
        elif isinstance(item.value, (Block, Seq)):
            bodies.append((f"{pad}{scalar(item.key)}:", item.comment))
            nested.append(render_block(item.value, indent + 2) if isinstance(item.value, Block) else render_seq(item.value, indent + 2))
        elif isinstance(item.value, (list, tuple)):
            lines = _flow_lines(f"{pad}{scalar(item.key)}: ", list(item.value), indent)
            if len(lines) == 1:
                bodies.append((lines[0], item.comment))
                nested.append([])
            else:  # wrapped: the comment goes on the last line
                bodies.append((lines[0], ""))
                nested.append(lines[1:-1] + _with_comments([(lines[-1], item.comment)]))
        else:
            shown = scalar(item.value, flow=False) if isinstance(item.value, str) else _flow(item.value)
            bodies.append((f"{pad}{scalar(item.key)}: {shown}", item.comment))
            nested.append([])
    aligned = _with_comments(bodies)
    out: list[str] = []
    for line, after in zip(aligned, nested, strict=True):
        out.append(line)
        out.extend(after)
    return out


def render_seq(seq: Seq, indent: int) -> list[str]:
    pad = " " * indent
    out: list[str] = []
    scalars: list[tuple[str, str]] = []  # a run of scalar items, their comments aligned together
    for value, comment in seq.items:
        if isinstance(value, Block):
            out.extend(_with_comments(scalars))
            scalars = []
            lines = render_block(value, indent + 2)
            out.append(pad + "- " + lines[0][indent + 2 :])
            out.extend(lines[1:])
        else:
            scalars.append((f"{pad}- {_flow(value)}", comment))
    return out + _with_comments(scalars)


def to_data(node: Any) -> Any:
    """The plain data a node stands for (what a YAML parser should read back)."""
    if isinstance(node, Block):
        return {item.key: to_data(item.value) for item in node.items if isinstance(item, Item)}
    if isinstance(node, Seq):
        return [to_data(value) for value, _ in node.items]
    if isinstance(node, (list, tuple)):
        return [to_data(v) for v in node]
    if isinstance(node, dict):
        return {k: to_data(v) for k, v in node.items()}
    return node
