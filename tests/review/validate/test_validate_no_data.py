"""`validate --no-data`: a config repository without its datasets. Every check that needs no source file still fires,
at the same place with the same message as plain `validate`; no source file is opened, no data path globbed."""

from __future__ import annotations

import builtins
import glob
import io
import json
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

from urdf_pipeline.compile import FROM_CONFIG, check_config
from urdf_pipeline.review.validate.annotations import ConfigResult, validate_config
from urdf_pipeline.sources import KINDS, lerobot

from ...compile import test_invalid_configs
from ...compile.test_invalid_configs import CASES, COMPILE_CASES, Case
from ...conftest import CONFIGS, assert_commands_leave_out

invalid_dir = test_invalid_configs.invalid_dir  # the fixture: the examples plus every case and the inputs they need
BY_NAME = {case.name: case for case in CASES}
SHIPPED = sorted(path.name for path in CONFIGS.glob("*.yaml"))
# A source's name lookups that only its data can answer: left to validate with the data when the names are unknown.
NAMES_FROM_DATA = ("is not a name of source", "neither mapped nor ignored", "ignored name", "has no value named")
# Output checks that need the segments' number or names (episodes of the dataset, files of a glob).
SEGMENTS_FROM_DATA = {"path_without_segment_placeholder", "segment_duplicate_ids", "episodes_out_of_range", "episodes_range_selects_none"}
# Edge checks that read a source's file: a bag's /tf frames (edges with `tf: SOURCE`).
EDGES_FROM_DATA = {"tf_edge_unknown_child"}
# One case per check the issue names: a bad URDF path, an unresolved mesh, an unmapped movable joint, a frame with
# no edge to the root, a schema error; and a map entry naming no source value, when the config gives the names.
CHECKS = (
    "missing_urdf_file",
    "unresolved_mesh",
    "unmapped_urdf_joint",
    "missing_calibration_edge",
    "missing_required_key",
    "map_name_not_in_source",
)


@pytest.fixture
def no_data_dir(examples_dir: Path, allow_examples: Path, tmp_path: Path) -> Path:
    """A config repository: the shipped configs and the robots (linked from the examples, which the runner allows),
    and no data folder at all."""
    directory = tmp_path / "repo"
    directory.mkdir()
    (directory / "robots").symlink_to(examples_dir / "robots", target_is_directory=True)
    for name in SHIPPED:
        (directory / name).write_bytes((examples_dir / name).read_bytes())
    return directory


