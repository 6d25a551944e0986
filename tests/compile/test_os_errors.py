"""Paths the operating system cannot follow are the config's problem, never a crash: a symlink loop, a name too long,
a file where a folder is expected, a FIFO, no permission. Each hostile layout is built in tmp_path around a small
robot and refused by `validate`, `validate --no-data` (where it reads the path), `plan` and `run` with exit 1 and one
located line at the key that names the path; nothing is written."""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from urdf_pipeline.confine import ALLOW_ENV

from ..hostile_project import URDF, loop, make_project, set_key, write_config

LONG = "n" * 300  # longer than any file system's 255-byte names
LOOP = "a symbolic link loop"
TOO_LONG = "too long for the file system"

Build = Callable[[Path, dict[str, Any]], None]


@dataclass(frozen=True)
class Hostile:
    name: str
    build: Build
    key: str  # the YAML path the error is located at
    expect: str
    reads_data: bool = False  # only the commands that read sources see it (not `validate --no-data`)


def _urdf(value: Any) -> Build:
    return lambda root, data: set_key(data, "robots.arm.urdf", value)


def _urdf_loop(root: Path, data: dict[str, Any]) -> None:
    set_key(data, "robots.arm.urdf", f"robots/{loop(root / 'robots' / 'loop.urdf')}")


def _urdf_fifo(root: Path, data: dict[str, Any]) -> None:
    os.mkfifo(root / "robots" / "fifo.urdf")
    set_key(data, "robots.arm.urdf", "robots/fifo.urdf")


def _xacro_loop(root: Path, data: dict[str, Any]) -> None:
    set_key(data, "robots.arm.urdf", {"xacro": loop(root / "arm.urdf.xacro")})


def _package_loop(root: Path, data: dict[str, Any]) -> None:
    set_key(data, "robots.arm.package_paths", {"arm": loop(root / "arm_package")})


def _mesh(mesh: str, make: Callable[[Path], None] = lambda meshes: None) -> Build:
    def build(root: Path, data: dict[str, Any]) -> None:
        urdf = root / "robots" / "arm" / "urdf" / "arm.urdf"
        urdf.write_text(URDF.format(mesh=mesh), encoding="utf-8")
        make(root / "robots" / "arm" / "meshes")

    return build


def _source(value: str, make: Callable[[Path], None] = lambda root: None) -> Build:
    def build(root: Path, data: dict[str, Any]) -> None:
        make(root)
        set_key(data, "sources.state.parquet", value)

    return build


def _glob_with(extra: Callable[[Path], None]) -> Build:
    def build(root: Path, data: dict[str, Any]) -> None:
        extra(root / "data")
        set_key(data, "sources.state.parquet", "data/*.parquet")
        set_key(data, "output.segment", "{stem}")

    return build


def _control_name(data_dir: Path) -> None:
    (data_dir / "ep\n::error::x.parquet").write_bytes((data_dir / "episode_000.parquet").read_bytes())


def _sidecar_loop(root: Path, data: dict[str, Any]) -> None:
    data["edges"] = [{"file": loop(root / "calibration.yaml")}]


def _output(key: str, value: str, make: Callable[[Path], None] = lambda root: None) -> Build:
    def build(root: Path, data: dict[str, Any]) -> None:
        make(root)
        if key == "output.model":
            set_key(data, "output.layout", "split")
        set_key(data, key, value)

    return build


