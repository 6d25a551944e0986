"""A URDF text as XML, read as ROS reads it, with every element's line; what no URDF reader would read is refused here
(docs/urdf.md says what and why: xacro content, a `<link>` or `<joint>` not directly in `<robot>`, a DOCTYPE that
declares entities or names a DTD, which ROS's parser would not expand, so the robot would differ from ROS's).

The xacro sandbox applies the same DOCTYPE rule to every xacro file (`doctype_refusal`); MJCF and COLLADA files, read
by other tools again, refuse any DOCTYPE from their bytes (`doctype_line`).
"""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET
from xml.parsers.expat import ExpatError, ParserCreate

from ..errors import quoted, shown

MAX_DEPTH = 100  # element nesting; a URDF needs about six levels
MAX_URDF_BYTES = 16 << 20  # one URDF text (a file, xacro's output, a bag's); real ones are at most a few MB
MAX_ELEMENTS = 200_000  # elements of one URDF: a 20,000-link chain has 120,000; parsed in about 3 s and 150 MB
XACRO_NAMESPACE = "ros.org/wiki/xacro"  # http://www.ros.org/wiki/xacro, with or without www, http or https
# Extensions that hold elements named <joint> (a transmission's joint, ros2_control's interfaces) or SDF of their own.
FOREIGN_CONTAINERS = frozenset({"transmission", "gazebo", "ros2_control"})
SHOWN_VALUE = 60  # characters of an attribute value quoted in a message
_LEADING = re.compile(r"\ufeff?[ \t\r\n]+(?=<\?xml[ \t\r\n?])")
_DECLARATION_END = "?>"
# xacro's substitutions in attribute values: ${expression} and $(arg|find|eval|env|optenv|dirname|cwd ...).
_XACRO_EXPRESSION = re.compile(r"\$\{|\$\((?:arg|find|eval|env|optenv|dirname|cwd)\b")
_DOCTYPE = re.compile(rb"<!doctype", re.IGNORECASE)


def doctype_line(data: bytes) -> int | None:
    """The line of the first `<!DOCTYPE` in `data` (the raw bytes, before any XML parser reads them; NUL bytes are
    skipped, so UTF-16 and UTF-32 text is searched too), else None. One search for every file type that may hold no
    DOCTYPE at all (MJCF, COLLADA): the text `<!DOCTYPE` anywhere, a comment included, refuses the file."""
    plain = data.replace(b"\0", b"") if b"\0" in data else data
    match = _DOCTYPE.search(plain)
    return None if match is None else plain.count(b"\n", 0, match.start()) + 1


def doctype_refusal(name: str, system_id: str | None, public_id: str | None, has_internal_subset: bool) -> str | None:
    """Why a URDF's or xacro file's `<!DOCTYPE>` is refused (what expat reports of it), or None for a bare one."""
    if has_internal_subset:
        found = f"<!DOCTYPE {shown(name)} [...]> declares entities (an internal subset)"
    elif system_id is not None or public_id is not None:
        found = f"<!DOCTYPE {shown(name)} ... {quoted(system_id or public_id or '')}> names an external DTD"
    else:
        return None
    return (
        f"{found}: ROS's URDF parser (urdfdom, TinyXML2) reads no DTD and expands no entity, so the robot would mean "
        f"something else to ROS than here; write the entities' text in place and keep at most a bare <!DOCTYPE {shown(name)}>"
    )


class UrdfParseError(Exception):
    """The file is not a usable URDF; the caller turns each message into a user error at the config line."""

    def __init__(self, *messages: str) -> None:
        super().__init__("; ".join(messages))
        self.messages = messages


class XacroContent(UrdfParseError):
    """A text given as URDF that holds xacro: `found` (`<xacro:include filename="arm.xacro">`) at `line` of `origin`.
    `advice(fix)` is the user's message with the fix of the form at hand (the config's xacro form, init's --xacro)."""

    def __init__(self, origin: str, line: int, found: str) -> None:
        self.origin, self.line, self.found = origin, line, found
        super().__init__(self.advice(f"expand it as xacro: urdf: {{xacro: {origin}}}"))

    def advice(self, fix: str, what: str = "this file") -> str:
        return (
            f"{self.origin}:{self.line}: {self.found} is xacro: {what} is a xacro file, not a URDF, and a URDF reader would "
            f"keep only what lies outside its xacro elements (often just the root link); {fix}"
        )


class _PrologRead(Exception):
    """The root element started: the prolog, where a DOCTYPE may stand, has been read."""


def prolog_refusal(data: bytes) -> str | None:
    """`LINE: why` when the prolog of `data` holds a DOCTYPE `doctype_refusal` refuses, else None; expat reads only up
    to the root element (no entity is declared or expanded). For a file another parser reads next (xacro's minidom,
    which would expand the entities): malformed XML is left for that parser to report."""
    parser = ParserCreate()
    found: list[str] = []

    def doctype(name: str, system_id: str | None, public_id: str | None, has_internal_subset: int) -> None:
        refusal = doctype_refusal(name, system_id, public_id, bool(has_internal_subset))
        if refusal is not None:
            found.append(f"{parser.CurrentLineNumber}: {refusal}")
        raise _PrologRead

    def root(*_: object) -> None:
        raise _PrologRead

    parser.StartDoctypeDeclHandler = doctype
    parser.StartElementHandler = root
    try:
        parser.Parse(data, True)
    except (_PrologRead, ExpatError):
        pass
    return found[0] if found else None


