"""Format templates that come from input: the config's `output.path` and `output.segment`, a LeRobot dataset's
`data_path` and `video_path`. One parser and checker for all of them, because `str.format` on a stranger's template
is a door (docs/security.md): a template is accepted only with placeholders its caller names, no attribute or item
access, no conversion, no nested field, and a spec of the placeholder's kind at most MAX_WIDTH wide (or the exact spec
a reader substitutes), so formatting it cannot fail."""

from __future__ import annotations

import re
import string
from collections.abc import Mapping
from dataclasses import dataclass

from ..errors import UserError, Where, quoted

MAX_WIDTH = 64  # of a placeholder's width and precision: a file name holds 255 bytes, `{x:08d}` is what people write
_SPEC = re.compile(
    r"(?P<align>[<>^=])?(?P<sign>[-+ ])?(?P<alternate>#)?(?P<zero>0)?(?P<width>\d+)?(?P<grouping>[,_])?"
    r"(?:\.(?P<precision>\d+))?(?P<type>[a-zA-Z%])?"
)
_TYPES = {int: frozenset("dxXob"), str: frozenset("s")}  # presentation types per kind (`c` would raise on a large int)
_SAMPLES: dict[type, int | str] = {int: 12, str: "x"}


@dataclass(frozen=True)
class Placeholder:
    """A field a template may hold: the kind of value it is given (int or str) and, when the reader that consumes the
    template only substitutes one exact text, that spec (`03d` for `{episode_chunk:03d}`; "" for `{video_key}`)."""

    kind: type[int] | type[str]
    exact: str | None = None

    def written(self, name: str) -> str:
        """How the placeholder is written: `{name}`, or `{name:SPEC}` with its exact spec."""
        return "{" + name + (f":{self.exact}" if self.exact else "") + "}"


@dataclass(frozen=True)
class Template:
    """A checked template: its text and the placeholders it holds."""

    text: str
    fields: frozenset[str]

    def format(self, **values: int | str) -> str:
        """The text with the values in; the values are of the kinds the template was checked for."""
        return self.text.format(**values)


class TemplateError(ValueError):
    """Why a template is refused, in words for its owner; the caller names the file and key."""


def parse_template(text: str, placeholders: Mapping[str, Placeholder]) -> Template:
    """`text` checked against `placeholders` (see the module's docstring); TemplateError says what is wrong."""
    try:
        parts = list(string.Formatter().parse(text))
    except ValueError as exc:  # `{` never closed, a single `}`: literal braces are written `{{` and `}}`
        raise TemplateError(f"is not a format template ({exc}); write a literal brace as {{{{ or }}}}") from None
    fields: set[str] = set()
    for _, name, spec, conversion in parts:  # one iteration per placeholder of a short template
        if name is None:
            continue
        fields.add(_checked_field(name, spec or "", conversion, placeholders))
    return Template(text, frozenset(fields))


def checked_template(text: str, placeholders: Mapping[str, Placeholder], what: str, where: Where | None) -> Template:
    """`parse_template` whose refusal is a UserError: `what` names the key (and file) that holds the template."""
    try:
        return parse_template(text, placeholders)
    except TemplateError as exc:
        raise UserError(f"{what} {quoted(text)} {exc}", where) from None


def _checked_field(name: str, spec: str, conversion: str | None, placeholders: Mapping[str, Placeholder]) -> str:
    known = ", ".join(placeholder.written(name) for name, placeholder in placeholders.items())
    if name == "" or name.isdigit():
        raise TemplateError(f"has a positional placeholder {quoted('{' + name + '}')}; name it: {known}")
    if any(mark in name for mark in ".["):
        raise TemplateError(f"reads an attribute or item in {quoted('{' + name + '}')}; placeholders are plain names: {known}")
    placeholder = placeholders.get(name)
    if placeholder is None:
        raise TemplateError(f"has the unknown placeholder {quoted('{' + name + '}')}; known: {known}")
    if conversion is not None:
        raise TemplateError(f"converts {quoted('{' + name + '!' + conversion + '}')}; remove !{conversion}")
    if "{" in spec or "}" in spec:
        raise TemplateError(f"nests a placeholder in the format spec of {{{name}}}; write the spec out, e.g. {{{name}:06d}}")
    if placeholder.exact is not None:
        if spec != placeholder.exact:
            raise TemplateError(
                f"writes {quoted('{' + name + (':' + spec if spec else '') + '}')}; the reader only knows {placeholder.written(name)}"
            )
        return name
    _check_spec(name, spec, placeholder.kind)
    return name


def _check_spec(name: str, spec: str, kind: type[int] | type[str]) -> None:
    """A spec of `kind` (the standard mini-language, no fill character), width and precision at most MAX_WIDTH."""
    match = _SPEC.fullmatch(spec)
    what = "a number" if kind is int else "text"
    if match is None or (match["type"] and match["type"] not in _TYPES[kind]):
        example = "06d" if kind is int else ".40"
        raise TemplateError(f"has the format spec {quoted(spec)} in {{{name}}}, not one for {what}; e.g. {{{name}:{example}}}")
    for part in ("width", "precision"):
        digits = match[part]
        if digits is not None and (len(digits) > 3 or int(digits) > MAX_WIDTH):
            raise TemplateError(f"asks for a {part} of {digits[:12]}{'…' if len(digits) > 12 else ''} in {{{name}}}; at most {MAX_WIDTH}")
    try:
        format(_SAMPLES[kind], spec)
    except ValueError as exc:  # a sign or `=` on text, a precision on an integer, `,` with `x`...
        raise TemplateError(f"has the format spec {quoted(spec)} in {{{name}}}, wrong for {what} ({exc})") from None