CASES = [
    Hostile("urdf_loop", _urdf_loop, "robots.arm.urdf", LOOP),
    Hostile("urdf_long_name", _urdf(f"robots/{LONG}.urdf"), "robots.arm.urdf", TOO_LONG),
    Hostile(
        "urdf_below_a_file", _urdf("data/episode_000.parquet/arm.urdf"), "robots.arm.urdf", "episode_000.parquet is a file, not a folder"
    ),
    Hostile("urdf_fifo", _urdf_fifo, "robots.arm.urdf", "is a FIFO, not a regular file"),
    Hostile("xacro_loop", _xacro_loop, "robots.arm.urdf.xacro", LOOP),
    Hostile("package_folder_loop", _package_loop, "robots.arm.package_paths.arm", LOOP),
    Hostile(
        "package_folder_long_name",
        lambda r, d: set_key(d, "robots.arm.package_paths", {"arm": LONG}),
        "robots.arm.package_paths.arm",
        TOO_LONG,
    ),
    Hostile("mesh_long_name", _mesh(f"{LONG}.stl"), "robots.arm.urdf", TOO_LONG),
    Hostile(
        "mesh_loop", _mesh("loop.stl", lambda meshes: None if loop(meshes / "loop.stl") else None), "robots.arm.package_paths", "loop.stl"
    ),
    Hostile(
        "source_loop",
        _source("data/loop.parquet", lambda r: None if loop(r / "data" / "loop.parquet") else None),
        "sources.state.parquet",
        LOOP,
        True,
    ),
    Hostile("source_long_name", _source(f"data/{LONG}.parquet"), "sources.state.parquet", TOO_LONG, True),
    Hostile("source_below_a_file", _source("data/episode_000.parquet/x.parquet"), "sources.state.parquet", "is a file, not a folder", True),
    Hostile(
        "source_fifo", _source("data/fifo.parquet", lambda r: os.mkfifo(r / "data" / "fifo.parquet")), "sources.state.parquet", "FIFO", True
    ),
    Hostile("glob_matches_a_loop", _glob_with(lambda d: None if loop(d / "loop.parquet") else None), "sources.state.parquet", LOOP, True),
    Hostile(
        "glob_folder_long_name",
        lambda r, d: set_key(d, "sources.state.parquet", f"{LONG}/*.parquet"),
        "sources.state.parquet",
        TOO_LONG,
        True,
    ),
    Hostile(
        "glob_matches_a_control_character",
        _glob_with(_control_name),
        "sources.state.parquet",
        "data/ep\\n::error::x.parquet' holds a control",
        True,
    ),
    Hostile(
        "segment_id_with_a_newline",
        lambda r, d: set_key(d, "output.segment", "ep\n::error::x"),
        "output.segment",
        "segment id 'ep\\n::error::x' holds a control character",
    ),
    Hostile("sidecar_loop", _sidecar_loop, "edges[0].file", LOOP),
    Hostile(
        "output_folder_loop", _output("output.path", "out/{segment}.rrd", lambda r: None if loop(r / "out") else None), "output.path", LOOP
    ),
    Hostile(
        "output_below_a_file",
        _output("output.path", "data/episode_000.parquet/{segment}.rrd"),
        "output.path",
        "episode_000.parquet is not a directory",
    ),
    Hostile("output_long_name", _output("output.path", f"out/{LONG}.rrd"), "output.path", "bytes, more than the 255"),
    Hostile("output_no_room_for_partial", _output("output.path", f"out/{'n' * 240}.rrd"), "output.path", "bytes, more than the 235"),
    Hostile(
        "output_is_a_folder",
        _output("output.path", "out/{segment}.rrd", lambda r: (r / "out" / "episode_000.rrd").mkdir(parents=True)),
        "output.path",
        "it exists and it is a folder",
    ),
    Hostile(
        "manifest_loop",
        _output("output.manifest", "out/m.json", lambda r: None if (r / "out").mkdir() or loop(r / "out" / "m.json") else None),
        "output.manifest",
        LOOP,
    ),
    Hostile("model_loop", _output("output.model", "model/m.rrd", lambda r: None if loop(r / "model") else None), "output.model", LOOP),
]


def _error_lines(err: str, config: Path) -> list[str]:
    assert "Traceback" not in err and "internal error" not in err, err
    lines = [line for line in err.splitlines() if line.startswith("error")]
    for line in lines:
        assert re.match(rf"^error: {re.escape(str(config))}:\d+:\d+: ", line), line
    return lines


