"""`make demo` (python -m urdf_pipeline.examples DIR) prepares every config in configs/, or says which it cannot."""

from __future__ import annotations

import builtins
import json
import shutil
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
    assert f"try: urdf-pipeline run {target / 'demo.yaml'}" in capsys.readouterr().err

    edited = (target / "demo.yaml").read_text() + "# mine\n"
    (target / "demo.yaml").write_text(edited)
    assert examples.main([str(target), "--frames", "30"]) == 0
    assert (target / "demo.yaml").read_text() == edited  # a second run keeps the user's edit, and says so
    assert f"{target / 'demo.yaml'}: kept as it is" in capsys.readouterr().err


def test_in_the_checkout_the_configs_are_their_own_source() -> None:
    assert examples.example_configs().resolve() == CONFIGS.resolve()
    assert examples.copy_configs(CONFIGS) == []
