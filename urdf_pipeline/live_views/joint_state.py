"""ROS 2 sensor_msgs/msg/JointState messages as live samples: what every live feed (a Foxglove WebSocket server, an
MCAP file being written) yields, decoded from CDR by the MCAP project's ROS 2 decoder (`mcap-ros2-support`).

A run reads finished bags with Rerun's McapReader; a live feed has one message at a time, so it decodes here. Both
take the same fields: the header stamp (`timeline: header`), the log and publish times, `name` and `position`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from ..errors import UserError, Where, shown

JOINT_STATE = "sensor_msgs/msg/JointState"
MAX_NAMES = 4096  # a JointState naming more joints than any robot has is a wrong topic, not a robot


@dataclass(frozen=True)
class JointStateSample:
    """One message of a topic the config's MCAP source names."""

    topic: str  # the topic as the config writes it (the feed matches channels with or without a leading "/")
    names: tuple[str, ...]
    positions: np.ndarray  # float64, one per name
    header_ns: int  # header.stamp in nanoseconds
    log_time_ns: int  # MCAP log time; a Foxglove message's timestamp
    publish_time_ns: int  # MCAP publish time; a Foxglove message's timestamp
    received_ns: int  # time.monotonic_ns() when its bytes reached this process: the start of the latency measured


class Feed(Protocol):
    """A live source of JointState samples. `batches()` blocks until samples arrive and yields them in arrival order,
    at least every `POLL_SECONDS` (an empty list when nothing came), so the caller can stop or flush; it ends when the
    source ends for good (an MCAP file closed by its writer, reconnects used up: then it raises UserError). `close()`
    releases the connection or file, from any thread."""

    description: str  # "ws://127.0.0.1:8765", "bags/run.mcap (followed)": for lines the user reads

    def batches(self) -> Iterator[list[JointStateSample]]: ...

    def close(self) -> None: ...


POLL_SECONDS = 0.25


def same_topic(a: str, b: str) -> bool:
    """ROS topics compare with or without their leading slash, as Rerun's MCAP reader names entities."""
    return "/" + a.lstrip("/") == "/" + b.lstrip("/")


class JointStateDecoder:
    """CDR payloads of one channel -> (header stamp ns, names, positions). Made from the channel's schema; anything
    that is not ROS 2 JointState in CDR is refused by name (`where`: the config's source)."""

    def __init__(
        self, topic: str, schema_name: str, schema_encoding: str, schema_text: str, message_encoding: str, where: Where | None
    ) -> None:
        self.topic, self.where = topic, where
        if schema_name != JOINT_STATE or schema_encoding != "ros2msg" or message_encoding != "cdr":
            raise UserError(
                f"topic '{shown(topic)}' carries {shown(schema_name or 'no schema')} ({shown(schema_encoding)}, "
                f"{shown(message_encoding)}), not ROS 2 {JOINT_STATE} (ros2msg, cdr)",
                where,
            )
        from mcap_ros2._dynamic import generate_dynamic

        try:
            self._decode: Any = generate_dynamic(schema_name, schema_text)[schema_name]
        except Exception as exc:  # noqa: BLE001 - the decoder's parser raises assorted errors on a bad schema text
            raise UserError(f"topic '{shown(topic)}': its {JOINT_STATE} schema does not parse ({shown(exc)})", where) from None

    def __call__(self, payload: bytes | memoryview) -> tuple[int, tuple[str, ...], np.ndarray]:
        try:
            message = self._decode(bytes(payload))
            stamp = message.header.stamp
            header_ns = int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)
            names, positions = tuple(message.name), np.asarray(message.position, dtype=np.float64)
        except Exception as exc:  # noqa: BLE001 - CDR decoding of a damaged payload raises assorted errors
            raise UserError(f"a message on '{shown(self.topic)}' is not a readable {JOINT_STATE} ({shown(exc)})", self.where) from None
        if len(names) > MAX_NAMES:
            raise UserError(f"a message on '{shown(self.topic)}' names {len(names)} joints (at most {MAX_NAMES})", self.where)
        if len(names) != len(positions):
            raise UserError(
                f"a message on '{shown(self.topic)}' has {len(positions)} positions but {len(names)} names; "
                "every message must give one position per name",
                self.where,
            )
        return header_ns, names, positions
