"""Every config in tests/configs/invalid/ must be refused loudly, at the right line, before anything is written.

Each case file starts with comment lines:

    # expect: <text>        a substring that must appear in stderr (one or more such lines, all required)
    # expect-line: N        the line that must appear as `FILE:N:` in an error (optional)
    # stage: data           the problem shows only once joint values are read: `validate` must accept it (optional)
    # xfail: <reason>       a known package bug keeps the case from passing (strict xfail; optional)

Cases use paths relative to the examples directory (robots/panda.urdf, data/episode_000.parquet, ...) and write
to out/invalid/<case name>.rrd. The extra inputs some cases need are made by the `invalid_dir` fixture below.
"""

from __future__ import annotations

import os
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.examples import panda_raw_values, write_joint_parquet
from urdf_pipeline.urdf.model import read_urdf

from ..hostile_inputs import write_hostile_inputs
from ..lerobot_layouts import write_hostile_lerobot
from ..mjcf_inputs import write_mjcf_inputs
from ..source_inputs import write_source_inputs

CASES_DIR = Path(__file__).resolve().parents[1] / "configs" / "invalid"
ERROR_LINE = re.compile(r"^error: .+:\d+: ")
FRAMES = 300
MISSING_MESH_URI = "package://example-robot-data/robots/panda_description/meshes/visual/no_such_link3.dae"
MESH_VARIANTS = {  # robots/panda_NAME.urdf: link3's visual mesh at this URI
    "mesh_outside": "/etc/hostname",
    "mesh_file_uri_outside": "file:///etc/hostname",
    "package_escape": "package://example-robot-data/../../panda.urdf",
    "garbage_stl": "meshes/garbage.stl",
    "garbage_dae": "meshes/renamed.dae",
}


@dataclass(frozen=True)
class Case:
    name: str
    file: Path
    expects: tuple[str, ...]
    line: int | None
    stage: str  # "compile": found without reading joint values; "data": found only by reading them
    xfail: str | None  # a known package bug: the case's tests are strict xfails


def _load_case(file: Path) -> Case:
    expects: list[str] = []
    line: int | None = None
    stage = "compile"
    xfail: str | None = None
    for text in file.read_text(encoding="utf-8").splitlines():
        if not text.startswith("#"):
            break
        key, _, value = text[1:].strip().partition(":")
        value = value.strip()
        if key == "expect":
            expects.append(value)
        elif key == "expect-line":
            line = int(value)
        elif key == "stage":
            assert value in ("compile", "data"), f"{file.name}: unknown stage '{value}'"
            stage = value
        elif key == "xfail":
            xfail = value
    assert expects, f"{file.name}: a case needs at least one '# expect: ...' line at its top"
    return Case(file.stem, file, tuple(expects), line, stage, xfail)


def _params(cases: list[Case]) -> list:
    return [
        pytest.param(
            case, id=case.name, marks=[pytest.mark.xfail(reason=case.xfail, raises=AssertionError, strict=True)] if case.xfail else []
        )
        for case in cases
    ]


CASES = [_load_case(file) for file in sorted(CASES_DIR.glob("*.yaml"))]
COMPILE_CASES = [case for case in CASES if case.stage == "compile"]
DATA_CASES = [case for case in CASES if case.stage == "data"]


def _config(directory: Path, case: Case) -> Path:
    return directory / f"invalid_{case.name}.yaml"


def _files_under(directory: Path) -> dict[str, tuple[int, int]]:
    """Every file below `directory` (hidden ones too) -> (size, mtime_ns)."""
    found: dict[str, tuple[int, int]] = {}
    for folder, _, names in os.walk(directory):
        for name in names:
            path = Path(folder) / name
            stat = path.lstat()
            found[str(path.relative_to(directory))] = (stat.st_size, stat.st_mtime_ns)
    return found


def _partials(directory: Path) -> list[str]:
    return [name for name in _files_under(directory) if ".partial" in Path(name).name]


def _assert_refused(case: Case, config: Path, err: str) -> None:
    assert "Traceback" not in err, err
    assert "internal error" not in err, err
    errors = [line for line in err.splitlines() if line.startswith("error")]
    assert errors, f"no error line in stderr:\n{err}"
    for line in errors:
        assert ERROR_LINE.match(line), f"error line without FILE:LINE: {line!r}"
        assert line.startswith(f"error: {config}:"), f"error does not point into the config: {line!r}"
    for expected in case.expects:
        assert expected in err, f"expected {expected!r} in stderr:\n{err}"
    if case.line is not None:
        assert f"{config}:{case.line}:" in err, f"expected an error at {config.name}:{case.line}:\n{err}"


