"""ROS 2 bags that carry their own robot and frames, written with the MCAP ROS 2 writer (mcap-ros2-support): a
robot description on /robot_description, static mounts on /tf_static, a moving base on /tf, joint states. And the
same bag with a decompression bomb in it (`write_bomb_bag`): a chunk of a few KB that inflates to a GiB of zeros."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator, Sequence
from pathlib import Path

import numpy as np
import zstandard
from lz4 import frame as lz4_frame
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Chunk, ChunkIndex, DataEnd, Footer, Header, Message, MessageIndex, Statistics
from mcap_ros2.writer import Writer

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

MCAP_MAGIC = b"\x89MCAP0\r\n"
HEAD_AND_FIELDS = struct.Struct("<BQHIQQ")  # a Message record: opcode, length, channel, sequence, log and publish time
T0_NS = 1_700_000_000_000_000_000
STEP_NS = 10_000_000

TF_MESSAGE_MSGDEF = """geometry_msgs/TransformStamped[] transforms
================================================================================
MSG: geometry_msgs/TransformStamped
std_msgs/Header header
string child_frame_id
Transform transform
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
================================================================================
MSG: geometry_msgs/Transform
Vector3 translation
Quaternion rotation
================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
================================================================================
MSG: geometry_msgs/Quaternion
float64 x
float64 y
float64 z
float64 w
"""

# (parent, child, translation, quaternion_xyzw)
Transform = tuple[str, str, Sequence[float], Sequence[float]]


def _stamp(ns: int) -> dict[str, int]:
    return {"sec": ns // 10**9, "nanosec": ns % 10**9}


def _tf_message(stamp_ns: int, transforms: Sequence[Transform]) -> dict[str, object]:
    return {
        "transforms": [
            {
                "header": {"stamp": _stamp(stamp_ns), "frame_id": parent},
                "child_frame_id": child,
                "transform": {
                    "translation": dict(zip("xyz", map(float, translation), strict=True)),
                    "rotation": dict(zip("xyzw", map(float, quaternion), strict=True)),
                },
            }
            for parent, child, translation, quaternion in transforms
        ]
    }


def write_robot_bag(
    path: Path,
    descriptions: Sequence[str],
    static: Sequence[Sequence[Transform]],
    joint_names: Sequence[str] = (),
    joint_values: np.ndarray | None = None,
    moving: Sequence[Sequence[Transform]] = (),
    tf_stamps_ns: Sequence[int] | None = None,
) -> list[int]:
    """`descriptions` in order on /robot_description (the last is the robot), each list of `static` one /tf_static
    message, `joint_values` [N, K] one JointState per row, `moving` one /tf message per row (stamped as the row,
    or `tf_stamps_ns`). Returns the stamps."""
    rows = len(joint_values) if joint_values is not None else len(moving)
    stamps = [T0_NS + i * STEP_NS for i in range(rows)]
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        writer = Writer(stream)
        text = writer.register_msgdef("std_msgs/msg/String", "string data\n")
        tf = writer.register_msgdef("tf2_msgs/msg/TFMessage", TF_MESSAGE_MSGDEF)
        joint_state = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        for description in descriptions:
            writer.write_message("/robot_description", text, {"data": description}, log_time=T0_NS, publish_time=T0_NS)
        for transforms in static:
            writer.write_message("/tf_static", tf, _tf_message(T0_NS, transforms), log_time=T0_NS, publish_time=T0_NS)
        for row, stamp in enumerate(stamps):
            log_time = stamp + 2_000_000
            if joint_values is not None:
                message = {
                    "header": {"stamp": _stamp(stamp), "frame_id": ""},
                    "name": list(joint_names),
                    "position": [float(v) for v in joint_values[row]],
                    "velocity": [],
                    "effort": [],
                }
                writer.write_message("/joint_states", joint_state, message, log_time=log_time, publish_time=log_time)
            if row < len(moving):
                tf_stamp = tf_stamps_ns[row] if tf_stamps_ns is not None else stamp
                writer.write_message("/tf", tf, _tf_message(tf_stamp, moving[row]), log_time=log_time, publish_time=log_time)
        writer.finish()
    return stamps


def packed(compression: str, pieces: Iterator[bytes], size: int) -> bytes:
    """`pieces` compressed as one zstd or lz4 frame (or kept), a piece at a time: a GiB of zeros never sits in memory."""
    if compression == "zstd":
        packer = zstandard.ZstdCompressor().compressobj(size=size)
        return b"".join(packer.compress(piece) for piece in pieces) + packer.flush()
    if compression == "lz4":
        frame = lz4_frame.LZ4FrameCompressor()
        return frame.begin() + b"".join(frame.compress(piece) for piece in pieces) + frame.flush()
    return b"".join(pieces)


def _zero_message(channel_id: int, log_time: int, size: int) -> Iterator[bytes]:
    """A Message record `size` bytes long in all, whose data is zeros, in pieces of 1 MiB."""
    head = HEAD_AND_FIELDS.pack(Opcode.MESSAGE, size - 9, channel_id, 0, log_time, log_time)
    yield head
    left, zeros = size - len(head), bytes(1 << 20)
    while left > 0:
        yield zeros if left >= len(zeros) else zeros[:left]
        left -= len(zeros)


def write_bomb_bag(
    source: Path,
    target: Path,
    topic: str,
    compression: str,
    inflated: int,
    stated: int | None = None,
    before: int = 0,
    in_summary: bool = False,
    count: int = 1,
) -> None:
    """`source`'s messages again (read with the mcap library, written with its record writer, one chunk per message,
    `compression`, a full summary), with one more chunk on `topic`: a message of zeros that inflates to `inflated`
    bytes, stating `stated` (its true size by default: lying low or high otherwise), before the topic's message number
    `before` (after them all when there are fewer), or, `in_summary`, in the summary section where no chunk belongs;
    `count` such chunks in a row."""
    with source.open("rb") as stream:
        triples = list(make_reader(stream).iter_messages(log_time_order=False))
    schemas = {schema.id: schema for schema, _, _ in triples if schema is not None}
    channels = {channel.id: channel for _, channel, _ in triples}
    target_channel = next(channel for channel in channels.values() if channel.topic == topic)
    messages: list[Message | None] = [message for _, _, message in triples]
    on_topic = [row for row, message in enumerate(messages) if message is not None and message.channel_id == target_channel.id]
    at = on_topic[before] if before < len(on_topic) else len(messages)
    messages[at:at] = [None] * count  # None: a bomb
    log_time = triples[0][2].log_time
    bomb = Chunk(
        compression=compression,
        data=packed(compression, _zero_message(target_channel.id, log_time, inflated), inflated),
        message_start_time=log_time,
        message_end_time=log_time,
        uncompressed_crc=0,
        uncompressed_size=inflated if stated is None else stated,
    )
    out = RecordBuilder()
    out.write(MCAP_MAGIC)
    Header("ros2", "bomb").write(out)
    for record in [*schemas.values(), *channels.values()]:
        record.write(out)
    indexes: list[ChunkIndex] = []
    for message in messages:
        if message is None and in_summary:
            continue
        if message is None:
            chunk = bomb
        else:
            content = RecordBuilder()
            message.write(content)
            records = content.end()
            chunk = Chunk(
                compression=compression,
                data=packed(compression, iter([records]), len(records)),
                message_start_time=message.log_time,
                message_end_time=message.log_time,
                uncompressed_crc=zlib.crc32(records),
                uncompressed_size=len(records),
            )
        start = out.count
        chunk.write(out)
        length = out.count - start
        index_start = out.count
        channel_id = target_channel.id if message is None else message.channel_id
        MessageIndex(channel_id=channel_id, records=[(chunk.message_start_time, 0)]).write(out)
        indexes.append(
            ChunkIndex(
                message_start_time=chunk.message_start_time,
                message_end_time=chunk.message_end_time,
                chunk_start_offset=start,
                chunk_length=length,
                message_index_offsets={channel_id: index_start},
                message_index_length=out.count - index_start,
                compression=compression,
                compressed_size=len(chunk.data),
                uncompressed_size=chunk.uncompressed_size,
            )
        )
    DataEnd(0).write(out)
    summary_start = out.count
    if in_summary:
        bomb.write(out)
    for record in [*schemas.values(), *channels.values()]:
        record.write(out)
    counts: dict[int, int] = {}
    for message in messages:
        channel_id = target_channel.id if message is None else message.channel_id
        counts[channel_id] = counts.get(channel_id, 0) + 1
    times = [message.log_time for message in messages if message is not None]
    Statistics(
        message_count=len(messages),
        schema_count=len(schemas),
        channel_count=len(channels),
        attachment_count=0,
        metadata_count=0,
        chunk_count=len(indexes),
        message_start_time=min(times),
        message_end_time=max(times),
        channel_message_counts=counts,
    ).write(out)
    for index in indexes:
        index.write(out)
    Footer(summary_start, 0, 0).write(out)
    out.write(MCAP_MAGIC)
    target.write_bytes(out.end())
