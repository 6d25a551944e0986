"""The output appears atomically; a directory in its way is a user error and leaves nothing behind."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples


def test_a_directory_at_the_output_path_is_a_user_error(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["output"]["path"] = str(tmp_path / "taken.rrd")
    (tmp_path / "taken.rrd").mkdir()
    data["robots"]["arm"]["urdf"] = str(examples_dir / data["robots"]["arm"]["urdf"])
    data["robots"]["arm"]["package_paths"] = {"example-robot-data": str(examples_dir / "robots" / "share" / "example-robot-data")}
    data["sources"]["arm_state"]["parquet"] = str(examples_dir / "data" / "episode_000.parquet")
    config = tmp_path / "c.yaml"
    config.write_text(yaml.safe_dump(data))
    result = run_cli("run", str(config))
    assert result.code == 1 and "cannot write" in result.err and "Traceback" not in result.err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.yaml", "taken.rrd"]
