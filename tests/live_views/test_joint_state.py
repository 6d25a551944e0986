"""The one JointState decoder of the live feeds: the definition a stream advertises is compared with JointState's,
never compiled, and each message is read by JointState's fixed CDR layout, its cost bounded by its bytes. Every
hostile definition and payload is built here."""

from __future__ import annotations

import struct
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from mcap.writer import Writer
from mcap_ros2._dynamic import serialize_dynamic

from urdf_pipeline.errors import UserError, Where, has_control_character
from urdf_pipeline.examples import JOINT_STATE_MSGDEF
from urdf_pipeline.live_views import McapFollowFeed
from urdf_pipeline.live_views.joint_state import MAX_NAME_ORDERS, MAX_ORDER_BYTES, JointStateDecoder, NameOrders
from urdf_pipeline.sources.joint_state_cdr import JOINT_STATE, MAX_NAME_BYTES, MAX_NAMES, definition_differs

WHERE = Where(Path("live.yaml"), 3, "sources.js.topic", 5)

# ROS 2's own text, as rosbag2 and foxglove_bridge send it: comments, blank lines, one section per type.
ROS_DEFINITION = """# This is a message that holds data to describe the state of a set of torque controlled joints.
#
#  * the position of the joint (rad or m),

std_msgs/Header header

string[] name
float64[] position  # rad or m
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
# Standard metadata for higher-level stamped data types.
builtin_interfaces/Time stamp

# Transform frame with which this data is associated.
string frame_id

================================================================================
MSG: builtin_interfaces/Time
# The seconds component, valid over all int32 values.
int32 sec
uint32   nanosec
"""


def decoder(text: str = JOINT_STATE_MSGDEF) -> JointStateDecoder:
    return JointStateDecoder("/joint_states", JOINT_STATE, "ros2msg", text, "cdr", WHERE)


