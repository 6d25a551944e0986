import json
from importlib.metadata import version
from pathlib import Path

import jsonschema
import pytest

from urdf_pipeline.config.document import parse_document
from urdf_pipeline.config.schema import schema, schema_text, validate_document
from urdf_pipeline.errors import UserError

REPO = Path(__file__).resolve().parents[2]


def test_top_level_schema_file_is_the_shipped_one() -> None:
    assert (REPO / "schemas" / "urdf-pipeline.schema.json").read_text() == schema_text()


def test_schema_is_valid_2020_12_with_id() -> None:
    jsonschema.Draft202012Validator.check_schema(schema())
    assert schema()["$schema"].endswith("2020-12/schema") and schema()["$id"]


def _walk(node, path=""):
    if isinstance(node, dict):
        yield path, node
        for key, value in node.items():
            yield from _walk(value, f"{path}/{key}")
    elif isinstance(node, list):
        for index, value in enumerate(node):
            yield from _walk(value, f"{path}/{index}")


def test_every_key_is_described_and_objects_are_closed() -> None:
    for path, node in _walk(schema()):
        for key, sub in node.get("properties", {}).items():
            assert "description" in sub, f"{path}/properties/{key} has no description"
        if node.get("type") == "object" and "properties" in node:
            assert node.get("additionalProperties") is False, f"{path} allows unknown keys"


def test_every_schema_error_is_reported_with_its_line() -> None:
    text = "version: 2\nsources: {}\nrobots:\n  arm:\n    urdf: 3\n    jionts: {}\noutput: {path: x.rrd}\n"
    doc = parse_document(text, Path("c.yaml"))
    with pytest.raises(UserError) as error:
        validate_document(doc)
    lines = "\n".join(error.value.lines())
    assert "c.yaml:1:1: version: must be 1, got 2" in lines
    assert "c.yaml:6:5: robots.arm.jionts: unknown key 'jionts' (did you mean 'joints'?)" in lines
    assert "c.yaml:5:5: robots.arm.urdf: wrong type" in lines
    assert "missing required key 'application_id'" in lines
    assert len(error.value.lines()) >= 5


def test_cli_prints_the_schema(run_cli) -> None:
    result = run_cli("schema")
    assert result.code == 0 and json.loads(result.out)["$id"] == schema()["$id"]


def test_id_is_the_released_schema_of_the_installed_version() -> None:
    """A config keeps the schema of the release it was written for: the URL names the tag of this version."""
    expected = (
        f"https://raw.githubusercontent.com/urdf-pipeline/urdf-pipeline/v{version('urdf-pipeline')}/schemas/urdf-pipeline.schema.json"
    )
    assert schema()["$id"] == expected


def test_cli_writes_the_schema_to_a_file(run_cli, tmp_path: Path) -> None:
    target = tmp_path / "repo" / "schemas" / "urdf-pipeline.schema.json"
    result = run_cli("schema", "-o", str(target))
    assert result.code == 0 and result.out == "" and result.err == ""
    assert target.read_text(encoding="utf-8") == schema_text()
    target.write_text("old")
    assert run_cli("schema", "--output", str(target)).code == 0 and target.read_text(encoding="utf-8") == schema_text()
    assert sorted(p.name for p in target.parent.iterdir()) == [target.name]  # no temporary file left
    refused = run_cli("schema", "-o", str(tmp_path / "repo" / "schemas"))  # a folder
    assert refused.code == 1 and refused.err.startswith(f"error: cannot write the schema to {tmp_path / 'repo' / 'schemas'}")
    assert sorted(p.name for p in target.parent.iterdir()) == [target.name]
    (tmp_path / "file").write_text("")
    assert "cannot write the schema" in run_cli("schema", "-o", str(tmp_path / "file" / "schema.json")).err  # parent is a file
