"""The JSON Schema shipped with the package, and validation that reports every error with its line and column."""

from __future__ import annotations

import difflib
import json
import math
from collections.abc import Iterator, Mapping
from functools import lru_cache
from importlib import resources
from typing import Any

import jsonschema
from jsonschema.exceptions import ValidationError, best_match

from ..errors import Problems, UserError, shown
from .document import Document, PathKey

SCHEMA_RESOURCE = "urdf-pipeline.schema.json"


def schema_text() -> str:
    return resources.files("urdf_pipeline").joinpath("data", SCHEMA_RESOURCE).read_text(encoding="utf-8")


@lru_cache(maxsize=1)
def schema() -> dict[str, Any]:
    return json.loads(schema_text())


@lru_cache(maxsize=8)
def _validator(subschema: str | None) -> jsonschema.Draft202012Validator:
    """One validator per schema or $def and process: its references are resolved once, not per document."""
    root = schema()
    return jsonschema.Draft202012Validator(root if subschema is None else {"$ref": f"#/$defs/{subschema}", "$defs": root["$defs"]})


INT64 = 2**63  # a whole number in a config is below it in size: every count, index and size the tool keeps is an int64


def unusable_numbers(data: Any, path: PathKey = ()) -> Iterator[tuple[PathKey, str]]:
    """(path, why) of every number no key can use, wherever it is: NaN, infinities (1e999 too), a whole number beyond
    64 bits. One rule for every number key, present and future: JSON Schema's `type: number` and bounds let NaN through."""
    if isinstance(data, dict):
        for key, value in data.items():  # one iteration per key; nodes and depth are bounded by document.py
            yield from unusable_numbers(value, (*path, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield from unusable_numbers(value, (*path, index))
    elif isinstance(data, float) and not math.isfinite(data):
        kind = "NaN" if math.isnan(data) else ("an infinity" if data > 0 else "a negative infinity")
        yield (
            path,
            f"{kind} is not a number this tool can use (.nan, .inf, or a literal beyond a float's range such as 1e999): write a finite number",
        )
    elif isinstance(data, int) and not isinstance(data, bool) and not -INT64 <= data < INT64:
        yield path, f"{shown(data, 40)} is beyond a 64-bit integer (2^63): write a smaller number"


def validate_document(document: Document, subschema: str | None = None) -> None:
    """Validate against the schema (or one of its $defs); raise all errors at once, each at its line and column.
    A number no key can use (`unusable_numbers`) is refused at its own key, and the schema's errors about it (a NaN
    sign is not -1 or 1) are left out."""
    validator = _validator(subschema)
    problems = Problems()
    unusable = dict(unusable_numbers(document.data))
    for path, why in unusable.items():
        problems.add(why, document.where(*path))
    errors = sorted(validator.iter_errors(document.data), key=lambda e: (_position(document, e), list(map(str, e.absolute_path))))
    for error in errors:
        if unusable and _about(error, unusable):
            continue
        path, message = _explain(error)
        problems.add(message, document.where(*path))
    problems.raise_if_any()


def _about(error: ValidationError, unusable: dict[PathKey, str]) -> bool:
    """Whether a schema error is about an unusable number: at it or below it, or a choice (oneOf) above it."""
    path = tuple(error.absolute_path)
    return any(bad[: len(path)] == path if error.validator in ("oneOf", "anyOf") else path[: len(bad)] == bad for bad in unusable)


def _position(document: Document, error: ValidationError) -> tuple[int, int]:
    where = document.where(*error.absolute_path)
    return where.line, where.column


def _explain(error: ValidationError) -> tuple[tuple[str | int, ...], str]:
    """Turn a jsonschema error into (YAML path of the culprit, a message that says how to fix it)."""
    if error.validator in ("oneOf", "anyOf"):
        special = _rotation_choice(error)
        if special:
            return tuple(error.absolute_path), special
        if error.context:
            return _explain(best_match(_branches_of_the_right_type(error)))
    path = tuple(error.absolute_path)
    node = error.schema if isinstance(error.schema, Mapping) else {}  # the failing subschema (a bool or unset for some errors)
    if error.validator == "additionalProperties" and isinstance(error.instance, dict):
        allowed = set(node.get("properties", {}))
        extras = [key for key in error.instance if key not in allowed]
        if extras:
            key = extras[0]
            hint = difflib.get_close_matches(key, sorted(allowed), n=1)
            suggestion = f" (did you mean '{hint[0]}'?)" if hint else f"; allowed keys: {', '.join(sorted(allowed))}"
            return (*path, key), f"unknown key '{key}'{suggestion}"
    if error.validator == "required":
        return path, f"missing required key {error.message.split(' is a required')[0]}"
    if error.validator == "const":
        return path, f"must be {json.dumps(error.validator_value)}, got {json.dumps(error.instance)}"
    if error.validator == "enum":
        choices = ", ".join(json.dumps(v) for v in error.validator_value) if isinstance(error.validator_value, list) else ""
        return path, f"{json.dumps(error.instance)} is not one of {choices}"
    if error.validator == "type":
        return (
            path,
            f"wrong type: expected {error.validator_value}, got {type(error.instance).__name__} {json.dumps(error.instance, default=str)}",
        )
    if error.validator == "pattern" and error.validator_value == "\\.rrd$":
        return path, f"{json.dumps(error.instance)} must end in .rrd"
    if error.validator == "pattern" and node.get("description"):
        return path, f"{json.dumps(error.instance)} is not valid here: {node['description']}"
    return path, error.message


def _branches_of_the_right_type(error: ValidationError) -> list[ValidationError]:
    """Errors from the oneOf branches the instance was meant for: a mapping is judged by a mapping branch, and among
    those by the branch whose required keys it has ({timestamp: t, unit: h} by the timestamp form, not the sequence form)."""

    def penalty(branch: object) -> int:
        root = [e for e in error.context if e.relative_schema_path[0] == branch and not e.relative_path]
        return 2 if any(e.validator == "type" for e in root) else 1 if any(e.validator == "required" for e in root) else 0

    branches = {e.relative_schema_path[0] for e in error.context}
    best = min((penalty(b) for b in branches), default=0)
    fitting = [e for e in error.context if penalty(e.relative_schema_path[0]) == best]
    return fitting or list(error.context)


def _rotation_choice(error: ValidationError) -> str | None:
    """Edges need exactly one rotation form; say so instead of a generic oneOf failure."""
    instance = error.instance
    if not isinstance(instance, dict) or "parent" not in instance or "child" not in instance:
        return None
    given = [key for key in ("quaternion_xyzw", "rpy", "rpy_deg") if key in instance]
    if len(given) == 1:
        return None
    if not given:
        return "edge needs one rotation: quaternion_xyzw, rpy or rpy_deg (write quaternion_xyzw: [0, 0, 0, 1] for none)"
    return f"edge gives {len(given)} rotations ({', '.join(given)}); keep exactly one"


def require_schema_valid(document: Document) -> None:
    if not isinstance(document.data, dict):
        raise UserError("the config must be a YAML mapping", document.where())
    validate_document(document)
