"""One rule for every number of a config: NaN, infinities and whole numbers beyond 64 bits are refused at their key by
the schema layer, whichever key holds them, with one error naming it (the schema's own complaints about the same
value left out). Every number of every shipped config is tried, and the YAML spellings that make one."""

from __future__ import annotations

import copy
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from urdf_pipeline.config.document import Document, format_path, parse_document
from urdf_pipeline.config.schema import validate_document
from urdf_pipeline.errors import UserError, UserErrors

from ..conftest import CONFIGS


def _numbers(data: Any, path: tuple[str | int, ...] = ()) -> Iterator[tuple[str | int, ...]]:
    if isinstance(data, dict):
        for key, value in data.items():
            yield from _numbers(value, (*path, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            yield from _numbers(value, (*path, index))
    elif isinstance(data, int | float) and not isinstance(data, bool):
        yield path


def _with(data: Any, path: tuple[str | int, ...], value: object) -> Any:
    changed = copy.deepcopy(data)
    node = changed
    for part in path[:-1]:
        node = node[part]
    node[path[-1]] = value
    return changed


def _errors(document: Document) -> list[UserError]:
    try:
        validate_document(document)
    except UserErrors as errors:
        return errors.errors
    except UserError as error:
        return [error]
    return []


CASES = [
    (config.name, path) for config in sorted(CONFIGS.glob("*.yaml")) for path in _numbers(parse_document(config.read_text(), config).data)
]


def test_the_shipped_configs_hold_numbers_of_every_kind() -> None:
    keys = {str(path[-1]) for _, path in CASES} | {str(path[-2]) for _, path in CASES if isinstance(path[-1], int)}
    assert {"translation", "quaternion_xyzw", "offset"} <= keys, keys


@pytest.mark.parametrize(("name", "path"), CASES, ids=[f"{n}:{format_path(p)}" for n, p in CASES])
@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 2**63])
def test_every_number_of_a_config_refuses_what_no_key_can_use(name: str, path: tuple[str | int, ...], value: float, tmp_path: Path) -> None:
    original = parse_document((CONFIGS / name).read_text(), CONFIGS / name)
    assert _errors(original) == []
    errors = _errors(Document(original.file, _with(original.data, path, value), original.lines))
    assert len(errors) == 1, [e.message for e in errors]
    assert errors[0].where is not None and errors[0].where.path == format_path(path)
    assert ("is not a number this tool can use" if isinstance(value, float) else "is beyond a 64-bit integer") in errors[0].message


@pytest.mark.parametrize(
    ("text", "says"),
    [
        (".nan", "NaN is not"),
        (".NaN", "NaN is not"),
        (".inf", "an infinity is not"),
        ("+.inf", "an infinity is not"),
        ("-.Inf", "a negative infinity is not"),
        ("1e999", "an infinity is not"),
        ("-1.5e400", "a negative infinity is not"),
        ("-" + "9" * 30, "-999999999999999999999999999999 is beyond a 64-bit integer"),
    ],
)
def test_every_yaml_spelling_is_refused_at_its_line_and_column(text: str, says: str) -> None:
    source = (CONFIGS / "demo.yaml").read_text()
    assert "offset: 0.1" in source
    text_written = source.replace("offset: 0.1", f"offset: {text}", 1)
    (error,) = _errors(parse_document(text_written, CONFIGS / "demo.yaml"))
    assert says in error.message and error.where is not None
    assert error.where.line == next(i for i, row in enumerate(text_written.splitlines(), 1) if f"offset: {text}" in row)