@pytest.fixture
def no_source_reads(monkeypatch: pytest.MonkeyPatch, examples_dir: Path) -> Iterator[None]:
    """Every way a source could be read fails the test: each kind's entry points, LeRobot's episode list, globbing,
    and Python's open() of anything under the examples' data folder."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError(f"a source was read: {args}")

    for module in KINDS.values():
        for function in ("compile_source", "open_stream", "describe"):
            monkeypatch.setattr(module, function, refuse)
    monkeypatch.setattr(lerobot, "episodes", refuse)
    monkeypatch.setattr(glob, "glob", refuse)
    real_open = io.open
    data = (examples_dir / "data").resolve()

    def guarded_open(file: object, *args: object, **kwargs: object) -> object:
        if isinstance(file, str | Path) and Path(file).resolve().is_relative_to(data):
            raise AssertionError(f"a source was read: {file} was opened")
        return real_open(file, *args, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(io, "open", guarded_open)
    monkeypatch.setattr(builtins, "open", guarded_open)
    yield


def _errors(result: ConfigResult) -> set[str]:
    return {problem.line() for problem in result.errors}


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_configs_pass_without_their_data(name: str, no_data_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli) -> None:
    monkeypatch.chdir(no_data_dir)
    without = run_cli("validate", "--no-data", name)
    assert (without.code, without.out) == (0, f"ok: {name}\n"), without.err
    assert "error" not in without.err
    data = yaml.safe_load((no_data_dir / name).read_text(encoding="utf-8"))
    nameless = [source for source, spec in data["sources"].items() if "names" not in spec]
    notes = [line for line in without.err.splitlines() if line.startswith("note: ")]
    assert len(notes) == len(nameless), without.err  # one note per source whose names only its data holds
    for source, note in zip(nameless, notes, strict=True):
        assert f": sources.{source}: names unknown without data" in note

    with_data = run_cli("validate", name)  # the data is elsewhere: plain validate cannot pass here
    assert with_data.code == 1 and "sources." in with_data.err


@pytest.mark.usefixtures("no_source_reads")
@pytest.mark.parametrize("name", SHIPPED)
def test_no_source_file_is_opened(name: str, examples_dir: Path, run_cli) -> None:
    """Beside its data (which exists here), --no-data still reads none of it."""
    result = run_cli("validate", "--no-data", str(examples_dir / name))
    assert result.code == 0, result.err
    with pytest.raises(AssertionError, match="a source was read"):
        validate_config(str(examples_dir / name))  # the guard works: plain validate reads the sources


def test_unreadable_data_does_not_matter(no_data_dir: Path, run_cli) -> None:
    (no_data_dir / "data").mkdir()
    (no_data_dir / "data" / "episode_000.parquet").write_text("not a parquet file\n")
    config = str(no_data_dir / "demo.yaml")
    assert run_cli("validate", "--no-data", config).code == 0
    refused = run_cli("validate", config)
    assert refused.code == 1 and "cannot read parquet schema" in refused.err


@pytest.mark.usefixtures("no_source_reads")
def test_a_glob_is_not_expanded(no_data_dir: Path, run_cli) -> None:
    data = yaml.safe_load((no_data_dir / "demo.yaml").read_text(encoding="utf-8"))
    data["sources"]["arm_state"]["parquet"] = "data/episodes/*.parquet"
    data["output"]["segment"] = "{stem}"
    config = no_data_dir / "globbed.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    assert run_cli("validate", "--no-data", str(config)).code == 0

    data["output"]["segment"] = "{episode:06d}_{stem:d}"  # a template that cannot be formatted: found without data
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    result = run_cli("validate", "--no-data", str(config))
    assert result.code == 1 and "output.segment: output.segment '{episode:06d}_{stem:d}' has the format spec 'd' in {stem}" in result.err


@pytest.mark.parametrize("case", COMPILE_CASES, ids=lambda case: case.name)
def test_every_check_that_needs_no_data_fires_as_validate_does(case: Case, invalid_dir: Path) -> None:
    """Each invalid case under both: --no-data reports exactly validate's errors, minus those that need a source file
    (under `sources.`), the names only the data holds, and the segments' number and names."""
    config = str(invalid_dir / f"invalid_{case.name}.yaml")
    full, bare = validate_config(config), validate_config(config, data=False)
    source_failed = any(problem.where is not None and problem.where.path.startswith("sources.") for problem in full.errors)
    if not source_failed:  # a source that failed hides its robots' errors from validate; --no-data still finds them
        assert _errors(bare) <= _errors(full)
    for problem in full.errors:
        if problem.line() in _errors(bare):
            continue
        path = problem.where.path if problem.where is not None else ""
        from_data = (
            path.startswith("sources.")
            or (path.startswith("output.") and case.name in SEGMENTS_FROM_DATA)
            or (path.startswith("edges") and case.name in EDGES_FROM_DATA)
            or (bool(bare.notes) and any(phrase in problem.message for phrase in NAMES_FROM_DATA))
        )
        assert from_data, f"--no-data missed: {problem.line()}"