def encoded(names: list[str], positions: list[float], sec: int = 3, nanosec: int = 9, effort: list[float] | None = None) -> bytes:
    """A JointState in CDR, by the MCAP project's own ROS 2 writer."""
    encode = serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE]
    message = {
        "header": {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": "base"},
        "name": names,
        "position": positions,
        "velocity": [],
        "effort": effort or [],
    }
    return bytes(encode(message))


def big_endian(names: list[str], positions: list[float], sec: int, nanosec: int) -> bytes:
    """The same message in big-endian CDR (CDR_BE), laid out by hand: each value aligned from byte 4."""
    out = bytearray(b"\x00\x00\x00\x00")

    def align(size: int) -> None:
        out.extend(b"\x00" * (-(len(out) - 4) % size))

    def string(text: str) -> None:
        align(4)
        data = text.encode() + b"\x00"
        out.extend(struct.pack(">I", len(data)) + data)

    align(4)
    out.extend(struct.pack(">iI", sec, nanosec))
    string("base")
    align(4)
    out.extend(struct.pack(">I", len(names)))
    for name in names:
        string(name)
    align(4)
    out.extend(struct.pack(">I", len(positions)))
    align(8)
    out.extend(struct.pack(f">{len(positions)}d", *positions))
    align(4)
    out.extend(struct.pack(">II", 0, 0))
    return bytes(out)


def test_messages_read_as_ros_writes_them() -> None:
    names, positions = ["shoulder", "elbow", "wrïst", ""], [0.5, -1.25, 3.0, 1e-300]
    header_ns, got_names, got = decoder()(encoded(names, positions, effort=[1.0, 2.0]))
    assert (header_ns, got_names) == (3_000_000_009, tuple(names))
    np.testing.assert_array_equal(got, positions)
    assert got.dtype == np.float64 and got.flags.writeable
    header_ns, got_names, got = decoder()(big_endian(names, positions, 7, 11))
    assert (header_ns, got_names) == (7_000_000_011, tuple(names))
    np.testing.assert_array_equal(got, positions)


def test_names_are_interned_per_order() -> None:
    decode = decoder()
    first = decode(encoded(["a", "b"], [1.0, 2.0]))[1]
    again = decode(encoded(["a", "b"], [3.0, 4.0]))[1]
    other = decode(encoded(["b", "a"], [3.0, 4.0]))[1]
    assert first is again and other == ("b", "a")


def test_name_orders_are_bounded_in_count_and_bytes() -> None:
    orders = NameOrders()
    first = orders.interned(tuple(["a"]))
    assert orders.interned(tuple(["a"])) is first
    for k in range(MAX_NAME_ORDERS):
        orders.interned((f"n{k}",))
    assert orders.interned(tuple(["a"])) is not first  # the table started again
    long_names = [f"{k:04d}" + "x" * (MAX_NAME_BYTES - 4) for k in range(MAX_NAMES)]
    for k in range(40):  # 40 distinct lists of about 1.2 MB each
        orders.interned(tuple(long_names[k:]))
        assert orders._bytes <= MAX_ORDER_BYTES


@pytest.mark.parametrize(
    "text",
    [
        ROS_DEFINITION,
        JOINT_STATE_MSGDEF.replace("std_msgs/Header header", "Header header"),
        JOINT_STATE_MSGDEF.replace("MSG: std_msgs/Header", "MSG: std_msgs/msg/Header").replace(
            "builtin_interfaces/Time", "builtin_interfaces/msg/Time"
        ),
        ROS_DEFINITION.replace("\n", "\r\n"),
    ],
)
def test_joint_states_definition_in_its_spellings_is_taken(text: str) -> None:
    assert definition_differs(text) is None
    decoder(text)


def _nested(depth: int) -> str:
    sections = [f"MSG: pkg/T{i}\npkg/T{i + 1} child\n" for i in range(depth)]
    return JOINT_STATE_MSGDEF.replace("float64[] effort", "float64[] effort\npkg/T0 bomb") + "".join("=" * 80 + "\n" + s for s in sections)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("", "its definition of sensor_msgs/JointState is not ROS 2's"),
        ("string data\n", "its definition of sensor_msgs/JointState is not ROS 2's"),
        (JOINT_STATE_MSGDEF.replace("float64[] effort", "float64[] effort\nfloat64[] extra"), "sensor_msgs/JointState is not ROS 2's"),
        (JOINT_STATE_MSGDEF.replace("string[] name", "string[<=3] name"), "the line 'string[<=3] name', which"),
        (JOINT_STATE_MSGDEF.replace("int32 sec", "int64 sec"), "builtin_interfaces/Time is not ROS 2's"),
        (JOINT_STATE_MSGDEF.replace("string frame_id", 'string frame_id "x"'), "which JointState's has not"),
        (JOINT_STATE_MSGDEF.replace("string frame_id", "string FRAME=1"), "which JointState's has not"),
        (JOINT_STATE_MSGDEF + "=" * 80 + "\nMSG: pkg/Loop\npkg/Loop self\n", "types JointState's has not"),  # recursive
        (JOINT_STATE_MSGDEF + "=" * 80 + "\nstring no_header\n", "does not start with 'MSG: TYPE'"),
        (JOINT_STATE_MSGDEF + "=" * 80 + "\nMSG: std_msgs/Header\nstring x\n", "defines std_msgs/Header twice"),
        (_nested(60), "is not ROS 2's"),  # deep nesting
        (JOINT_STATE_MSGDEF + "#" * 70_000, "is 70,"),  # huge: refused from its length
        (JOINT_STATE_MSGDEF + "\x1b[31m bad\u202e line\n", "the line '"),
    ],
)
def test_another_definition_under_joint_states_name_is_refused(text: str, says: str) -> None:
    with pytest.raises(UserError) as refused:
        decoder(text)
    assert refused.value.where == WHERE
    assert refused.value.message.startswith(f"topic '/joint_states' is named {JOINT_STATE}, but ")
    assert says in refused.value.message and not has_control_character(refused.value.message)
    assert len(refused.value.message) < 600


def test_a_huge_definition_costs_its_length_only() -> None:
    """A definition of a million fields and types, each section naming the next: compared line by line, refused."""
    fields = "".join(f"=== \nMSG: pkg/T{i}\nfloat64[] f{i}\n" for i in range(20_000))
    with pytest.raises(UserError, match="characters long"):
        decoder(JOINT_STATE_MSGDEF + fields)
    tracemalloc.start()
    try:
        with pytest.raises(UserError):
            decoder(JOINT_STATE_MSGDEF + fields[:60_000])
        assert tracemalloc.get_traced_memory()[1] < 8 * 1024 * 1024
    finally:
        tracemalloc.stop()