@pytest.fixture(scope="module")
def invalid_dir(examples_dir: Path) -> Path:
    """The examples directory plus the broken inputs the cases refer to, and a copy of every case."""
    robots, data = examples_dir / "robots", examples_dir / "data"
    panda_urdf = robots / "panda.urdf"
    _, panda = read_urdf(panda_urdf)

    # Right schema (frame_index, timestamp, 8-wide observation.state), zero rows.
    write_joint_parquet(data / "empty.parquet", np.zeros((0, 8)))
    # j1 (degrees) at 200 for ten rows: panda_joint1's limits are +-2.8973 rad = +-166.0 deg, slack 2 deg.
    beyond = panda_raw_values(FRAMES, panda)
    beyond[100:110, 0] = 200.0
    write_joint_parquet(data / "out_of_limits.parquet", beyond)
    # Three NaN samples of j4.
    nan = panda_raw_values(FRAMES, panda)
    nan[50:53, 3] = np.nan
    write_joint_parquet(data / "nan_values.parquet", nan)
    # MCAP, HDF5 and RRD inputs of the mcap_*, hdf5_* and rrd_* cases.
    write_source_inputs(data, panda_raw_values(FRAMES, panda))
    # Symlink loops, a file in an output folder's place, a newline in a file name, hostile HDF5 and index values.
    write_hostile_inputs(examples_dir, panda_raw_values(FRAMES, panda))
    write_mjcf_inputs(robots)  # the mjcf_* cases: robots/mjcf_arm_*.xml
    write_hostile_lerobot(data, data / "so101_lerobot")  # the metadata_* and template_*_path_* cases

    text = panda_urdf.read_text(encoding="utf-8")
    original = "package://example-robot-data/robots/panda_description/meshes/visual/link3.dae"
    assert text.count(original) == 1
    (robots / "panda_missing_mesh.urdf").write_text(text.replace(original, MISSING_MESH_URI), encoding="utf-8")
    shutil.copyfile(panda_urdf, robots / "panda.urdf.xacro")
    # The urdf_* cases: xacro content in a .urdf (line 7), a <link> inside panda_link3 (line 77).
    robot_tag = '<robot name="panda" xmlns:xacro="http://www.ros.org/wiki/xacro">'
    assert text.count(robot_tag) == 1 and text.count('    <link name="panda_link3">\n') == 1
    xacro_content = text.replace(robot_tag, robot_tag + '\n  <xacro:include filename="panda_hand.xacro"/>')
    (robots / "panda_xacro_content.urdf").write_text(xacro_content, encoding="utf-8")
    nested = text.replace('    <link name="panda_link3">\n', '    <link name="panda_link3">\n<link name="wrist_camera"/>\n')
    (robots / "panda_nested_link.urdf").write_text(nested, encoding="utf-8")
    # The path_* and mesh_* cases: link3's visual mesh replaced (see tests/urdf/test_meshes.py for every form).
    for variant, uri in MESH_VARIANTS.items():
        (robots / f"panda_{variant}.urdf").write_text(text.replace(original, uri), encoding="utf-8")
    (robots / "meshes").mkdir(exist_ok=True)
    (robots / "meshes" / "garbage.stl").write_bytes(np.random.default_rng(0).bytes(300))  # not 84 + 50 n bytes
    (robots / "meshes" / "renamed.dae").write_text("a text file renamed to .dae\n", encoding="utf-8")

    for case in CASES:
        shutil.copyfile(case.file, _config(examples_dir, case))
    (examples_dir / "out" / "invalid").mkdir(parents=True, exist_ok=True)
    return examples_dir


def test_cases_are_named_and_cover_both_stages() -> None:
    assert len({case.name for case in CASES}) == len(CASES)
    assert COMPILE_CASES and DATA_CASES


@pytest.mark.parametrize("case", _params(CASES))
def test_run_refuses_and_writes_nothing(case: Case, invalid_dir: Path, run_cli) -> None:
    config = _config(invalid_dir, case)
    out = invalid_dir / "out"
    before = _files_under(out)

    result = run_cli("run", str(config))

    assert result.code == 1, f"exit {result.code}\nstdout:\n{result.out}\nstderr:\n{result.err}"
    _assert_refused(case, config, result.err)
    assert not result.out.strip(), f"a failed run printed an output path: {result.out!r}"
    assert not (out / "invalid" / f"{case.name}.rrd").exists()
    assert _files_under(out) == before, "a failed run changed files in the output directory"
    assert not _partials(out)