def _blank_leading_declaration(text: str) -> str:
    """The leading space and the declaration after it replaced by spaces (line breaks kept): lines and columns stay."""
    match = _LEADING.match(text)
    if match is None:
        return text
    end = text.find(_DECLARATION_END, match.end())
    if end < 0:
        return text  # an unclosed declaration: expat says so
    end += len(_DECLARATION_END)
    return re.sub(r"[^\n]", " ", text[:end]) + text[end:]


def _shown(tag: str, attributes: dict[str, str], attribute: str | None = None) -> str:
    """`<tag name="value">` for a message: the attribute at fault (else the first), its value shortened."""
    name = attribute if attribute is not None else next(iter(attributes), None)
    if name is None:
        return f"<{tag}>"
    value = attributes[name]
    value = value if len(value) <= SHOWN_VALUE else value[:SHOWN_VALUE] + "..."
    return f'<{tag} {name}="{value}">'


class _Scan:
    """The checks made on each element as expat reads it (so a 20,000-link file is read once): depth, xacro, nesting."""

    def __init__(self, origin: str, source_lines: bool) -> None:
        self.origin = origin
        self.source_lines = source_lines
        self.xacro_prefixes = {"xacro"}
        self.open: list[tuple[str, int]] = []  # the elements enclosing this one: tag, line
        self.foreign = 0  # how many enclosing elements are FOREIGN_CONTAINERS
        self.elements = 0

    def at(self, line: int) -> str:
        return f"{self.origin}:{line}" if self.source_lines else f"{self.origin} (line {line} of the expanded text)"

    def start(self, tag: str, attributes: dict[str, str], line: int) -> None:
        if len(self.open) >= MAX_DEPTH:  # a URDF is a few levels deep; thousands would exhaust recursion further on
            raise UrdfParseError(f"{self.at(line)}: elements nested more than {MAX_DEPTH} levels deep")
        self.elements += 1
        if self.elements > MAX_ELEMENTS:  # each one costs a few hundred bytes in the tree and the model
            raise UrdfParseError(
                f"{self.at(line)}: more than {MAX_ELEMENTS:,} elements (<{shown(tag)}> crosses the bound); no robot needs so many"
            )
        self._xacro(tag, attributes, line)
        if tag in ("link", "joint") and len(self.open) > 1 and not self.foreign:  # depth 1 is <robot>'s own
            parent, parent_line = self.open[-1]
            raise UrdfParseError(
                f"{self.at(line)}: {_shown(tag, attributes)} is inside <{parent}> (line {parent_line}), not directly inside "
                f"<robot>: URDF readers (ROS, pinocchio, Rerun) ignore a <{tag}> anywhere else, so the robot would silently "
                f"lose it; move it to the top level of <robot>"
            )
        self.open.append((tag, line))
        self.foreign += tag in FOREIGN_CONTAINERS

    def end(self, tag: str) -> None:
        self.open.pop()
        self.foreign -= tag in FOREIGN_CONTAINERS

    def _xacro(self, tag: str, attributes: dict[str, str], line: int) -> None:
        expression = None
        for name, value in attributes.items():
            if "$" in value and _XACRO_EXPRESSION.search(value):
                expression = expression or name
            elif name.startswith("xmlns:") and XACRO_NAMESPACE in value:
                self.xacro_prefixes.add(name[len("xmlns:") :])
        prefix, colon, _ = tag.partition(":")
        if colon and prefix in self.xacro_prefixes:
            raise XacroContent(self.origin, line, _shown(tag, attributes))
        if expression is not None:
            raise XacroContent(self.origin, line, _shown(tag, attributes, expression))


def parse_root(text: str, origin: str, source_lines: bool = True) -> tuple[ET.Element, dict[int, int]]:
    """The <robot> element and the line of each element (by id). Like ROS's parser (tinyxml2), namespace-unaware:
    `<robot xmlns="...">` is a <robot>. UrdfParseError (XacroContent for xacro) for what no URDF reader reads;
    `source_lines` says whether the text is the file itself (else lines are named as the expanded text's)."""
    if len(text) > MAX_URDF_BYTES:  # a backstop: each form reads at most this much (a file, xacro's output, a bag's)
        raise UrdfParseError(f"{origin} holds more than {MAX_URDF_BYTES >> 20} MB of URDF text; real robots need at most a few MB")
    builder, lines = ET.TreeBuilder(), {}
    parser = ParserCreate()
    scan = _Scan(origin, source_lines)

    def start(tag: str, attributes: dict[str, str]) -> None:
        line = parser.CurrentLineNumber
        scan.start(tag, attributes, line)
        lines[id(builder.start(tag, attributes))] = line

    def end(tag: str) -> None:
        scan.end(tag)
        builder.end(tag)

    def doctype(name: str, system_id: str | None, public_id: str | None, has_internal_subset: int) -> None:
        refusal = doctype_refusal(name, system_id, public_id, bool(has_internal_subset))
        if refusal is not None:  # raised as expat starts the DOCTYPE: no entity of it is ever declared
            raise UrdfParseError(f"{scan.at(parser.CurrentLineNumber)}: {refusal}")

    parser.StartDoctypeDeclHandler = doctype
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = builder.data
    try:
        parser.Parse(_blank_leading_declaration(text), True)
    except ExpatError as exc:
        raise UrdfParseError(f"{origin} is not valid XML: {exc}") from None
    robot = builder.close()
    if robot.tag != "robot":
        raise UrdfParseError(f"{origin}: root element is <{robot.tag}>, not <robot>")
    return robot, lines
