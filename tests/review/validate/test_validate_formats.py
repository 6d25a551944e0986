"""`validate --format text|github|json`: every problem of every config, at its line and column, for CI and review.

Expected columns are computed from the case files' text: the column of the key (or sequence item) the problem is at,
on the case's `# expect-line`.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
import yaml

from urdf_pipeline.config.document import Document, parse_document
from urdf_pipeline.errors import Where
from urdf_pipeline.review.validate.annotations import Annotation

from ...compile.test_invalid_configs import CASES, MISSING_MESH_URI

WARNINGS_CONFIG = Path(__file__).resolve().parents[2] / "configs" / "annotations" / "warnings.yaml"
BY_NAME = {case.name: case for case in CASES}
TEXT_ERROR = re.compile(r"^error: .+:\d+:\d+: ")

# case -> (the YAML path of its error, the text on its expect-line that the error points at)
POINTS = {
    "bad_sign": ("robots.arm.joints.map.j2.sign", "sign:"),  # a key inside a flow mapping
    "unknown_key": ("robots.arm.entity_path_prefx", "entity_path_prefx:"),
    "duplicate_yaml_key": ("robots.arm.joints.unit", "unit:"),  # the second occurrence
    "wrong_type": ("robots.arm.joints.limits.slack", "slack:"),  # a problem with the value: at its key
    "wrong_version": ("version", "version:"),
    "yaml_syntax_error": ("", ": joint positions"),  # where the parser stopped
    "assume_identity_unknown_frame": ("frames.assume_identity[0]", "camera_lnk"),  # a sequence item
    "unknown_urdf_joint_in_map": ("robots.arm.joints.map.j4", "j4:"),  # found by compiling, not by the schema
    "fixed_chain_unknown_link": ("edges[1].fixed_chain.to", "to:"),
}


def _config(name: str) -> str:
    return f"formats_{name}.yaml"


def _point(name: str) -> tuple[int, int]:
    """(line, column) of the case's error, from the case file's text."""
    case = BY_NAME[name]
    assert case.line is not None, f"{name} has no expect-line"
    text = case.file.read_text(encoding="utf-8").splitlines()[case.line - 1]
    needle = POINTS[name][1]
    assert text.count(needle) == 1, f"{needle!r} is not unique on line {case.line} of {name}"
    return case.line, text.index(needle) + 1


def _lines_with(text: str, needle: str) -> int:
    (line,) = [number for number, content in enumerate(text.splitlines(), 1) if needle in content]
    return line


@pytest.fixture(scope="module")
def cases_dir(examples_dir: Path) -> Path:
    """The examples directory plus a copy of each case used here and of the warnings config (with its URDF)."""
    for name in POINTS:
        shutil.copyfile(BY_NAME[name].file, examples_dir / _config(name))
    robots = examples_dir / "robots"
    urdf = (robots / "panda.urdf").read_text(encoding="utf-8")
    original = "package://example-robot-data/robots/panda_description/meshes/visual/link3.dae"
    assert urdf.count(original) == 1
    (robots / "annotations_missing_mesh.urdf").write_text(urdf.replace(original, MISSING_MESH_URI), encoding="utf-8")
    shutil.copyfile(WARNINGS_CONFIG, examples_dir / _config("warnings"))
    return examples_dir


@pytest.fixture
def here(cases_dir: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Run from the examples directory, so configs are given (and reported) as relative paths, as in CI."""
    monkeypatch.chdir(cases_dir)
    return cases_dir


