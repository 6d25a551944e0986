"""Parse YAML while keeping the line and column of every key, so every later error can point at them.

Configs and edges files come from pull requests, so reading them is bounded before anything is built (docs/security.md:
size, characters, plain-data tags only, nodes and depth counted with aliases expanded while composing, so an alias bomb
is refused before it is expanded). Each refusal is a UserError at a line and column."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from ..confine import file_state
from ..errors import UserError, Where

PathKey = tuple[str | int, ...]

MAX_BYTES = 4 * 2**20  # a config or edges file is a few KB; anything this large is refused before parsing
MAX_NODES = 100_000  # nodes once aliases are expanded: an alias bomb is refused after composing this many, never expanded
MAX_DEPTH = 100  # levels of nesting, aliases expanded: far beyond any config, far below Python's recursion limit


def format_path(path: PathKey) -> str:
    """`('robots', 'arm', 'edges', 0)` -> `robots.arm.edges[0]`: the YAML path shown in messages."""
    text = ""
    for part in path:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


class Lines(dict[PathKey, int]):
    """The 1-based line of every YAML path with, in `columns`, its 1-based column.

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


_STANDARD = "tag:yaml.org,2002:"
_MERGE, _VALUE = _STANDARD + "merge", _STANDARD + "value"  # `<<` and `=`, as PyYAML resolves them
_TAGS = {  # the explicit tags a config may carry: YAML's own, for plain data
    yaml.ScalarEvent: {_STANDARD + name for name in ("null", "bool", "int", "float", "str", "timestamp")},
    yaml.SequenceStartEvent: {_STANDARD + "seq"},
    yaml.MappingStartEvent: {_STANDARD + "map"},
}


@dataclass
class _Flow:
    """A flow collection (`[...]` or `{...}`) the scanner opened, and where it closed, to name it in syntax errors."""

    start: yaml.Mark
    kind: str  # "sequence" or "mapping"
    end: int | None = None  # the index of its closing bracket


class _Loader(yaml.SafeLoader):
    """YAML 1.1 as PyYAML reads it (safely), except that 1e-3 is a number (as in YAML 1.2 and JSON), bounded while
    composing (the module's docstring): an alias counts as the nodes and levels of its anchor, never expanded."""

    def __init__(self, text: str, file: Path) -> None:
        self.file = file
        self.depth = 0  # of the node being composed (the root is at 1)
        self.deepest = 0  # the deepest level reached inside the node being composed, aliases expanded
        self.total = 0  # nodes composed so far, aliases expanded
        self.extent: dict[int, tuple[int, int]] = {}  # id(anchored node) -> (its nodes, its levels below it), expanded
        self.flows: list[_Flow] = []
        self.open_flows: list[_Flow] = []
        super().__init__(text)

    def compose_node(self, parent: Any, index: Any) -> Any:
        event = self.peek_event()
        if isinstance(event, yaml.AliasEvent):
            node = super().compose_node(parent, index)  # refuses an undefined alias
            self._expand_alias(event, node)
            return node
        self.depth += 1
        if self.depth > MAX_DEPTH:
            raise self._refuse(
                f"nested more than {MAX_DEPTH} levels deep (lists and mappings inside each other); a config is a few levels "
                "deep: is this the right file, or is a '[' or '{' never closed?",
                event.start_mark,
            )
        if event.tag not in (None, "!") and event.tag not in _TAGS.get(type(event), ()):
            raise self._refuse(
                f"the tag {_shown(event.tag)} is not allowed (nothing was constructed or run): a config holds plain data "
                "(text, numbers, true/false, null, lists, mappings); remove the tag",
                event.start_mark,
            )
        self.total += 1
        if self.total > MAX_NODES:
            raise self._refuse(
                f"more than {MAX_NODES:,} YAML nodes (keys, values and list items): far more than any config or edges file "
                "needs; is this the right file?",
                event.start_mark,
            )
        before, outer = self.total - 1, self.deepest
        self.deepest = self.depth
        node = super().compose_node(parent, index)
        if event.anchor is not None:
            self.extent[id(node)] = (self.total - before, self.deepest - self.depth)
        self.deepest = max(outer, self.deepest)
        self.depth -= 1
        return node

    def _expand_alias(self, event: Any, node: Any) -> None:
        """Count the alias as the nodes and levels of its anchor, without expanding it."""
        anchor = f"&{event.anchor} (line {node.start_mark.line + 1})"
        if id(node) not in self.extent:
            raise self._refuse(
                f"the alias *{event.anchor} is inside its own anchor {anchor}: a value that contains itself never ends; "
                "write the value out instead",
                event.start_mark,
            )
        nodes, levels = self.extent[id(node)]
        self.total += nodes
        if self.total > MAX_NODES:
            raise self._refuse(
                f"with its aliases expanded, this file has more than {MAX_NODES:,} YAML nodes: *{event.anchor} repeats "
                f"{anchor}, which alone stands for {nodes:,} nodes (an alias bomb?); reuse large anchors less often, or "
                "write the data out",
                event.start_mark,
            )
        deepest = self.depth + 1 + levels
        if deepest > MAX_DEPTH:
            raise self._refuse(
                f"with its aliases expanded, this file is nested more than {MAX_DEPTH} levels deep: *{event.anchor} puts "
                f"{anchor}, {levels + 1} level(s) deep, at level {self.depth + 1}; write the value out, or nest fewer "
                "anchors inside each other",
                event.start_mark,
            )
        self.deepest = max(self.deepest, deepest)

    def _refuse(self, message: str, mark: yaml.Mark) -> UserError:
        return UserError(message, Where(self.file, mark.line + 1, column=mark.column + 1))

    def fetch_flow_sequence_start(self) -> None:
        self._open_flow("sequence")
        super().fetch_flow_sequence_start()

    def fetch_flow_mapping_start(self) -> None:
        self._open_flow("mapping")
        super().fetch_flow_mapping_start()

    def fetch_flow_collection_end(self, token_class: Any) -> None:
        if self.open_flows:
            self.open_flows.pop().end = self.index
        super().fetch_flow_collection_end(token_class)

    def _open_flow(self, kind: str) -> None:
        self.flows.append(_Flow(self.get_mark(), kind))
        self.open_flows.append(self.flows[-1])

    def flow_around(self, index: int) -> _Flow | None:
        """The innermost flow collection that holds the character at `index` (the scanner may have read beyond it)."""
        inside = [flow for flow in self.flows if flow.start.index < index and (flow.end is None or flow.end >= index)]
        return max(inside, key=lambda flow: flow.start.index, default=None)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


