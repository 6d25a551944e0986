"""MCAP sources: ROS 2 JointState messages whose names (and their order) come with every message."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
from mcap_ros2.writer import Writer

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q

T0_NS = 1_700_000_000_000_000_000
STEP_NS = 10_000_000


def write_joint_states(
    path: Path,
    messages: Sequence[tuple[Sequence[str], Sequence[float]]],
    stamps_ns: Sequence[int] | None = None,
    topic: str = "/joint_states",
    chunk_size: int = 4096,
) -> list[int]:
    """One sensor_msgs/msg/JointState per (names, positions); also a std_msgs/String topic. Returns the header stamps."""
    stamps = list(stamps_ns) if stamps_ns is not None else [T0_NS + i * STEP_NS for i in range(len(messages))]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        writer = Writer(stream, chunk_size=chunk_size)
        schema = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        chatter = writer.register_msgdef("std_msgs/msg/String", "string data\n")
        for i, ((names, positions), stamp) in enumerate(zip(messages, stamps, strict=True)):
            message = {
                "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}, "frame_id": ""},
                "name": list(names),
                "position": [float(v) for v in positions],
                "velocity": [],
                "effort": [],
            }
            log_time = T0_NS + 5_000_000 + i * STEP_NS  # recorded a little after the stamp
            writer.write_message(topic, schema, message, log_time=log_time, publish_time=log_time)
            writer.write_message("/chatter", chatter, {"data": "hello"}, log_time=log_time, publish_time=log_time)
        writer.finish()
    return stamps


def shuffled_messages(q: np.ndarray, seed: int, extra: dict[str, float] | None = None) -> list[tuple[list[str], list[float]]]:
    """Each message names the joints in its own random order (plus `extra` name: value pairs)."""
    rng = np.random.default_rng(seed)
    names = [*PANDA_JOINTS, *(extra or {})]
    messages = []
    for row in q:
        values = [*row, *(extra or {}).values()]
        order = rng.permutation(len(names))
        messages.append(([names[i] for i in order], [values[i] for i in order]))
    return messages


def test_shuffled_name_order_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=64, seed=21)
    messages = shuffled_messages(q, seed=22, extra={"panda_finger_joint2": 0.01})
    assert len({tuple(names) for names, _ in messages}) > 1, "the name order must change between messages"
    stamps = write_joint_states(examples_dir / "data" / "shuffled.mcap", messages, chunk_size=1500)
    # No names: they come from the first message (order irrelevant); the mimic finger's value is ignored.
    config = panda_config(
        examples_dir, "mcap_shuffled", {"mcap": "data/shuffled.mcap", "topic": "/joint_states"}, ignore=["panda_finger_joint2"]
    )
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "ros2_timestamp", stamps, q, [0, 1, 2, 33, 63])


def test_log_time_timeline_and_config_names(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=20, seed=23)
    write_joint_states(examples_dir / "data" / "unstamped.mcap", shuffled_messages(q, seed=24), stamps_ns=[0] * 20)
    source = {"mcap": "data/unstamped.mcap", "topic": "/joint_states", "names": list(reversed(PANDA_JOINTS))}

    refused = run_cli("run", str(panda_config(examples_dir, "mcap_unstamped", source)))
    assert refused.code == 1
    assert "messages on '/joint_states' have a zero header stamp (" in refused.err
    assert "timeline: log_time" in refused.err

    result = run_cli("run", str(panda_config(examples_dir, "mcap_log_time", {**source, "timeline": "log_time"})))
    assert result.code == 0, result.err
    log_times = [T0_NS + 5_000_000 + i * STEP_NS for i in range(20)]
    assert_panda_fk(examples_dir, Path(result.out.strip()), "message_log_time", log_times, q, [0, 19])
    frames_timelines = _fk_timelines(Path(result.out.strip()))
    assert frames_timelines == {"message_log_time"}, "only the chosen timeline is kept"


def _fk_timelines(recording: Path) -> set[str]:
    from rerun.chunk import RrdReader

    timelines: set[str] = set()
    for chunk in RrdReader(recording).stream().filter(content="/arm/joint_transforms", is_static=False).to_chunks():
        batch = chunk.to_record_batch()
        timelines |= {f.name for f in batch.schema if (f.metadata or {}).get(b"rerun:kind") == b"index"}
    return timelines


def test_validate_checks_topic_and_schema(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=3, seed=25)
    write_joint_states(examples_dir / "data" / "topics.mcap", shuffled_messages(q, seed=26))

    missing = run_cli("validate", str(panda_config(examples_dir, "mcap_no_topic", {"mcap": "data/topics.mcap", "topic": "/joint_state"})))
    assert missing.code == 1
    assert "topic '/joint_state' not in topics.mcap; its sensor_msgs/msg/JointState topics: /joint_states" in missing.err

    wrong = run_cli("validate", str(panda_config(examples_dir, "mcap_wrong_schema", {"mcap": "data/topics.mcap", "topic": "/chatter"})))
    assert wrong.code == 1
    assert "topic '/chatter' carries std_msgs/msg/String (cdr), not ROS 2 sensor_msgs/msg/JointState (cdr)" in wrong.err

    (examples_dir / "data" / "not.mcap").write_text("not an mcap file")
    broken = run_cli("validate", str(panda_config(examples_dir, "mcap_broken", {"mcap": "data/not.mcap", "topic": "/joint_states"})))
    assert broken.code == 1 and "data/not.mcap, byte 0: not an MCAP file" in broken.err and "Traceback" not in broken.err


def test_config_names_must_cover_the_joints_mapped(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=3, seed=27)
    write_joint_states(examples_dir / "data" / "first_names.mcap", shuffled_messages(q, seed=28))
    source = {"mcap": "data/first_names.mcap", "topic": "/joint_states", "names": PANDA_JOINTS[:7]}
    result = run_cli("validate", str(panda_config(examples_dir, "mcap_short_names", source)))
    assert result.code == 1
    assert "'panda_finger_joint1' is not a name of source 'state'" in result.err


def test_a_message_lacking_a_mapped_name_is_refused(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=10, seed=29)
    messages = shuffled_messages(q, seed=30)
    for row in (3, 4, 7):  # these messages lose panda_joint4
        names, values = messages[row]
        keep = [i for i, name in enumerate(names) if name != "panda_joint4"]
        messages[row] = ([names[i] for i in keep], [values[i] for i in keep])
    write_joint_states(examples_dir / "data" / "lacking.mcap", messages)
    config = panda_config(examples_dir, "mcap_lacking", {"mcap": "data/lacking.mcap", "topic": "/joint_states", "names": PANDA_JOINTS})
    assert run_cli("validate", str(config)).code == 0, "validate reads no values"
    result = run_cli("run", str(config))
    assert result.code == 1
    assert "source 'state' rows lack names that robot 'arm' maps: 'panda_joint4' from 3 of 10 rows" in result.err
    assert not (examples_dir / "out" / "sources" / "mcap_lacking.rrd").exists()


def test_an_ignored_name_may_be_absent_from_some_messages(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=10, seed=31)
    messages = shuffled_messages(q, seed=32, extra={"head_pan": 0.5})
    messages[5] = shuffled_messages(q[5:6], seed=33)[0]  # no head_pan in this one
    stamps = write_joint_states(examples_dir / "data" / "sometimes.mcap", messages)
    source = {"mcap": "data/sometimes.mcap", "topic": "/joint_states", "names": [*PANDA_JOINTS, "head_pan"]}
    result = run_cli("run", str(panda_config(examples_dir, "mcap_sometimes", source, ignore=["head_pan"])))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "ros2_timestamp", stamps, q, [4, 5, 6])


def test_an_unknown_name_in_the_data_is_refused(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=6, seed=34)
    messages = shuffled_messages(q, seed=35)
    messages[2] = shuffled_messages(q[2:3], seed=36, extra={"mystery_joint": 1.0})[0]
    write_joint_states(examples_dir / "data" / "unknown.mcap", messages)
    result = run_cli("run", str(panda_config(examples_dir, "mcap_unknown", {"mcap": "data/unknown.mcap", "topic": "/joint_states"})))
    assert result.code == 1
    assert "source 'state' has rows naming 'mystery_joint', not among its names (1 of 6 rows in one batch)" in result.err


def test_value_count_differing_from_name_count_is_refused(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=5, seed=37)
    messages = [(list(PANDA_JOINTS), [*row, 0.0, 0.0]) for row in q]  # 10 positions, 8 names
    write_joint_states(examples_dir / "data" / "uneven.mcap", messages)
    result = run_cli("run", str(panda_config(examples_dir, "mcap_uneven", {"mcap": "data/uneven.mcap", "topic": "/joint_states"})))
    assert result.code == 1
    assert "source 'state' has rows of 10 values but 8 names (5 of 5 rows in one batch)" in result.err


def test_a_name_given_twice_in_one_message_is_refused(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=4, seed=38)
    messages = [(list(PANDA_JOINTS), list(row)) for row in q]
    messages[1] = ([*PANDA_JOINTS[:7], "panda_joint1"], list(q[1]))
    write_joint_states(examples_dir / "data" / "twice.mcap", messages)
    source = {"mcap": "data/twice.mcap", "topic": "/joint_states", "names": PANDA_JOINTS}
    result = run_cli("run", str(panda_config(examples_dir, "mcap_twice", source)))
    assert result.code == 1
    assert "source 'state' names 'panda_joint1' 2 times in one row" in result.err
