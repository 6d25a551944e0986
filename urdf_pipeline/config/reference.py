"""The config reference (docs/config-reference.md), generated from the JSON Schema so the two never disagree.

Regenerate with `python -m urdf_pipeline.config.reference > docs/config-reference.md`; a test fails when the file is stale.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

from .schema import schema

HEADER = """# Config reference

Generated from `schemas/urdf-pipeline.schema.json` by `python -m urdf_pipeline.config.reference`; do not edit by
hand. Each row is one key: its YAML path (`NAME`, `KEY` and `*` stand for names you choose, `[]` for list items),
what it accepts, its default (or `required`: the key must be given wherever its parent is), what it means, and an
example. A key that chooses a form (a source kind, an edge with `fixed_chain`, `source` or `file`) first says what
that form is. Editors that read the schema (the first line of every example config,
`# yaml-language-server: $schema=...`) show the same text while you type.
"""


@dataclass(frozen=True)
class Key:
    path: str
    required: bool
    kinds: str
    default: str
    description: str
    example: str


def keys(
    node: dict[str, Any] | None = None, path: str = "", seen: frozenset[str] = frozenset(), label: str = "", form: str = ""
) -> Iterator[Key]:
    """Every documented key below `node`, depth first, in the schema's order; `$ref`s are followed (once per path).
    `label` names the form a key belongs to (a source kind, a URDF form) where the same path has several; `form` is
    that form's own description, shown once, on the key that chooses the form (`parquet`, `fixed_chain`, ...)."""
    root = schema()
    node = root if node is None else node
    for name, spec in node.get("properties", {}).items():
        key_path = f"{path}.{name}" if path else name
        resolved, refs = _resolved(root, spec)
        shown = f"{key_path}` ({label})" if label else f"{key_path}`"
        default = _json(spec.get("default", resolved.get("default")))
        required = name in node.get("required", [])
        description = _description(spec, resolved)
        if form and name == label:
            description = f"{_escaped(form)} {description}"
        yield Key(shown, required, _kinds(root, resolved), default, description, _example(spec, resolved))
        if refs & seen:
            continue
        for suffix, child, child_label, child_form in _children(root, resolved):
            yield from keys(child, key_path + suffix, seen | refs, child_label or label, child_form)


def _resolved(root: dict[str, Any], spec: dict[str, Any]) -> tuple[dict[str, Any], frozenset[str]]:
    refs: set[str] = set()
    while "$ref" in spec:
        ref = spec["$ref"]
        refs.add(ref)
        spec = {**root["$defs"][ref.rsplit("/", 1)[1]], **{k: v for k, v in spec.items() if k != "$ref"}}
    return spec, frozenset(refs)


def _children(root: dict[str, Any], spec: dict[str, Any]) -> Iterator[tuple[str, dict[str, Any], str, str]]:
    """Where more keys live: own properties, list items, named entries (`*`), and the branches of oneOf/anyOf/allOf
    and if-then-else. A branch chosen by a required key is labelled with it (`parquet`, `fixed_chain`, ...) and
    carries its description (the form's, written once in the schema); the branch that only explains a missing kind
    (`if: not ...`) adds no keys."""
    if "properties" in spec:
        yield "", spec, "", ""
    if isinstance(spec.get("items"), dict):
        items, _ = _resolved(root, spec["items"])
        for suffix, child, label, form in _children(root, items):
            yield "[]" + suffix, child, label, form
    if isinstance(spec.get("additionalProperties"), dict):
        entries, _ = _resolved(root, spec["additionalProperties"])
        for suffix, child, label, form in _children(root, entries):
            yield ".*" + suffix, child, label, form
    for combinator in ("oneOf", "anyOf", "allOf"):
        for branch in spec.get(combinator, []):
            yield from _children(root, _resolved(root, branch)[0])
    if isinstance(spec.get("if"), dict):
        required = spec["if"].get("required", [])
        if required and isinstance(spec.get("then"), dict):
            then, _ = _resolved(root, spec["then"])
            for suffix, child, label, form in _children(root, then):
                yield suffix, child, label or required[0], form or (str(then.get("description", "")) if not label else "")
        if isinstance(spec.get("else"), dict):
            yield from _children(root, _resolved(root, spec["else"])[0])


def _kinds(root: dict[str, Any], spec: dict[str, Any]) -> str:
    if "enum" in spec:
        return " \\| ".join(f"`{_json(v)}`" for v in spec["enum"])
    if "const" in spec:
        return f"`{_json(spec['const'])}`"
    kinds = spec.get("type")
    if kinds is not None:
        return " \\| ".join(kinds) if isinstance(kinds, list) else str(kinds)
    branches = spec.get("oneOf") or spec.get("anyOf") or []
    names = []
    for branch in branches:
        resolved, _ = _resolved(root, branch)
        names.append(_kinds(root, resolved))
    return " \\| ".join(dict.fromkeys(n for n in names if n)) or "see description"


def _description(spec: dict[str, Any], resolved: dict[str, Any]) -> str:
    return _escaped(str(spec.get("description") or resolved.get("description", "")))


def _escaped(text: str) -> str:
    """One table cell: a `|` would end it, a newline the row."""
    return text.replace("|", "\\|").replace("\n", " ")


def _example(spec: dict[str, Any], resolved: dict[str, Any]) -> str:
    examples = spec.get("examples") or resolved.get("examples") or []
    return " ".join(f"`{_json(e)}`" for e in examples[:2])


def _json(value: Any) -> str:
    return "" if value is None else json.dumps(value, ensure_ascii=False).replace("|", "\\|")


def reference_markdown() -> str:
    lines = [HEADER, "| key | accepts | default | meaning | example |", "| --- | --- | --- | --- | --- |"]
    for key in dict.fromkeys(keys()):  # a key reached through two equal branches (index.unit) is listed once
        default = "required" if key.required else f"`{key.default}`" if key.default else ""
        lines.append(f"| `{key.path} | {key.kinds} | {default} | {key.description} | {key.example} |")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(reference_markdown(), end="")