def _shown(tag: str) -> str:
    """`tag:yaml.org,2002:python/name:os.system` -> `!!python/name:os.system`, as it was most likely written."""
    return "!!" + tag[len(_STANDARD) :] if tag.startswith(_STANDARD) else tag


def read_text(file: Path, what: str = "config file") -> str:
    """The file's text, refused before any parsing when it is larger than MAX_BYTES, not UTF-8, or holds a NUL or
    another character YAML forbids (at that character's line and column)."""
    state = file_state(file, f"the {what}", Where(file, 0))  # a FIFO or a device would keep the read waiting forever
    if state == "folder":
        raise UserError(f"the {what} is a folder, not a file", Where(file, 0))
    try:
        with file.open("rb") as stream:
            raw = stream.read(MAX_BYTES + 1)
    except FileNotFoundError:
        raise UserError(f"{what} not found", Where(file, 0)) from None
    except OSError as exc:
        raise UserError(f"cannot read the {what}: {exc.strerror or exc}", Where(file, 0)) from None
    if len(raw) > MAX_BYTES:
        raise UserError(
            f"the {what} is larger than {MAX_BYTES // 2**20} MB, the most this tool reads as YAML or JSON: is this the right file?",
            Where(file, 0),
        )
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        column = len(raw[raw.rfind(b"\n", 0, exc.start) + 1 : exc.start].decode("utf-8", "replace")) + 1
        utf16 = " (it starts like UTF-16)" if raw.startswith((b"\xff\xfe", b"\xfe\xff")) else ""
        raise UserError(
            f"byte 0x{raw[exc.start]:02x} is not UTF-8: the {what} must be UTF-8 text{utf16}; save it as UTF-8",
            Where(file, line, column=column),
        ) from None
    _check_characters(text, file)
    return text


def _check_characters(text: str, file: Path) -> None:
    """Refuse a NUL byte or a control character at its line and column (PyYAML would name only an offset)."""
    found = yaml.reader.Reader.NON_PRINTABLE.search(text)
    if found is None:
        return
    index, character = found.start(), found.group()
    line, column = text.count("\n", 0, index) + 1, index - text.rfind("\n", 0, index)
    name = "a NUL byte" if character == "\0" else f"the control character U+{ord(character):04X}"
    raise UserError(
        f"{name}: YAML text cannot hold it (is this a binary file?); remove it",
        Where(file, line, column=column),
    )


def load_document(file: Path, what: str = "config file") -> Document:
    """Read and parse a YAML (or JSON) file within the bounds; syntax errors, duplicate keys and anything beyond the
    bounds are user errors with a line and column."""
    return parse_document(read_text(file, what), file)


def parse_document(text: str, file: Path) -> Document:
    _check_characters(text, file)
    loader = _Loader(text, file)
    try:
        root = loader.get_single_node()
    except yaml.MarkedYAMLError as exc:
        raise _syntax_error(exc, loader, file) from None
    except yaml.YAMLError as exc:  # not expected after _check_characters: still a problem of the file, not a bug
        raise UserError(f"YAML error: {exc}", Where(file, 1)) from None
    finally:
        loader.dispose()
    lines = Lines()
    if root is None:
        return Document(file, None, lines)
    lines.mark((), root.start_mark)
    data = _convert(root, (), lines, file, yaml.constructor.SafeConstructor())
    return Document(file, data, lines)


