"""xacro's time bound is a budget of the config, not of each robot, and the same expansion is made once: ten robots
naming one slow xacro cannot take ten times the bound, an expansion the budget cannot pay for is refused naming the
budget, and a file edited since its expansion is expanded again."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf import xacro_guard

XACRO_NS = 'xmlns:xacro="http://www.ros.org/wiki/xacro"'
JOINT = (
    '<joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 0 1"/>'
    '<limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
)


def write_xacro(path: Path, body: str = "") -> None:
    """A one-joint robot (links base and l1, joint j1) whose xacro also holds `body`; `side` is its one argument."""
    path.write_text(
        f'<robot name="r" {XACRO_NS}><xacro:arg name="side" default="l"/>{body}<link name="base"/><link name="l1"/>{JOINT}</robot>',
        encoding="utf-8",
    )


def write_config(directory: Path, robots: dict[str, Any]) -> Path:
    """A config of several robots, each `KEY: urdf value`, each hung from world and driven by its own value."""
    write_joint_parquet(directory / "d.parquet", np.zeros((3, len(robots))))
    config = {
        "version": 1,
        "sources": {"s": {"parquet": "d.parquet", "column": "observation.state", "index": "frame_index", "names": list(robots)}},
        "robots": {
            key: {
                "urdf": urdf,
                "frame_prefix": f"{key}_",
                "joints": {"source": "s", "map": {key: "j1"}, **({"ignore": [k for k in robots if k != key]} if len(robots) > 1 else {})},
            }
            for key, urdf in robots.items()
        },
        "frames": {"root": "world"},
        "edges": [
            {"parent": "world", "child": f"{key}_base", "translation": [0.0, 0.0, 0.0], "quaternion_xyzw": [0.0, 0.0, 0.0, 1.0]}
            for key in robots
        ],
        "output": {"path": "out/{segment}.rrd", "application_id": "budget", "segment": "budget"},
    }
    path = directory / "robots.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture
def expansions(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The xacro files expanded in a child process from here on (cache hits are not expansions)."""
    made: list[str] = []
    run = xacro_guard._run

    def counted(command: list[str], payload: dict[str, Any], *rest: Any) -> Any:
        made.append(Path(payload["file"]).name)
        return run(command, payload, *rest)

    monkeypatch.setattr(xacro_guard, "_run", counted)
    return made


def test_robots_naming_the_same_xacro_with_the_same_args_expand_it_once(tmp_path: Path, run_cli, expansions: list[str]) -> None:
    write_xacro(tmp_path / "arm.urdf.xacro", '<xacro:property name="pi" value="3"/>')  # xacro warns: redefining pi
    same = {"xacro": "arm.urdf.xacro", "args": {"side": "l"}}
    config = write_config(tmp_path, {"a": same, "b": same, "c": same, "d": {"xacro": "arm.urdf.xacro", "args": {"side": "r"}}})

    result = run_cli("validate", str(config))
    assert result.code == 0, result.err
    assert expansions == ["arm.urdf.xacro", "arm.urdf.xacro"]  # side:=l once for a, b and c; side:=r for d
    assert result.err.count("redefining global symbol: pi") == 2  # xacro's warnings: once per expansion the config makes

    again = run_cli("validate", str(config))  # another config (or command) in the same process: nothing expanded again
    assert again.code == 0, again.err
    assert len(expansions) == 2
    assert again.err.count("redefining global symbol: pi") == 2  # its warnings are still shown for this config


def test_an_included_file_edited_since_the_expansion_is_expanded_again(tmp_path: Path, run_cli, expansions: list[str]) -> None:
    (tmp_path / "parts.xacro").write_text(f'<robot {XACRO_NS}><link name="extra"/></robot>', encoding="utf-8")
    write_xacro(tmp_path / "arm.urdf.xacro", '<xacro:include filename="parts.xacro"/>')
    config = write_config(tmp_path, {"a": {"xacro": "arm.urdf.xacro"}, "b": {"xacro": "arm.urdf.xacro"}})
    assert run_cli("validate", str(config)).code == 1  # link 'extra' has no joint: two root links
    assert expansions == ["arm.urdf.xacro"]

    (tmp_path / "parts.xacro").write_text(f'<robot {XACRO_NS}><gazebo reference="l1"/></robot>', encoding="utf-8")
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err  # the edit is seen: the file was expanded again, once for both robots
    assert expansions == ["arm.urdf.xacro", "arm.urdf.xacro"]

    write_xacro(tmp_path / "arm.urdf.xacro", '<xacro:include filename="parts.xacro"/><link name="extra"/>')
    assert run_cli("validate", str(config)).code == 1  # the xacro file itself edited: expanded again
    assert len(expansions) == 3


def test_a_budget_used_up_by_the_first_robots_refuses_the_later_ones(
    tmp_path: Path, run_cli, expansions: list[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_XACRO_TIMEOUT", "2")
    write_xacro(tmp_path / "spin.urdf.xacro", '<link name="${python.sum(python.range(10**15))}"/>')  # never ends
    write_xacro(tmp_path / "quick_b.urdf.xacro")
    write_xacro(tmp_path / "quick_c.urdf.xacro")
    robots = {"a": {"xacro": "spin.urdf.xacro"}, "b": {"xacro": "quick_b.urdf.xacro"}, "c": {"xacro": "quick_c.urdf.xacro"}}
    config = write_config(tmp_path, robots)

    result = run_cli("validate", str(config))
    assert result.code == 1 and "Traceback" not in result.err, result.err
    assert expansions == ["spin.urdf.xacro"]  # b and c are not started: the budget is spent
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert all(line.startswith(f"error: {config}:") for line in errors), result.err
    assert "robots.a.urdf: xacro expansion of spin.urdf.xacro did not end within 2 s and was stopped" in result.err
    for key in ("b", "c"):
        assert (
            f"robots.{key}.urdf: xacro expansion of quick_{key}.urdf.xacro was not started: this config's xacro time budget of 2 s "
            "was used up by the expansions before it (spin.urdf.xacro)"
        ) in result.err
    assert "URDF_PIPELINE_XACRO_TIMEOUT" in result.err

    fresh = run_cli("validate", str(write_config(tmp_path, {"b": robots["b"], "c": robots["c"]})))
    assert fresh.code == 0, fresh.err  # another config has a budget of its own