def _count_claim(count: int) -> bytes:
    """A 100-byte message whose name sequence says `count` names."""
    head = b"\x00\x01\x00\x00" + struct.pack("<iI", 1, 2) + struct.pack("<I", 1) + b"\x00\x00\x00\x00"
    return (head + struct.pack("<I", count)).ljust(100, b"a")


def _unreadable(payload: bytes, says: str) -> None:
    with pytest.raises(UserError) as refused:
        decoder()(payload)
    assert refused.value.where == WHERE
    assert refused.value.message.startswith(f"a message on '/joint_states' is not a readable {JOINT_STATE} (")
    assert says in refused.value.message, refused.value.message


def test_a_count_is_checked_against_the_bytes_before_anything_is_made() -> None:
    tracemalloc.start()
    try:
        _unreadable(_count_claim(2**31), "it names 2,147,483,648 joints (at most 4,096)")
        _unreadable(_count_claim(4000), "it says 4,000 joints but has 76 bytes left")
        positions = _count_claim(0)[:24] + struct.pack("<I", 2**29)  # no names, then 2^29 positions claimed
        _unreadable(positions.ljust(100, b"\x00"), "it names 536,870,912 positions")
        assert tracemalloc.get_traced_memory()[1] < 1024 * 1024
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize(
    ("payload", "says"),
    [
        (b"", "does not start with a plain CDR encapsulation header"),
        (b"\x00\x03\x00\x00" + bytes(40), "does not start with a plain CDR encapsulation header"),  # PL_CDR
        (encoded(["a"], [1.0])[:-9], "before its fields do"),
        (encoded(["a" * (MAX_NAME_BYTES + 1)], [1.0]), f"its joint name is {MAX_NAME_BYTES + 1} bytes long (at most {MAX_NAME_BYTES})"),
        (encoded(["a"], [1.0]).replace(b"a\x00", b"\xff\x00"), "its joint name is not UTF-8"),
        (encoded([f"j{k}" for k in range(MAX_NAMES + 1)], [0.0] * (MAX_NAMES + 1)), "it names 4,097 joints (at most 4,096)"),
    ],
)
def test_a_damaged_message_is_refused_naming_the_topic(payload: bytes, says: str) -> None:
    _unreadable(payload, says)


def test_names_and_positions_must_pair() -> None:
    with pytest.raises(UserError, match="has 1 positions but 2 names"):
        decoder()(encoded(["a", "b"], [1.0]))


def test_a_message_of_the_largest_size_costs_its_bytes() -> None:
    """4,096 names of 256 bytes (1 MB): read, and the memory it takes is a small multiple of its bytes."""
    names = [f"{k:04d}" + "x" * (MAX_NAME_BYTES - 4) for k in range(MAX_NAMES)]
    payload = encoded(names, [float(k) for k in range(MAX_NAMES)])
    tracemalloc.start()
    try:
        got = decoder()(payload)[1]
        assert tracemalloc.get_traced_memory()[1] < 4 * len(payload)
    finally:
        tracemalloc.stop()
    assert got == tuple(names)


def _followed(tmp_path: Path, definition: str, payload: bytes) -> UserError:
    """A finished MCAP file with one channel of `definition` under JointState's name and one message: what the
    follow feed says of it (the same decoder as the WebSocket feed's)."""
    path = tmp_path / "hostile.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema = writer.register_schema(JOINT_STATE, "ros2msg", definition.encode())
        channel = writer.register_channel("/joint_states", "cdr", schema)
        writer.add_message(channel, 1, payload, 1)
        writer.finish()
    with pytest.raises(UserError) as refused:
        for _ in McapFollowFeed(path, {"/joint_states": WHERE}).batches():
            pass
    return refused.value


def test_a_followed_file_goes_through_the_same_decoder(tmp_path: Path) -> None:
    recursive = JOINT_STATE_MSGDEF + "=" * 80 + "\nMSG: pkg/Loop\npkg/Loop self\n"
    assert (
        "is named sensor_msgs/msg/JointState, but its definition has types JointState's has not"
        in _followed(tmp_path, recursive, encoded(["a"], [1.0])).message
    )
    assert "it names 2,147,483,648 joints (at most 4,096)" in _followed(tmp_path, JOINT_STATE_MSGDEF, _count_claim(2**31)).message