@pytest.mark.parametrize("case", _params(COMPILE_CASES))
def test_validate_refuses(case: Case, invalid_dir: Path, run_cli) -> None:
    config = _config(invalid_dir, case)
    result = run_cli("validate", str(config))
    assert result.code == 1, f"exit {result.code}\nstdout:\n{result.out}\nstderr:\n{result.err}"
    _assert_refused(case, config, result.err)
    assert f"ok: {config}" not in result.out


@pytest.mark.parametrize("case", _params(DATA_CASES))
def test_validate_accepts_problems_only_the_data_shows(case: Case, invalid_dir: Path, run_cli) -> None:
    """validate reads no joint values, so it cannot (and must not pretend to) see these problems."""
    config = _config(invalid_dir, case)
    result = run_cli("validate", str(config))
    assert result.code == 0, f"exit {result.code}\nstderr:\n{result.err}"
    assert f"ok: {config}" in result.out
    assert "error" not in result.err


def test_validate_reports_every_config_at_once(invalid_dir: Path, run_cli) -> None:
    configs = [_config(invalid_dir, case) for case in COMPILE_CASES]
    result = run_cli("validate", *map(str, configs))
    assert result.code == 1
    assert "Traceback" not in result.err
    for line in result.err.splitlines():
        assert ERROR_LINE.match(line), line
    for config in configs:
        assert f"error: {config}:" in result.err, f"{config.name} not reported"


@pytest.mark.parametrize("mode", ["--no-data", "--live"])
def test_every_case_is_checked_without_its_data(mode: str, invalid_dir: Path, run_cli) -> None:
    """The compile without the data answers every case with errors and notes, never an internal error."""
    result = run_cli("validate", mode, *(str(_config(invalid_dir, case)) for case in CASES))
    assert result.code == 1 and "Traceback" not in result.err, result.err[-3000:]


def _control_text(segment: str) -> str:
    """The config the cases are made from, with its data fixed, writing `segment`."""
    text = (CASES_DIR / "limit_violation.yaml").read_text(encoding="utf-8")
    return text.replace("data/out_of_limits.parquet", "data/episode_000.parquet").replace("segment: limit_violation", f"segment: {segment}")


@pytest.mark.parametrize("case", _params(DATA_CASES))
def test_failing_run_leaves_existing_output_untouched(case: Case, invalid_dir: Path, run_cli) -> None:
    name = f"preexisting_{case.name}"
    text = case.file.read_text(encoding="utf-8")
    assert text.count(f"segment: {case.name}\n") == 1
    config = invalid_dir / f"invalid_{name}.yaml"
    config.write_text(text.replace(f"segment: {case.name}\n", f"segment: {name}\n"), encoding="utf-8")
    target = invalid_dir / "out" / "invalid" / f"{name}.rrd"
    # An earlier recording of the same segment, written by the pipeline (it replaces no file it did not write).
    earlier = invalid_dir / f"invalid_{name}_earlier.yaml"
    earlier.write_text(_control_text(name), encoding="utf-8")
    assert run_cli("run", str(earlier)).code == 0 and target.is_file()
    payload = target.read_bytes()
    stat = target.stat()

    result = run_cli("run", str(config))

    assert result.code == 1, result.err
    for expected in case.expects:
        assert expected in result.err
    assert target.read_bytes() == payload
    assert target.stat().st_mtime_ns == stat.st_mtime_ns
    assert not _partials(target.parent)


def test_control_the_cases_base_config_runs(invalid_dir: Path, run_cli) -> None:
    """The config the cases are made from, with its data fixed, runs: each case fails for its own defect only."""
    config = invalid_dir / "invalid_control_base.yaml"
    config.write_text(_control_text("control_base"), encoding="utf-8")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert (invalid_dir / "out" / "invalid" / "control_base.rrd").is_file()


def test_control_missing_mesh_allowed_explicitly(invalid_dir: Path, run_cli) -> None:
    """The unresolved-mesh case runs with allow_missing_meshes: true, with a warning that names the mesh."""
    text = (CASES_DIR / "unresolved_mesh.yaml").read_text(encoding="utf-8")
    text = text.replace("    package_paths:\n", "    allow_missing_meshes: true\n    package_paths:\n", 1)
    text = text.replace("segment: unresolved_mesh", "segment: control_allow_missing_meshes")
    config = invalid_dir / "invalid_control_allow_missing_meshes.yaml"
    config.write_text(text, encoding="utf-8")
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert "warning:" in result.err and MISSING_MESH_URI in result.err