@pytest.mark.parametrize("name", sorted(POINTS))
def test_every_format_points_at_line_and_column(name: str, here: Path, run_cli) -> None:
    config, (path, _) = _config(name), POINTS[name]
    line, column = _point(name)
    where = f"{path}: " if path else ""

    github = run_cli("validate", "--format", "github", config)
    assert github.code == 1 and github.err == "", github.err
    commands = github.out.splitlines()
    assert commands and all(command.startswith(f"::error file={config},line=") for command in commands), github.out
    assert any(command.startswith(f"::error file={config},line={line},col={column}::{where}") for command in commands), github.out
    for expected in BY_NAME[name].expects:
        assert expected in github.out

    report = run_cli("validate", "--format", "json", config)
    assert report.code == 1 and report.err == ""
    items = json.loads(report.out)
    assert any(
        item.items() >= {"file": config, "line": line, "column": column, "path": path, "severity": "error"}.items() for item in items
    )
    assert [Annotation(**item).github() for item in items] == commands  # the same problems, in the same order

    text = run_cli("validate", config)
    assert text.code == 1 and text.out == ""
    assert f"error: {config}:{line}:{column}: {where}" in text.err, text.err
    assert all(TEXT_ERROR.match(error) for error in text.err.splitlines()), text.err


def test_a_valid_config_in_every_format(here: Path, run_cli) -> None:
    text = run_cli("validate", "demo.yaml")
    assert (text.code, text.out, text.err) == (0, "ok: demo.yaml\n", "")
    github = run_cli("validate", "--format", "github", "demo.yaml")
    assert (github.code, github.out, github.err) == (0, "", "ok: demo.yaml\n")
    report = run_cli("validate", "--format", "json", "demo.yaml")
    assert (report.code, json.loads(report.out), report.err) == (0, [], "ok: demo.yaml\n")


def test_every_problem_of_every_file_at_once(here: Path, run_cli) -> None:
    configs = ["demo.yaml", *(_config(name) for name in POINTS), _config("warnings")]
    report = run_cli("validate", "--format", "json", *configs)
    assert report.code == 1
    assert report.err == "ok: demo.yaml\nok: formats_warnings.yaml\n"
    items = json.loads(report.out)
    key = [(i["file"], i["line"], i["column"], i["path"], i["severity"] != "error", i["message"]) for i in items]
    assert key == sorted(key) and len(set(key)) == len(key)
    assert {i["file"] for i in items if i["severity"] == "error"} == {_config(name) for name in POINTS}
    assert {i["file"] for i in items if i["severity"] == "warning"} == {_config("warnings")}
    found = {(i["file"], i["line"], i["column"], i["path"]) for i in items}
    for name, (path, _) in POINTS.items():
        assert (_config(name), *_point(name), path) in found, name

    github = run_cli("validate", "--format", "github", *configs)
    assert github.code == 1
    assert github.out.splitlines() == [Annotation(**item).github() for item in items]

    text = run_cli("validate", *configs)
    assert text.code == 1 and text.out == "ok: demo.yaml\nok: formats_warnings.yaml\n"
    for name in POINTS:
        assert f"error: {_config(name)}:{':'.join(map(str, _point(name)))}: " in text.err, name


def test_warnings_are_annotations_and_exit_0(here: Path, run_cli) -> None:
    config = _config("warnings")
    source = WARNINGS_CONFIG.read_text(encoding="utf-8")
    robot = (_lines_with(source, "  arm:"), 3)
    frame_line = _lines_with(source, "assume_identity: [table]")
    frame = (frame_line, source.splitlines()[frame_line - 1].index("table") + 1)
    mesh = f"robots.arm: 1 mesh(es) do not resolve: {MISSING_MESH_URI} (visual of link 'panda_link3'); they will be invisible"
    assumed = "frames.assume_identity[0]: frame 'table' has no calibration; logging an identity edge from root 'world'"

    github = run_cli("validate", "--format", "github", config)
    assert github.code == 0 and github.err == f"ok: {config}\n"
    first, second = github.out.splitlines()
    assert first.startswith(f"::warning file={config},line={robot[0]},col={robot[1]}::{mesh}"), first
    assert second.startswith(f"::warning file={config},line={frame[0]},col={frame[1]}::{assumed}"), second

    report = run_cli("validate", "--format", "json", config)
    assert report.code == 0
    assert [(i["severity"], i["line"], i["column"]) for i in json.loads(report.out)] == [("warning", *robot), ("warning", *frame)]

    text = run_cli("validate", config)
    assert text.code == 0 and text.out == f"ok: {config}\n"
    assert set(text.err.splitlines()) == {
        f"warning: {config}:{frame[0]}:{frame[1]}: {assumed} (frames.assume_identity): its pose is assumed, not measured",
        f"warning: {config}:{robot[0]}:{robot[1]}: {mesh} (allow_missing_meshes: true)",
    }


