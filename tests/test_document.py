from pathlib import Path

import pytest

from urdf_pipeline.document import format_path, parse_document
from urdf_pipeline.errors import UserError


def test_lines_are_kept_for_every_key_and_item() -> None:
    doc = parse_document("a: 1\nb:\n  c: [1, 2]\n  d:\n    - x: 1\n      y: 2\n", Path("f.yaml"))
    assert doc.data == {"a": 1, "b": {"c": [1, 2], "d": [{"x": 1, "y": 2}]}}
    assert doc.where("b", "d", 0, "y").line == 6
    assert doc.where("b", "d", 0, "y").path == "b.d[0].y"
    assert doc.where("b", "missing").line == 2  # nearest existing ancestor


def test_syntax_error_reports_its_line() -> None:
    with pytest.raises(UserError) as error:
        parse_document("a: 1\nb: [1, 2\nc: 3\n", Path("f.yaml"))
    assert error.value.where is not None and error.value.where.line == 3
    assert "YAML syntax error" in error.value.message


def test_duplicate_keys_are_refused_instead_of_silently_overwritten() -> None:
    with pytest.raises(UserError) as error:
        parse_document("map:\n  j1: a\n  j1: b\n", Path("f.yaml"))
    assert error.value.where.line == 3
    assert "duplicate key 'j1' (first at line 2)" in error.value.message


def test_format_path() -> None:
    assert format_path(("edges", 0, "child")) == "edges[0].child"


def test_scientific_notation_is_a_number_as_in_json() -> None:
    doc = parse_document("t: [1e-3, -2E+4, 1, 0.5, 1e3x]\n", Path("f.yaml"))
    assert doc.data == {"t": [0.001, -20000.0, 1, 0.5, "1e3x"]}