def _syntax_error(exc: yaml.MarkedYAMLError, loader: _Loader, file: Path) -> UserError:
    """`YAML syntax error: ...` where the parser stopped, naming the flow collection it was in and where that opened."""
    mark = exc.problem_mark or exc.context_mark
    line, column = (mark.line + 1, mark.column + 1) if mark else (1, 0)
    flow = loader.flow_around(mark.index) if mark else None
    context = exc.context if flow is None or exc.context != f"while parsing a flow {flow.kind}" else None  # said below
    problem = " ".join(part for part in (context, exc.problem) if part)
    if flow is not None:
        bracket = "]" if flow.kind == "sequence" else "}"
        problem += (
            f", in the flow {flow.kind} opened at line {flow.start.line + 1}, column {flow.start.column + 1}: "
            f"check the commas between its items and its closing '{bracket}'"
        )
    return UserError(f"YAML syntax error: {problem}", Where(file, line, column=column))


def _at(file: Path, mark: yaml.Mark, path: PathKey) -> Where:
    return Where(file, mark.line + 1, format_path(path), mark.column + 1)


def _convert(node: yaml.Node, path: PathKey, lines: Lines, file: Path, constructor: yaml.constructor.SafeConstructor) -> Any:
    """Plain data from a composed node, marking the line and column of every path. Aliases are walked as often as they
    are used, which the loader's bounds keep small."""
    if isinstance(node, yaml.MappingNode):
        result: dict[str, Any] = {}
        for key, (key_node, value_node) in _entries(node, path, file, constructor).items():
            child = (*path, key)
            lines.mark(child, key_node.start_mark)
            result[key] = _convert(value_node, child, lines, file, constructor)
        return result
    if isinstance(node, yaml.SequenceNode):
        items = []
        for index, item in enumerate(node.value):
            lines.mark((*path, index), item.start_mark)
            items.append(_convert(item, (*path, index), lines, file, constructor))
        return items
    assert isinstance(node, yaml.ScalarNode), f"a YAML node is a mapping, a sequence or a scalar, not {type(node).__name__}"
    return _scalar(node, path, file, constructor)


Pair = tuple[yaml.Node, yaml.Node]


def _entries(node: yaml.MappingNode, path: PathKey, file: Path, constructor: yaml.constructor.SafeConstructor) -> dict[str, Pair]:
    """key -> (key node, value node): the mapping's own keys, which must not repeat, over the keys merged in with
    `<<: *anchor` or `<<: [*a, *b]` (an own key overrides a merged one; of merged ones the first wins, as in YAML)."""
    own: dict[str, Pair] = {}
    merged: dict[str, Pair] = {}
    for key_node, value_node in node.value:
        if key_node.tag == _MERGE:
            for source in value_node.value if isinstance(value_node, yaml.SequenceNode) else [value_node]:
                if not isinstance(source, yaml.MappingNode):
                    raise UserError(
                        "'<<' merges a mapping or a list of mappings (<<: *defaults) into this one", _at(file, source.start_mark, path)
                    )
                for key, pair in _entries(source, path, file, constructor).items():
                    merged.setdefault(key, pair)
            continue
        key = _key(key_node, path, file, constructor)
        if key in own:
            raise UserError(
                f"duplicate key '{key}' (first at line {own[key][0].start_mark.line + 1}); YAML would silently keep only the last",
                _at(file, key_node.start_mark, (*path, key)),
            )
        own[key] = (key_node, value_node)
    return {**merged, **own}


def _key(node: yaml.Node, path: PathKey, file: Path, constructor: yaml.constructor.SafeConstructor) -> str:
    key = _scalar(node, path, file, constructor) if isinstance(node, yaml.ScalarNode) else []
    if not isinstance(key, (str, int, float, bool)) and key is not None:
        raise UserError("mapping keys must be scalars", _at(file, node.start_mark, path))
    return key if isinstance(key, str) else str(key)


def _scalar(node: yaml.ScalarNode, path: PathKey, file: Path, constructor: yaml.constructor.SafeConstructor) -> Any:
    if node.tag in (_MERGE, _VALUE):  # `<<` or `=` where no merge is possible: the text itself
        return node.value
    try:
        return constructor.construct_object(node, deep=True)
    except (yaml.MarkedYAMLError, ValueError, OverflowError) as exc:  # 2024-13-45, a 5000-digit number
        reason = exc.problem if isinstance(exc, yaml.MarkedYAMLError) else str(exc)
        value = node.value if len(node.value) <= 40 else node.value[:40] + "..."
        raise UserError(
            f"cannot read {value} as {_shown(node.tag)} ({reason}); quote it to keep it as text", _at(file, node.start_mark, path)
        ) from None