@pytest.mark.parametrize(
    "sidecar, text, needle",
    [
        (
            "formats_edges.yaml",
            "- parent: world\n  child: panda_link0\n  translation: [0, 0, 0.5]\n  rpy: [0, 0, 0]\n  scale: 2\n",
            "scale",
        ),
        (
            "formats_edges.json",
            '[\n  {"parent": "world", "child": "panda_link0", "translation": [0, 0, 0.5],\n   "rpy": [0, 0, 0], "scale": 2}\n]\n',
            '"scale"',
        ),
    ],
)
def test_sidecar_problems_have_columns(sidecar: str, text: str, needle: str, here: Path, run_cli) -> None:
    (here / "calib").mkdir(exist_ok=True)
    (here / "calib" / sidecar).write_text(text, encoding="utf-8")
    data = yaml.safe_load((here / "demo.yaml").read_text(encoding="utf-8"))
    data["edges"] = [{"file": f"calib/{sidecar}"}]
    config = f"formats_with_{sidecar.replace('.', '_')}.yaml"
    (here / config).write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    line = _lines_with(text, needle)
    column = text.splitlines()[line - 1].index(needle) + 1

    github = run_cli("validate", "--format", "github", config)
    assert github.code == 1
    assert github.out.startswith(f"::error file=calib/{sidecar},line={line},col={column}::[0].scale: unknown key 'scale'"), github.out


def test_run_errors_show_the_column_too(here: Path, run_cli) -> None:
    line, column = _point("bad_sign")
    result = run_cli("run", _config("bad_sign"))
    assert result.code == 1
    assert f"error: {_config('bad_sign')}:{line}:{column}: robots.arm.joints.map.j2.sign: 2 is not one of 1, -1" in result.err


def test_github_escaping() -> None:
    annotation = Annotation("dir/a,b:c%.yaml", 3, 7, "robots.x", "error", "100% off\r\nnext: a, b")
    assert annotation.github() == "::error file=dir/a%2Cb%3Ac%25.yaml,line=3,col=7::robots.x: 100%25 off%0D%0Anext: a, b"
    whole_file = Annotation("c.yaml", 0, 0, "", "error", "config file not found")
    assert whole_file.github() == "::error file=c.yaml::config file not found"
    assert (
        Annotation.at("warning", "m", Where(Path("./x/../c.yaml"), 2, "p", 5), "other.yaml").github()
        == "::warning file=c.yaml,line=2,col=5::p: m"
    )


def test_document_keeps_a_column_per_path() -> None:
    doc = parse_document("a: 1\nb:\n  c: [1, 2]\n  d:\n    - x: 1\n      y: {z: 3}\n", Path("f.yaml"))

    def point(*path: str | int) -> tuple[int, int]:
        where = doc.where(*path)
        return where.line, where.column

    assert point("b", "c") == (3, 3)  # the key
    assert point("b", "c", 1) == (3, 10)  # a flow sequence item
    assert point("b", "d", 0) == (5, 7)  # a block sequence item, after "- "
    assert point("b", "d", 0, "y", "z") == (6, 11)  # a key in a flow mapping
    assert point("b", "missing") == (2, 1)  # the nearest existing ancestor
    assert doc.where("b", "c").prefix() == "f.yaml:3:3"
    assert Document(Path("g.json"), doc.data, doc.lines).where("b", "c").column == 3  # lines carry their columns along
    assert Where(Path("f.yaml"), 3, "b.c").prefix() == "f.yaml:3"  # no column: as before
    assert Where(Path("f.yaml"), 0).prefix() == "f.yaml"