def _outputs(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*") if p.suffix in (".rrd", ".json", ".rbl") or ".partial" in p.name)


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
@pytest.mark.parametrize("command", [["validate"], ["validate", "--no-data"], ["plan"], ["run"]], ids=" ".join)
def test_hostile_path_is_one_located_error(case: Hostile, command: list[str], tmp_path: Path, run_cli, monkeypatch) -> None:
    monkeypatch.delenv(ALLOW_ENV, raising=False)
    data = make_project(tmp_path)
    case.build(tmp_path, data)
    config = write_config(tmp_path, data)
    before = _outputs(tmp_path)

    result = run_cli(*command, str(config))

    if case.reads_data and "--no-data" in command:  # no data path is looked at: the config itself is fine
        assert result.code == 0, result.err
        return
    assert result.code == 1, f"exit {result.code}\n{result.out}\n{result.err}"
    lines = _error_lines(result.err, config)
    assert len(lines) == 1, result.err
    assert f": {case.key}: " in lines[0], lines[0]
    assert case.expect in lines[0], lines[0]
    assert _outputs(tmp_path) == before


def test_the_project_itself_runs(tmp_path: Path, run_cli) -> None:
    """The control: the hostile cases fail for their own defect only."""
    config = write_config(tmp_path, make_project(tmp_path))
    for command in (["validate"], ["validate", "--no-data"], ["plan"], ["run"]):
        result = run_cli(*command, str(config))
        assert result.code == 0, (command, result.err)
    assert (tmp_path / "out" / "episode_000.rrd").is_file()


def _denied(path: str) -> None:
    """Skip unless the OS refuses `path` even to root (a container's /proc does: the tests run as root)."""
    try:
        with open(path, "rb"):
            pass
    except PermissionError:
        return
    except OSError:
        pass
    pytest.skip(f"{path} is not refused here")


@pytest.mark.parametrize(
    ("key", "path", "expect"),
    [
        ("robots.arm.urdf", "/proc/1/root/robots/arm.urdf", "permission denied"),  # stat itself is refused
        ("robots.arm.urdf", "/proc/sys/vm/compact_memory", "Permission denied"),  # a write-only file: stat works, open does not
        ("sources.state.parquet", "/proc/1/root/data/episode.parquet", "permission denied"),
        ("sources.state.parquet", "/proc/sys/vm/compact_memory", "ermission denied"),
    ],
)
def test_permission_denied_is_located(key: str, path: str, expect: str, tmp_path: Path, run_cli, monkeypatch) -> None:
    """Root reads a chmod 000 file, so the denial comes from files the kernel refuses to everyone: /proc/1/root (not
    ours to enter) and a write-only sysctl, allowed by the environment as a declared root."""
    _denied(str(Path(path).parents[1]) if path.startswith("/proc/1/root") else path)
    monkeypatch.setenv(ALLOW_ENV, "/proc")
    data = make_project(tmp_path)
    set_key(data, key, path)
    config = write_config(tmp_path, data)
    for command in (["validate"], ["plan"]):
        result = run_cli(*command, str(config))
        assert result.code == 1, result.err
        lines = _error_lines(result.err, config)
        assert len(lines) == 1 and f": {key}: " in lines[0] and expect in lines[0], result.err


def test_chmod_000_files_as_root_or_not(tmp_path: Path, run_cli, monkeypatch) -> None:
    """A URDF and a source without read permission: refused with the cause when the OS refuses them (not root), read
    when it does not (root); never a crash either way."""
    data = make_project(tmp_path)
    (tmp_path / "robots" / "arm" / "urdf" / "arm.urdf").chmod(0)
    (tmp_path / "data" / "episode_000.parquet").chmod(0)
    config = write_config(tmp_path, data)
    result = run_cli("validate", str(config))
    _error_lines(result.err, config)
    assert result.code == (0 if os.geteuid() == 0 else 1), result.err


def test_a_config_learns_nothing_of_an_unfollowable_path_outside(tmp_path: Path, run_cli, monkeypatch) -> None:
    """A loop outside the config's roots is refused by the rule, as any path there, not described."""
    monkeypatch.delenv(ALLOW_ENV, raising=False)
    project, outside = tmp_path / "project", tmp_path / "outside"
    project.mkdir()
    outside.mkdir()
    data = make_project(project)
    set_key(data, "robots.arm.urdf", str(outside / loop(outside / "loop.urdf")))
    config = write_config(project, data)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "is outside the config's folder" in result.err and LOOP not in result.err


def test_a_manifest_naming_unfollowable_paths_is_not_trusted(tmp_path: Path, run_cli) -> None:
    """A manifest (it may come from a pull request) whose entries name a symlink loop, a name too long or a NUL: the
    entries match no output, the run writes its outputs again and the manifest lists what is really there."""
    import json

    config = write_config(tmp_path, make_project(tmp_path))
    assert run_cli("run", str(config)).code == 0
    manifest_path = tmp_path / "out" / "config.manifest.json"
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))
    loop(tmp_path / "out" / "loop.rrd")
    hostile = ["loop.rrd", f"{LONG}.rrd", "a\u0000b.rrd"]
    manifest["segments"] = [{**manifest["segments"][0], "segment": f"s{i}", "path": p} for i, p in enumerate(hostile)] + manifest[
        "segments"
    ]
    manifest["segments"][-1]["path"] = "loop.rrd"  # the real segment's entry points at the loop
    manifest["blueprint"]["path"] = f"{LONG}.rbl"
    manifest["files"] = {**manifest["files"], str(tmp_path / "out" / "loop.rrd"): [1, 2, "x"], f"/{LONG}": [1, 2, "x"]}
    manifest_path.write_text(json.dumps(manifest), encoding="utf-8")

    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    rewritten = json.loads(manifest_path.read_text(encoding="utf-8"))
    assert [s["path"] for s in rewritten["segments"]] == ["episode_000.rrd"]


