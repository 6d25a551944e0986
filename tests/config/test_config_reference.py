"""The schema explains every key (description, example, default) and docs/config-reference.md is generated from it."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import jsonschema
import pytest

from urdf_pipeline.config.reference import keys, reference_markdown
from urdf_pipeline.config.schema import schema

REPO = Path(__file__).resolve().parents[2]
REFERENCE = REPO / "docs" / "config-reference.md"
SCHEMA_LINE = re.compile(r"^# yaml-language-server: \$schema=(\S+)$")


def test_reference_is_generated_from_the_current_schema() -> None:
    assert REFERENCE.read_text(encoding="utf-8") == reference_markdown(), (
        "docs/config-reference.md is stale: python -m urdf_pipeline.config.reference > docs/config-reference.md"
    )


@pytest.mark.parametrize("key", list(dict.fromkeys(keys())), ids=lambda k: k.path.replace("`", ""))
def test_every_key_has_a_description_an_example_and_a_default(key) -> None:
    assert key.description.strip(), "no description"
    assert key.example, "no example"
    if not key.required:
        assert key.default or "default" in key.description.lower(), "an optional key needs a default, or its description says what it is"


def _property_schemas(node: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    found = []
    if isinstance(node, dict):
        for name, spec in node.get("properties", {}).items():
            found.append((name, spec))
        for value in node.values():
            if isinstance(value, dict):
                found += _property_schemas(value)
            elif isinstance(value, list):
                for item in value:
                    found += _property_schemas(item)
    return found


def test_every_example_is_valid_for_its_key() -> None:
    root = schema()
    checked = 0
    for name, spec in _property_schemas(root):
        for example in spec.get("examples", []):
            validator = jsonschema.Draft202012Validator({"$defs": root["$defs"], **spec})
            errors = [e.message for e in validator.iter_errors(example)]
            assert not errors, f"{name}: example {example!r} is invalid: {errors}"
            checked += 1
    assert checked > 80


@pytest.mark.parametrize("config", sorted([*REPO.glob("configs/*.yaml"), *REPO.glob("tests/configs/valid/*.yaml")]), ids=lambda p: p.name)
def test_every_example_config_names_the_schema_for_editors(config: Path) -> None:
    first = config.read_text(encoding="utf-8").splitlines()[0]
    match = SCHEMA_LINE.match(first)
    assert match, f"{config.name} must start with '# yaml-language-server: $schema=...'"
    assert (config.parent / match.group(1)).resolve() == REPO / "schemas" / "urdf-pipeline.schema.json"