HOSTILE = ("yaml_alias_bomb", "yaml_deep_nesting", "yaml_python_apply_tag", "yaml_nul_byte", "yaml_flow_mapping_unclosed")


def test_hostile_configs_do_not_stop_the_others(here: Path, run_cli) -> None:
    """`validate A B C` with hostile configs among valid and invalid ones: each hostile one is an error at its line,
    and every other config is still validated and reported, in every format; exit 1."""
    for name in HOSTILE:
        shutil.copyfile(BY_NAME[name].file, here / _config(name))
    configs = ["demo.yaml", *(_config(name) for name in HOSTILE), _config("unknown_key"), _config("warnings")]

    text = run_cli("validate", *configs)
    assert text.code == 1 and text.out == "ok: demo.yaml\nok: formats_warnings.yaml\n", text.out
    assert "Traceback" not in text.err and "internal error" not in text.err
    for name in (*HOSTILE, "unknown_key"):
        assert f"error: {_config(name)}:{BY_NAME[name].line}:" in text.err, name

    for format in ("json", "github"):
        result = run_cli("validate", "--format", format, *configs)
        assert result.code == 1 and result.err == "ok: demo.yaml\nok: formats_warnings.yaml\n", result.err
        items = json.loads(result.out) if format == "json" else None
        for name in (*HOSTILE, "unknown_key"):
            if items is not None:
                assert any(i["file"] == _config(name) and i["line"] == BY_NAME[name].line and i["severity"] == "error" for i in items), name
            else:
                assert f"::error file={_config(name)},line={BY_NAME[name].line}," in result.out, name


NOT_CONFIGS = {
    "calib_edges.yaml": "- parent: world\n  child: camera\n  translation: [0, 0, 1]\n  rpy: [0, 0, 0]\n",  # a sidecar
    "controllers.yaml": "controller_manager:\n  ros__parameters:\n    update_rate: 100\n",  # ROS parameters
}
STILL_CONFIGS = {  # validated, and refused: a config with a typo is never skipped
    "typo_top_key.yaml": "version: 1\nrobot: {}\n",
    "typo_every_key.yaml": "verison: 1\nsorces: {}\nrobtos: {}\n",
    "empty.yaml": "",
    "scalar.yaml": "just text\n",
    "broken.yaml": "- [unclosed\n",
}


def test_skip_non_configs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli) -> None:
    monkeypatch.chdir(tmp_path)
    for name, text in {**NOT_CONFIGS, **STILL_CONFIGS}.items():
        Path(name).write_text(text, encoding="utf-8")
    skipped = {
        "calib_edges.yaml": "a top-level list, like a sidecar file of calibration edges",
        "controllers.yaml": "a mapping with none of a config's top-level keys (version, sources, robots, frames, edges, trails, output, qa)",
    }
    lines = [f"skipped: {name}: not a urdf-pipeline config ({why})" for name, why in skipped.items()]

    text = run_cli("validate", "--no-data", "--skip-non-configs", *NOT_CONFIGS)
    assert (text.code, text.out, text.err.splitlines()) == (0, "", lines)
    report = run_cli("validate", "--skip-non-configs", "--format", "json", *NOT_CONFIGS)
    assert (report.code, json.loads(report.out), report.err.splitlines()) == (0, [], lines)
    github = run_cli("validate", "--skip-non-configs", "--format", "github", *NOT_CONFIGS)
    assert (github.code, github.out, github.err.splitlines()) == (0, "", lines)

    for name in STILL_CONFIGS:
        result = run_cli("validate", "--no-data", "--skip-non-configs", name)
        assert result.code == 1 and "skipped" not in result.err and f"error: {name}" in result.err, name
    for name in NOT_CONFIGS:  # without the option, a file that is not a config is an error as before
        result = run_cli("validate", name)
        assert result.code == 1 and f"error: {name}" in result.err, name