MIDDLE = [
    case for case in CASES if case.name in ("urdf_loop", "mesh_long_name", "glob_matches_a_loop", "source_fifo", "output_folder_loop")
]


@pytest.mark.parametrize("case", MIDDLE, ids=[c.name for c in MIDDLE])
@pytest.mark.parametrize("fmt", ["text", "github", "json"])
@pytest.mark.parametrize("no_data", [False, True], ids=["data", "no-data"])
def test_validate_goes_on_past_a_hostile_config(case: Hostile, fmt: str, no_data: bool, tmp_path: Path, run_cli, monkeypatch) -> None:
    """`validate A B C` with B hostile: A is ok, B's error and C's own error are both reported, in every format."""
    monkeypatch.delenv(ALLOW_ENV, raising=False)
    configs = []
    for name in ("a", "b", "c"):
        root = tmp_path / name
        root.mkdir()
        data = make_project(root)
        if name == "b":
            case.build(root, data)
        if name == "c":
            set_key(data, "robots.arm.joints.map", {"j1": "no_such_joint"})
        configs.append(write_config(root, data))

    result = run_cli("validate", "--format", fmt, *(["--no-data"] if no_data else []), *map(str, configs))

    assert result.code == 1, result.err
    assert "Traceback" not in result.err and "internal error" not in result.err, result.err
    shown = result.out + result.err
    assert "no_such_joint" in shown, shown
    b_reported = case.expect in shown
    assert b_reported == (not (no_data and case.reads_data)), shown
    if fmt == "text":
        assert f"ok: {configs[0]}" in result.out
    if fmt == "json":
        import json

        files = {problem["file"] for problem in json.loads(result.out)}
        assert str(configs[0]) not in files and str(configs[2]) in files
        assert (str(configs[1]) in files) == b_reported
    if fmt == "github":
        assert all(line.startswith("::") for line in result.out.splitlines() if line.strip()), result.out
