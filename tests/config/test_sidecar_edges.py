"""`edges: - file: ...`: sidecar edge lists (YAML or JSON), validated like inline edges, errors at the sidecar's lines."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import yaml

from ..edge_helpers import write_config
from ..execute.test_fk_against_pinocchio import (
    assert_poses_match,
    check_robot,
    panda_joint_values,
    random_bimanual_parquet,
)
from ..rrd_frames import read_frames

ERROR_LINE = re.compile(r"^error: .+:\d+: ")


def bimanual_with_sidecars(directory: Path, name: str, parquet: str) -> Path:
    """bimanual_pandas.yaml with its left edge in a YAML sidecar and its right edge in a tab-indented JSON one."""
    data = yaml.safe_load((directory / "bimanual_pandas.yaml").read_text())
    left, right = data["edges"]
    left["translation"] = [1e-05, 0.3, 0.0]  # written 1e-05 by JSON tools; YAML 1.1 would read it as a string
    calib = directory / "calib" / name
    calib.mkdir(parents=True, exist_ok=True)
    wrist = {
        "parent": "left_panda_link7",
        "child": "left_wrist_cam",
        "fixed_chain": {"from": "left_panda_link7", "to": "left_panda_hand_tcp"},
    }
    (calib / "left.yaml").write_text("# left arm extrinsics\n" + yaml.safe_dump([wrist, left], sort_keys=False))
    (calib / "right.json").write_text(json.dumps([{**right, "translation": [1e-05, -0.3, 0.0]}], indent="\t"))
    data["edges"] = [{"file": f"calib/{name}/left.yaml"}, {"file": f"calib/{name}/right.json"}]
    data["sources"]["both_arms"]["parquet"] = parquet
    data["output"]["segment"] = name
    return write_config(directory, name, data)


def test_sidecar_edges_match_pinocchio(examples_dir: Path, run_cli) -> None:
    reference, left, right = random_bimanual_parquet(examples_dir, "sidecar_bimanual.parquet", frames=12, seeds=(41, 42))
    config = bimanual_with_sidecars(examples_dir, "sidecar_bimanual", "data/sidecar_bimanual.parquet")

    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))

    assert result.code == 0, result.err
    frames = read_frames(Path(result.out.strip()), "timestamp")
    times = sorted({t for by_time in frames.temporal.values() for t in by_time})
    for prefix, q, y, yaw in (("left_", left, 0.3, -90.0), ("right_", right, -0.3, 90.0)):
        world_from_base = np.eye(4)
        world_from_base[:3, :3] = pin.rpy.rpyToMatrix(0.0, 0.0, math.radians(yaw))
        world_from_base[:3, 3] = [1e-05, y, 0.0]
        values = [panda_joint_values(row) for row in q]
        check_robot(frames, times, reference, values, prefix, world_from_base, "world", [0, 11])
        if prefix == "left_":
            for frame in (0, 11):
                expected = world_from_base @ reference.link_poses(values[frame])["panda_hand_tcp"]
                assert_poses_match(frames.world_pose("left_wrist_cam", times[frame], "world"), expected, "left_wrist_cam")

    plan = run_cli("plan", str(config))
    assert "edge world -> right_panda_link0: " in plan.out and "(calib/sidecar_bimanual/right.json[0], line 2)" in plan.out


BROKEN_SIDECARS = {
    "schema": (
        "edges.yaml",
        "- parent: world\n  child: panda_link0\n  translation: [0.0, 0.0]\n  rpy: [0, 0, 0]\n",
        3,
        "[0].translation: [0.0, 0.0] is too short",
    ),
    "two_rotations": (
        "edges.yaml",
        "- parent: world\n  child: panda_link0\n  translation: [0, 0, 0.5]\n  rpy: [0, 0, 0]\n  rpy_deg: [0, 0, 0]\n",
        1,
        "[0]: edge gives 2 rotations (rpy, rpy_deg); keep exactly one",
    ),
    "yaml_syntax": ("edges.yaml", "- parent: world\n  child: [panda_link0\n", 3, "YAML syntax error"),
    "duplicate_key": (
        "edges.yaml",
        "- parent: world\n  child: panda_link0\n  child: panda_link1\n",
        3,
        "duplicate key 'child' (first at line 2)",
    ),
    "nested_file": ("edges.yaml", "- file: more.yaml\n", 1, "includes another edges file (more.yaml); a sidecar holds edges only"),
    "not_a_list": ("edges.yaml", "parent: world\nchild: panda_link0\n", 1, "wrong type: expected array, got dict"),
    "empty": ("edges.yaml", "", 1, "is empty; it must hold a list of edges"),
    "json_syntax": ("edges.json", '[\n  {"parent": "world",\n   "child": "panda_link0",,\n', 3, "JSON syntax error"),
    "json_schema": (
        "edges.json",
        '[\n\t{\n\t\t"parent": "world",\n\t\t"child": "panda_link0",\n\t\t"translation": [0, 0, "0.5"],\n\t\t"rpy": [0, 0, 0]\n\t}\n]\n',
        5,
        '[0].translation[2]: wrong type: expected number, got str "0.5"',
    ),
    "json_duplicate_key": ("edges.json", '[{"parent": "world",\n "parent": "x"}]\n', 2, "duplicate key 'parent'"),
    "nan": (
        "edges.yaml",
        "- parent: world\n  child: panda_link0\n  translation: [0, .nan, 0.5]\n  rpy: [0, 0, 0]\n",
        3,
        "[0].translation[1]: NaN is not a number this tool can use",
    ),
    "json_nan": (  # JSON's NaN and Infinity, which Python's json reads: the same rule as YAML's .nan and .inf
        "edges.json",
        '[\n  {"parent": "world", "child": "panda_link0",\n   "translation": [0, 0, Infinity],\n   "rpy": [NaN, 0, 0]}\n]\n',
        3,
        "[0].translation[2]: an infinity is not a number this tool can use",
    ),
}


@pytest.mark.parametrize("case", sorted(BROKEN_SIDECARS))
def test_sidecar_errors_point_at_the_sidecar_line(case: str, examples_dir: Path, run_cli) -> None:
    filename, text, line, message = BROKEN_SIDECARS[case]
    sidecar = examples_dir / "calib" / f"broken_{case}" / filename
    sidecar.parent.mkdir(parents=True, exist_ok=True)
    sidecar.write_text(text, encoding="utf-8")
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["edges"] = [{"file": f"calib/broken_{case}/{filename}"}]
    data["output"]["segment"] = f"sidecar_broken_{case}"
    config = write_config(examples_dir, f"sidecar_broken_{case}", data)

    for command in ("validate", "run"):
        result = run_cli(command, str(config))
        assert result.code == 1, result.err
        assert "Traceback" not in result.err
        errors = [e for e in result.err.splitlines() if e.startswith("error")]
        assert errors and all(ERROR_LINE.match(e) for e in errors), result.err
        assert f"error: {sidecar}:{line}:" in result.err, result.err  # FILE:LINE: or FILE:LINE:COL:
        assert message in result.err, result.err
    assert not (examples_dir / "out" / f"sidecar_broken_{case}.rrd").exists()


def test_frame_graph_errors_name_the_sidecar_edge(examples_dir: Path, run_cli) -> None:
    sidecar = examples_dir / "calib" / "two_parents.yaml"
    sidecar.parent.mkdir(parents=True, exist_ok=True)
    sidecar.write_text("- parent: table\n  child: panda_link0\n  translation: [0, 0, 0]\n  quaternion_xyzw: [0, 0, 0, 1]\n")
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["edges"].append({"file": "calib/two_parents.yaml"})
    data["output"]["segment"] = "sidecar_two_parents"
    config = write_config(examples_dir, "sidecar_two_parents", data)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert (
        f"error: {sidecar}:1:3: [0]: frame 'panda_link0' has two parents: 'world' (edges[0] at line " in result.err
        and "and 'table' (calib/two_parents.yaml[0] at line 1)" in result.err
    ), result.err


def test_sidecar_path_is_relative_to_the_config(examples_dir: Path, run_cli, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same relative file: entry works from any working directory; a missing one is named with its full path."""
    (examples_dir / "calib").mkdir(exist_ok=True)
    (examples_dir / "calib" / "base.yaml").write_text(
        yaml.safe_dump([{"parent": "world", "child": "panda_link0", "translation": [0, 0, 0.5], "quaternion_xyzw": [0, 0, 0, 1]}])
    )
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["edges"] = [{"file": "calib/base.yaml"}]
    config = write_config(examples_dir, "sidecar_relative", data)
    monkeypatch.chdir(tmp_path)
    assert run_cli("validate", str(config)).code == 0
    data["edges"] = [{"file": "calib/absent.yaml"}]
    missing = write_config(examples_dir, "sidecar_absent", data)
    result = run_cli("validate", str(missing))
    assert result.code == 1
    assert f"edges file not found: {(examples_dir / 'calib' / 'absent.yaml').resolve()}" in result.err
