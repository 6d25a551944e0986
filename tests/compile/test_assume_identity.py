"""frames.assume_identity: the one way to leave a frame uncalibrated, with a warning that names it."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import yaml

from ..edge_helpers import write_config
from ..rrd_frames import read_frames

WARNING_LINE = re.compile(r"^warning: .+:\d+: ")


def table_config(directory: Path, name: str, assume: list[str] | None) -> Path:
    """demo.yaml plus a cup on a table that nothing calibrates."""
    data = yaml.safe_load((directory / "demo.yaml").read_text())
    data["edges"].append({"parent": "table", "child": "cup", "translation": [0.1, 0.2, 0.75], "rpy_deg": [0, 0, 30]})
    if assume is not None:
        data["frames"]["assume_identity"] = assume
    data["output"]["segment"] = name
    return write_config(directory, name, data)


def test_assumed_frame_gets_an_identity_edge_and_a_warning(examples_dir: Path, run_cli) -> None:
    config = table_config(examples_dir, "assume_table", ["table"])
    line, column = next(
        (i, text.index("- table") + 3) for i, text in enumerate(config.read_text().splitlines(), 1) if text.strip() == "- table"
    )
    expected = (
        f"warning: {config}:{line}:{column}: frames.assume_identity[0]: frame 'table' has no calibration; "
        "logging an identity edge from root 'world' (frames.assume_identity): its pose is assumed, not measured"
    )

    validated = run_cli("validate", str(config))
    assert validated.code == 0, validated.err
    assert expected in validated.err.splitlines()

    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert expected in result.err.splitlines()
    assert all(WARNING_LINE.match(text) for text in result.err.splitlines() if text.startswith("warning"))
    frames = read_frames(Path(result.out.strip()), "frame_index")
    assert frames.static_entities["table"] == "/calibration"
    parent, pose = frames.static["table"]
    assert parent == "world" and np.allclose(pose, np.eye(4))
    cup = frames.world_pose("cup", 0, "world")
    assert np.allclose(cup[:3, 3], [0.1, 0.2, 0.75], atol=1e-6)

    plan = run_cli("plan", str(config))
    assert "edge world -> table: identity ASSUMED, not calibrated (frames.assume_identity[0], line " in plan.out


def test_without_it_a_missing_edge_stays_an_error(examples_dir: Path, run_cli) -> None:
    config = table_config(examples_dir, "assume_nothing", None)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "no edge connects frame 'table' to root 'world'" in result.err
    assert "warning" not in result.err


def test_no_warning_when_the_config_is_refused_for_the_listed_frame(examples_dir: Path, run_cli) -> None:
    config = table_config(examples_dir, "assume_cup", ["cup"])
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "frame 'cup' already has parent 'table'" in result.err and "list 'table', the top of its tree, instead" in result.err
    assert "warning" not in result.err