@pytest.mark.parametrize("name", CHECKS)
def test_each_check_in_every_format(name: str, invalid_dir: Path, no_data_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli) -> None:
    """Beside its data, --no-data prints what validate prints, in every format; without the data, the same errors."""
    case = BY_NAME[name]
    config = f"invalid_{name}.yaml"
    monkeypatch.chdir(invalid_dir)
    for format in ("text", "github", "json"):
        full = run_cli("validate", "--format", format, config)
        bare = run_cli("validate", "--no-data", "--format", format, config)
        assert full.code == bare.code == 1
        assert (bare.out, bare.err) == (full.out, full.err), format

    (no_data_dir / config).write_bytes(case.file.read_bytes())
    monkeypatch.chdir(no_data_dir)
    text = run_cli("validate", "--no-data", config)
    assert text.code == 1 and text.out == ""
    for expected in case.expects:
        assert expected in text.err
    if case.line is not None:
        assert f"error: {config}:{case.line}:" in text.err
    assert "not found: " + str(no_data_dir / "data") not in text.err
    github = run_cli("validate", "--no-data", "--format", "github", config)
    assert github.code == 1 and github.out.startswith(f"::error file={config},")
    report = run_cli("validate", "--no-data", "--format", "json", config)
    assert report.code == 1 and {item["severity"] for item in json.loads(report.out)} == {"error"}


def test_notes_in_every_format(no_data_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli) -> None:
    monkeypatch.chdir(no_data_dir)
    config = "so101_lerobot.yaml"
    text = run_cli("validate", "--no-data", config)
    (note,) = text.err.splitlines()
    assert note.startswith(f"note: {config}:6:3: sources.so101: names unknown without data (they come from the dataset's meta/info.json)")
    github = run_cli("validate", "--no-data", "--format", "github", config)
    assert github.code == 0 and github.err == f"ok: {config}\n"
    assert github.out.startswith(f"::notice file={config},line=6,col=3::sources.so101: names unknown without data")
    report = run_cli("validate", "--no-data", "--format", "json", config)
    (item,) = json.loads(report.out)
    assert (report.code, item["severity"], item["line"], item["path"]) == (0, "note", 6, "sources.so101")


FLOATER_URDF = """<?xml version="1.0"?>
<robot name="floater">
  <link name="odom"/><link name="pelvis"/><link name="leg"/>
  <joint name="floating_base" type="floating"><parent link="odom"/><child link="pelvis"/></joint>
  <joint name="hip" type="revolute">
    <parent link="pelvis"/><child link="leg"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
</robot>
"""


def test_temporal_edge_with_names_only_the_data_holds(tmp_path: Path, run_cli) -> None:
    """A wide CSV without names drives the hip and the floating pelvis: nothing to check the value names against, and
    the temporal edge still replaces the floating joint in the frame graph (no 'two parents')."""
    (tmp_path / "floater.urdf").write_text(FLOATER_URDF, encoding="utf-8")
    edge = {
        "parent": "odom",
        "child": "pelvis",
        "source": "log",
        "translation": ["x", "y", "z"],
        "quaternion_xyzw": ["qx", "qy", "qz", "qw"],
    }
    data = {
        "version": 1,
        "sources": {"log": {"csv": "logs/run.csv", "index": "t"}},
        "robots": {"floater": {"urdf": "floater.urdf", "joints": {"source": "log", "map": {"hip": "hip"}}}},
        "edges": [edge],
        "output": {"path": "out/{segment}.rrd", "application_id": "floater", "segment": "run"},
    }
    config = tmp_path / "floater.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    result = run_cli("validate", "--no-data", str(config))
    assert result.code == 0, result.err
    assert "sources.log: names unknown without data (they come from the CSV header)" in result.err

    data["sources"]["log"]["names"] = ["hip", "x", "y", "z", "qx", "qy", "qz", "qw"]
    edge["quaternion_xyzw"] = ["qx", "qy", "qz", "qw_"]
    config.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    result = run_cli("validate", "--no-data", str(config))
    assert result.code == 1 and "source 'log' has no value named 'qw_' (did you mean 'qw'?)" in result.err


def test_the_check_returns_no_plan(examples_dir: Path) -> None:
    """Nothing a run could take: errors and notes only."""
    found = check_config(examples_dir / "demo.yaml", FROM_CONFIG)
    assert (found.errors, found.notes, found.plan) == ((), (), None)
    assert not hasattr(found, "robots") and not hasattr(found, "dataset")


def test_validate_no_data_does_not_import_rerun(examples_dir: Path) -> None:
    assert_commands_leave_out("rerun", ["validate", "--no-data", *(str(examples_dir / name) for name in SHIPPED)])
