"""ROS 2 sensor_msgs/msg/JointState messages as live samples: what every live feed (a Foxglove WebSocket server, an
MCAP file being written) yields, read from CDR by the sources' one bounded reader of JointState's fixed layout
(`sources.read_joint_state`).

A run reads finished bags with Rerun's McapReader; a live feed has one message at a time, so it decodes here. Both
take the same fields: the header stamp (`timeline: header`), the log and publish times, `name` and `position`.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..errors import UserError, Where, shown
from ..sources import JOINT_STATE, JointStateUnreadable, definition_differs, read_joint_state

MAX_NAME_ORDERS = 4096  # distinct name lists a topic's NameOrders keeps
MAX_ORDER_BYTES = 16 * 1024 * 1024  # the distinct name lists a topic's NameOrders keeps, counted as names_bytes does


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


class NameOrders:
    """One tuple object per distinct list of names (so a consumer can cache by identity), kept for reuse up to
    `MAX_NAME_ORDERS` lists and `MAX_ORDER_BYTES`; past either it starts again (a robot sends one or a few orders)."""

    def __init__(self) -> None:
        self._kept: dict[tuple[str, ...], tuple[str, ...]] = {}
        self._bytes = 0

    def interned(self, names: tuple[str, ...]) -> tuple[str, ...]:
        kept = self._kept.get(names)
        if kept is None:
            size = names_bytes(names)
            if len(self._kept) >= MAX_NAME_ORDERS or self._bytes + size > MAX_ORDER_BYTES:
                self._kept.clear()
                self._bytes = 0
            self._kept[names] = kept = names
            self._bytes += size
        return kept


def names_bytes(names: tuple[str, ...]) -> int:
    """About what a names tuple holds in memory: its slots and its strings (a str is about 50 bytes and its text)."""
    return 56 + 8 * len(names) + sum(map(len, names)) + 50 * len(names)


class JointStateDecoder:
    """CDR payloads of one channel -> (header stamp ns, names, positions). Made from the channel's schema: anything
    that is not ROS 2 JointState in CDR, by name and by definition, is refused by name (`where`: the config's source).
    `orders`: the NameOrders the names are interned in (one per topic, kept across reconnects; else the decoder's)."""

    def __init__(
        self,
        topic: str,
        schema_name: str,
        schema_encoding: str,
        schema_text: str,
        message_encoding: str,
        where: Where | None,
        orders: NameOrders | None = None,
    ) -> None:
        self.topic, self.where = topic, where
        self.orders = orders or NameOrders()
        if schema_name != JOINT_STATE or schema_encoding != "ros2msg" or message_encoding != "cdr":
            raise UserError(
                f"topic '{shown(topic)}' carries {shown(schema_name or 'no schema')} ({shown(schema_encoding)}, "
                f"{shown(message_encoding)}), not ROS 2 {JOINT_STATE} (ros2msg, cdr)",
                where,
            )
        differs = definition_differs(schema_text)
        if differs is not None:
            raise UserError(f"topic '{shown(topic)}' is named {JOINT_STATE}, but {differs}", where)

    def __call__(self, payload: bytes | memoryview) -> tuple[int, tuple[str, ...], np.ndarray]:
        try:
            header_ns, names, positions = read_joint_state(bytes(payload))
        except JointStateUnreadable as exc:
            raise UserError(f"a message on '{shown(self.topic)}' is not a readable {JOINT_STATE} ({exc})", self.where) from None
        if len(names) != len(positions):
            raise UserError(
                f"a message on '{shown(self.topic)}' has {len(positions)} positions but {len(names)} names; "
                "every message must give one position per name",
                self.where,
            )
        return header_ns, self.orders.interned(names), positions
