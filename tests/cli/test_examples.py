"""`make demo` (python -m urdf_pipeline.examples DIR) prepares every config in configs/, or says which it cannot."""

from __future__ import annotations

import builtins
import shutil
from pathlib import Path

import pytest

from urdf_pipeline import examples

from ..conftest import CONFIGS


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
