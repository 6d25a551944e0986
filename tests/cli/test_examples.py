"""`make demo` (python -m urdf_pipeline.examples DIR) prepares every config in configs/, or says which it cannot."""

from __future__ import annotations

import builtins
import fnmatch
import json
import os
import shlex
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from urdf_pipeline import examples

from ..conftest import CONFIGS, REPO


def test_every_shipped_config_validates_after_the_examples_are_generated(examples_dir: Path, run_cli) -> None:
    configs = sorted(CONFIGS.glob("*.yaml"))
    assert len(configs) >= 7
    failed = {c.name: r.err for c in configs if (r := run_cli("validate", str(examples_dir / c.name))).code != 0}
    assert not failed


def test_without_the_optional_packages_the_examples_name_the_configs_they_cannot_prepare(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_import = builtins.__import__

    def without_extras(name: str, *args, **kwargs):  # as in a `make demo` venv: only the [demo] extra installed
        if name.split(".")[0] in ("rtbdata", "mcap_ros2"):
            raise ImportError(name)
        return real_import(name, *args, **kwargs)

    monkeypatch.setattr(builtins, "__import__", without_extras)
    for config in CONFIGS.glob("*.yaml"):
        shutil.copy(config, tmp_path / config.name)
    missing = examples.prepare(tmp_path, frames=30)
    assert missing == [
        "aloha_bimanual.yaml: not prepared, robots/rtbdata (the ViperX xacro) needs pip install rtb-data",
        "ur5_ros2_bag.yaml: not prepared, data/ur5_joint_states.mcap needs pip install mcap-ros2-support",
    ]
    for config in examples.MISSING_EXTRAS:  # each says so in its header comment too
        assert f"pip install {examples.MISSING_EXTRAS[config][1]}" in (CONFIGS / config).read_text().split("version: 1")[0]


def test_help_prints_help_and_creates_no_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as done:
        examples.main(["--help"])
    assert done.value.code == 0 and "usage: python -m urdf_pipeline.examples" in capsys.readouterr().out
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(SystemExit) as done:
        examples.main(["--frames", "0", "x"])
    assert done.value.code == 2 and list(tmp_path.iterdir()) == []


def test_the_configs_are_written_where_asked_with_a_schema_line_that_resolves_there(tmp_path: Path, capsys) -> None:
    """As a wheel's user runs it: DIR gets the configs, their inputs, and a schema line that is no venv path."""
    target = tmp_path / "robot_setup"
    assert examples.main([str(target), "--frames", "30"]) == 0
    assert sorted(p.name for p in target.glob("*.yaml")) == sorted(p.name for p in CONFIGS.glob("*.yaml"))
    first = (target / "demo.yaml").read_text().splitlines()[0]
    url = json.loads((REPO / "schemas" / "urdf-pipeline.schema.json").read_text())["$id"]
    assert first == f"# yaml-language-server: $schema={url}"  # no schemas/ above tmp_path
    assert (target / "demo.yaml").read_text().splitlines()[1:] == (CONFIGS / "demo.yaml").read_text().splitlines()[1:]
    assert f"try: {examples.cli_command()} run {target / 'demo.yaml'}" in capsys.readouterr().err

    edited = (target / "demo.yaml").read_text() + "# mine\n"
    (target / "demo.yaml").write_text(edited)
    assert examples.main([str(target), "--frames", "30"]) == 0
    assert (target / "demo.yaml").read_text() == edited  # a second run keeps the user's edit, and says so
    assert f"{target / 'demo.yaml'}: kept as it is" in capsys.readouterr().err


def test_in_the_checkout_the_configs_are_their_own_source() -> None:
    assert examples.example_configs().resolve() == CONFIGS.resolve()
    assert examples.copy_configs(CONFIGS) == []


def _tracked_example_configs() -> set[str] | None:
    """What a wheel built from a clean checkout carries as urdf_pipeline/example_configs: the files git tracks in the
    folder pyproject maps to that package, matching its package-data patterns (top level only, as setuptools globs)."""
    setuptools = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    folder = setuptools["package-dir"]["urdf_pipeline.example_configs"]
    patterns = setuptools["package-data"]["urdf_pipeline.example_configs"]
    try:
        listed = subprocess.run(["git", "-C", str(REPO), "ls-files", "--", folder], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return None
    names = [line.removeprefix(f"{folder}/") for line in listed.splitlines()]
    return {name for name in names if "/" not in name and any(fnmatch.fnmatch(name, pattern) for pattern in patterns)}


def test_the_shipped_list_is_what_the_wheel_carries() -> None:
    tracked = _tracked_example_configs()
    if tracked is None:
        pytest.skip("not a git checkout")
    assert tracked == set(examples.EXAMPLE_CONFIGS)


def test_only_the_shipped_configs_are_written_not_what_a_user_added_to_the_checkout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An editable install reads the checkout's configs/, where a user keeps configs of their own and runs write out/."""
    checkout = tmp_path / "configs"
    (checkout / "out").mkdir(parents=True)
    for name in examples.EXAMPLE_CONFIGS:
        shutil.copy(CONFIGS / name, checkout / name)
    (checkout / "my_robot.yaml").write_text("version: 1\n")
    (checkout / "out" / "demo.manifest.json").write_text("{}")
    (checkout / "out" / "stray.yaml").write_text("version: 1\n")
    monkeypatch.setattr(examples, "example_configs", lambda: checkout)
    target = tmp_path / "robot_setup"
    assert examples.copy_configs(target) == []
    assert sorted(p.relative_to(target).as_posix() for p in target.rglob("*")) == sorted(examples.EXAMPLE_CONFIGS)

    (checkout / "ur5_ros2_bag.yaml").unlink()  # deleted by its user: the others are written, and it is named
    again = tmp_path / "again"
    said = examples.copy_configs(again)
    assert said == [f"{checkout / 'ur5_ros2_bag.yaml'}: missing from the installed examples; not written"]
    assert sorted(p.name for p in again.iterdir()) == sorted(set(examples.EXAMPLE_CONFIGS) - {"ur5_ros2_bag.yaml"})


def _without_the_venv_on_path() -> dict[str, str]:
    """The environment of a shell where the venv is not activated (as `make demo` runs)."""
    bin_dir = str(Path(sys.executable).parent)
    path = os.pathsep.join(p for p in os.environ.get("PATH", "").split(os.pathsep) if p and os.path.abspath(p) != bin_dir)
    return {**os.environ, "PATH": path}


def test_from_the_editable_install_the_printed_command_runs_as_printed(tmp_path: Path) -> None:
    """`python -m urdf_pipeline.examples DIR` as make demo runs it (the editable install, no venv activated): it writes
    exactly the wheel's configs, and its last line is a command that works as printed."""
    env = _without_the_venv_on_path()
    done = subprocess.run(
        [sys.executable, "-m", "urdf_pipeline.examples", "robot_setup", "--frames", "30"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr
    written = {p.name for p in (tmp_path / "robot_setup").glob("*.yaml")}
    assert written == set(examples.EXAMPLE_CONFIGS)
    tracked = _tracked_example_configs()
    assert tracked is None or written == tracked
    last = done.stderr.splitlines()[-1]
    assert last.startswith("urdf_pipeline.examples: ready; try: ") and last.endswith(" run robot_setup/demo.yaml")
    command = shlex.split(last.removeprefix("urdf_pipeline.examples: ready; try: "))
    assert command[0] != "urdf-pipeline", "not on this PATH: the command names where it is"
    ran = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True)
    assert ran.returncode == 0, ran.stderr
    assert ran.stdout.strip().endswith("episode_000.rrd")


def test_the_command_is_the_script_on_path_or_beside_the_interpreter_or_python_m(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    venv_bin = tmp_path / "venv" / "bin"
    venv_bin.mkdir(parents=True)
    (venv_bin / "python").touch()
    monkeypatch.setattr(sys, "executable", str(venv_bin / "python"))
    monkeypatch.chdir(tmp_path)
    assert examples.cli_command() == "venv/bin/python -m urdf_pipeline"  # no script there: python -m works (__main__.py)
    script = venv_bin / "urdf-pipeline"
    script.write_text("#!/bin/sh\n")
    script.chmod(0o755)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert examples.cli_command() == "venv/bin/urdf-pipeline"
    monkeypatch.setenv("PATH", str(venv_bin))
    assert examples.cli_command() == "urdf-pipeline"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.setenv("PATH", "/nonexistent")
    assert examples.cli_command() == str(script)


def test_python_m_urdf_pipeline_is_the_cli() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "urdf_pipeline", "--version"], capture_output=True, text=True, env=_without_the_venv_on_path()
    )
    assert done.returncode == 0 and done.stdout.startswith("urdf-pipeline ")


def test_make_demo_ends_with_a_command_that_opens_the_recording_it_wrote(examples_dir: Path) -> None:
    """`make demo`'s last line, typed as printed with no venv activated: the venv's own viewer, on the demo's output."""
    from urdf_pipeline.compile import compile_config

    makefile = (REPO / "Makefile").read_text()
    recipe = makefile.split("\ndemo:", 1)[1].split("\n\n", 1)[0].splitlines()[1:]
    assert recipe[-1].strip() == '@echo "open it: $(BIN)/rerun configs/out/episode_000.rrd"'
    assert "BIN := $(VENV)/bin" in makefile and "VENV := .venv" in makefile
    assert (Path(sys.executable).parent / "rerun").is_file(), "rerun-sdk installs the viewer's script beside the interpreter"
    written = compile_config(examples_dir / "demo.yaml").segments[0].output
    assert written.relative_to(examples_dir).as_posix() == "out/episode_000.rrd"


def test_a_lerobot_dataset_of_more_than_1000_episodes_is_written_in_chunk_folders_rerun_reads(tmp_path: Path) -> None:
    """LeRobot v2.1 puts episode N in data/chunk-{N // chunks_size}: Rerun's reader refuses episode 1000 in chunk-000
    ("Invalid chunk index: 1"), and the benchmark of many episodes (benchmarks/bench_many_episodes.py) writes 10,000."""
    import numpy as np
    from rerun.experimental import LeRobotReader

    examples.write_lerobot_dataset(tmp_path, [np.zeros((1, 2))] * 1001, ["a", "b"])
    assert (tmp_path / "data" / "chunk-001" / "episode_001000.parquet").is_file()
    assert not (tmp_path / "data" / "chunk-000" / "episode_001000.parquet").exists()
    assert json.loads((tmp_path / "meta" / "info.json").read_text())["total_chunks"] == 2
    assert LeRobotReader(tmp_path).episodes()[-1] == 1000
