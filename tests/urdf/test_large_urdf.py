"""A robot of 20,000 links is checked in linear time: the URDF's structure checks, its mimics, fixed chains and the frame
graph each walk every link once (they were cubic: minutes). Only results are asserted here; the times are measured by
hand. A tree deeper than Rerun's loader can walk (it recurses once per level and crashed `run` with a segfault) is
refused by `validate`, naming the stack the person running the tool can give it."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.compile.frame_graph import FrameEdge, tops
from urdf_pipeline.errors import HINTED, Where
from urdf_pipeline.examples import write_joint_parquet
from urdf_pipeline.urdf.fixed_chain import find_fixed_chain
from urdf_pipeline.urdf.model import UrdfParseError, parse_urdf_text
from urdf_pipeline.urdf.repair import RUST_STACK_ENV
from urdf_pipeline.urdf.xml_text import MAX_ELEMENTS as MAX_URDF_ELEMENTS
from urdf_pipeline.urdf.xml_text import MAX_URDF_BYTES

LINKS = 20_000
MIB = 1 << 20


def chain(links: int, mimics: bool = False, link: str = "l") -> str:
    """links l0 .. l{links-1} in a chain: j1 continuous, the others fixed (or each mimicking the joint above it)."""
    joints = []
    for i in range(1, links):
        kind = "continuous" if i == 1 or mimics else "fixed"
        mimic = f'<mimic joint="j{i - 1}"/>' if mimics and i > 1 else ""
        joints.append(
            f'<joint name="j{i}" type="{kind}"><parent link="{link}{i - 1}"/><child link="l{i}"/>'
            f'<origin xyz="0 0 0.01"/><axis xyz="0 0 1"/>{mimic}</joint>'
        )
    return "\n".join(['<robot name="chain">', *(f'<link name="l{i}"/>' for i in range(links)), *joints, "</robot>"])


def tree(links: int) -> str:
    """l0 with links - 1 children: j1 continuous, the others fixed."""
    joints = [
        f'<joint name="j{i}" type="{"continuous" if i == 1 else "fixed"}"><parent link="l0"/><child link="l{i}"/>'
        f'<origin xyz="{i * 0.001} 0 0"/><axis xyz="0 0 1"/></joint>'
        for i in range(1, links)
    ]
    return "\n".join(['<robot name="tree">', *(f'<link name="l{i}"/>' for i in range(links)), *joints, "</robot>"])


def write_config(directory: Path, urdf_text: str) -> Path:
    (directory / "robot.urdf").write_text(urdf_text, encoding="utf-8")
    write_joint_parquet(directory / "d.parquet", np.zeros((3, 1)))
    config = {
        "version": 1,
        "sources": {"s": {"parquet": "d.parquet", "column": "observation.state", "index": "frame_index", "names": ["a"]}},
        "robots": {"big": {"urdf": "robot.urdf", "joints": {"source": "s", "map": {"a": "j1"}}}},
        "output": {"path": "out/{segment}.rrd", "application_id": "big", "segment": "big"},
    }
    path = directory / "big.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


def test_a_20000_link_chain_validates_when_rerun_s_loader_has_the_stack_for_it(
    tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    config = write_config(tmp_path, chain(LINKS))
    monkeypatch.delenv(RUST_STACK_ENV, raising=False)
    refused = run_cli("validate", str(config))
    assert refused.code == 1 and "Traceback" not in refused.err
    assert (
        f"error: {config}:11:5: robots.big.urdf: robot.urdf is a tree 19,999 joints deep (link 'l19999' below root link 'l0'); "
        "Rerun's URDF loader walks the tree recursively, and with a 2,048 KiB thread stack it would crash `run` beyond about "
        "1,024 levels; the person running the tool can give it a larger stack: RUST_MIN_STACK=41943040 (bytes)"
    ) in refused.err

    monkeypatch.setenv(RUST_STACK_ENV, str(64 * MIB))
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err
    assert f"ok: {config}" in result.out


def test_a_20000_link_wide_tree_validates(tmp_path: Path, run_cli) -> None:
    config = write_config(tmp_path, tree(LINKS))
    result = run_cli("validate", str(config))
    assert result.code == 0, result.err


def test_a_chain_of_20000_mimics_is_read_and_ordered() -> None:
    model = parse_urdf_text(chain(LINKS, mimics=True), "chain.urdf")
    assert model.depth() == (LINKS - 1, f"l{LINKS - 1}")
    order = [joint.name for joint in model.mimic_order()]
    assert order == [f"j{i}" for i in range(2, LINKS)]  # each after the joint it mimics
    assert model.joint(f"j{LINKS - 1}") is model.joints[-1]


def test_a_mimic_cycle_of_20000_joints_is_reported_once() -> None:
    text = chain(LINKS, mimics=True).replace('<child link="l1"/>', '<child link="l1"/><mimic joint="j19999"/>', 1)
    with pytest.raises(UrdfParseError) as caught:
        parse_urdf_text(text, "chain.urdf")
    (message,) = caught.value.messages
    assert message.startswith("chain.urdf:20002: joints mimic each other in a cycle: j1 -> j19999 -> j19998 -> ")  # at j1


def test_20000_joints_naming_missing_links_are_each_reported_with_few_hints() -> None:
    text = chain(LINKS, link="L")  # every joint's parent is 'L...', a typo of 'l...'
    with pytest.raises(UrdfParseError) as caught:
        parse_urdf_text(text, "chain.urdf")
    messages = caught.value.messages
    assert len(messages) == LINKS - 1
    assert messages[0].startswith(
        "chain.urdf:20002: joint 'j1' names parent link 'L0', which the URDF does not define (did you mean 'l0'?)"
    )
    assert sum("did you mean" in message for message in messages) == HINTED  # each hint compares a name with 20,000 links


def test_a_fixed_chain_of_20000_joints_is_found() -> None:
    model = parse_urdf_text(chain(LINKS), "chain.urdf")
    joints = find_fixed_chain(model, "l1", f"l{LINKS - 1}")
    assert [joint.name for joint in joints] == [f"j{i}" for i in range(2, LINKS)]


def test_each_frame_s_walk_ends_at_its_top_or_its_cycle() -> None:
    where = Where(Path("c.yaml"), 1)
    edges = [FrameEdge(f"f{i - 1}", f"f{i}", "edge", where) for i in range(1, LINKS)]
    edges += [FrameEdge("c2", "c1", "edge", where), FrameEdge("c1", "c2", "edge", where), FrameEdge("c2", "d", "edge", where)]
    parent_of = {edge.child: edge for edge in edges}
    frames = sorted({edge.parent for edge in edges} | {edge.child for edge in edges})
    ends = tops(parent_of, frames)
    assert all(ends[f"f{i}"] == "f0" for i in range(LINKS))
    assert ends["d"] == ends["c1"] == ends["c2"] == ("c1", "c2")


@pytest.mark.skipif(sys.platform != "linux", reason="the stack Rust gives a thread is measured on Linux")
def test_run_of_a_chain_within_the_stack_it_is_given_writes_its_recording(tmp_path: Path) -> None:
    """In a child process: Rust reads RUST_MIN_STACK once, when Rerun starts its first thread."""
    config = write_config(tmp_path, chain(3_000))
    command = [sys.executable, "-m", "urdf_pipeline", "run", "-q", str(config)]
    environment = {**os.environ, RUST_STACK_ENV: str(8 * MIB)}  # 4,096 levels by the rule; a 3,000-link chain crashed at 2 MiB
    result = subprocess.run(command, capture_output=True, text=True, env=environment, timeout=600, check=False)
    assert result.returncode == 0, result.stderr
    assert (tmp_path / "out" / "big.rrd").is_file()


def test_a_urdf_beyond_16_mb_is_refused_before_it_is_parsed(tmp_path: Path, run_cli) -> None:
    """A 20 MB name took 3.6 s and 320 MB to validate, a 60 MB one 14 s and 690 MB: the file is read no further."""
    config = write_config(tmp_path, chain(2).replace('name="chain"', f'name="{"a" * (MAX_URDF_BYTES + 1)}"'))
    result = run_cli("validate", str(config))
    assert result.code == 1 and "Traceback" not in result.err
    assert f"robots.big.urdf: {tmp_path / 'robot.urdf'} is larger than 16 MB: no robot's URDF is so large" in result.err


def test_a_urdf_of_too_many_elements_is_refused(tmp_path: Path, run_cli) -> None:
    """500,000 links in 11 MB took 8 s and 400 MB to validate; the bound is 10 times a 20,000-link chain's links."""
    links = "\n".join(f'<link name="x{i}"/>' for i in range(MAX_URDF_ELEMENTS))
    config = write_config(tmp_path, chain(2).replace("</robot>", f"{links}\n</robot>"))
    result = run_cli("validate", str(config))
    assert result.code == 1 and "Traceback" not in result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    # chain(2) holds 8 elements on its first 4 lines: the 199,993rd link, on line 199,997, is the 200,001st element.
    assert len(errors) == 1 and "robot.urdf:199997: more than 200,000 elements (<link> crosses the bound)" in errors[0]
