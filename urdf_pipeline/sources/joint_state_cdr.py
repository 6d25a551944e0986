"""ROS 2 sensor_msgs/msg/JointState in CDR, read by one bounded reader of its fixed layout: the live feeds' messages
and a remote bag's first message. Nothing a stranger sends is compiled: a channel's advertised definition is only
compared, normalised, with JointState's own, and each count is checked against the bytes left before anything is made,
so a message's cost is bounded by its bytes.
"""

from __future__ import annotations

import re
import struct

import numpy as np

from ..errors import quoted, shown

JOINT_STATE = "sensor_msgs/msg/JointState"
MAX_NAMES = 4096  # a JointState naming more joints than any robot has is a wrong topic, not a robot
MAX_NAME_BYTES = 256  # one joint name, in UTF-8 (URDF joint names are a few dozen characters)
MAX_SCHEMA_BYTES = 64 * 1024  # the JointState definition with its comments is about 3 kB


class JointStateUnreadable(Exception):
    """A payload that is no JointState in CDR (the decoder words it with the topic)."""


# sensor_msgs/msg/JointState as its definition declares it, each type by its canonical name (`_canonical`).
_EXPECTED = {
    "sensor_msgs/JointState": (
        ("std_msgs/Header", "header"),
        ("string[]", "name"),
        ("float64[]", "position"),
        ("float64[]", "velocity"),
        ("float64[]", "effort"),
    ),
    "std_msgs/Header": (("builtin_interfaces/Time", "stamp"), ("string", "frame_id")),
    "builtin_interfaces/Time": (("int32", "sec"), ("uint32", "nanosec")),
}
_SEPARATOR = re.compile(r"^=+\s*$", re.MULTILINE)


def _canonical(type_name: str) -> str:
    """`Header` -> `std_msgs/Header`, `pkg/msg/Type` -> `pkg/Type`, an array suffix kept."""
    base, bracket, rest = type_name.partition("[")
    parts = base.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        base = f"{parts[0]}/{parts[2]}"
    elif base == "Header":
        base = "std_msgs/Header"
    return base + bracket + rest


def definition_differs(schema_text: str) -> str | None:
    """Why a ros2msg definition is not JointState's (None when it is, normalised): read line by line, never built."""
    if len(schema_text) > MAX_SCHEMA_BYTES:
        return f"its definition is {len(schema_text):,} characters long (JointState's is about 3,000)"
    sections: dict[str, tuple[tuple[str, str], ...]] = {}
    for index, section in enumerate(_SEPARATOR.split(schema_text)):
        lines = [line.split("#", 1)[0].strip() for line in section.splitlines()]
        lines = [line for line in lines if line]
        name = "sensor_msgs/JointState"
        if index:
            if not lines or not lines[0].startswith("MSG:"):
                return "a section of its definition does not start with 'MSG: TYPE'"
            name, lines = _canonical(lines[0][4:].strip()), lines[1:]
        fields = []
        for line in lines:
            words = line.split()
            if len(words) != 2 or "=" in line:
                return f"its definition has the line {quoted(line)}, which JointState's has not"
            fields.append((_canonical(words[0]), words[1]))
        if name in sections:
            return f"its definition defines {shown(name)} twice"
        sections[name] = tuple(fields)
    if sections != _EXPECTED:
        for name, expected in _EXPECTED.items():
            if sections.get(name) != expected:
                return f"its definition of {name} is not ROS 2's ({', '.join(f'{t} {n}' for t, n in expected)})"
        return "its definition has types JointState's has not"
    return None


class _Cdr:
    """A plain CDR (XCDR1) reader over one payload: each value aligned to its size from the end of the 4-byte
    encapsulation header, each count checked against the bytes left before anything is made of it."""

    __slots__ = ("_at", "_data", "_order", "_u32")

    def __init__(self, data: bytes) -> None:
        if len(data) < 4 or data[0] != 0 or data[1] not in (0, 1):
            raise JointStateUnreadable("it does not start with a plain CDR encapsulation header")
        self._data, self._at = data, 4
        self._order = "<" if data[1] == 1 else ">"
        self._u32 = struct.Struct(self._order + "I")

    def _take(self, size: int, align: int) -> int:
        """The offset of the next `size` bytes, aligned to `align`; past the end: JointStateUnreadable."""
        at = self._at + (-(self._at - 4) % align)
        if at + size > len(self._data):
            raise JointStateUnreadable(f"it ends {len(self._data)} bytes in, before its fields do")
        self._at = at + size
        return at

    def uint32(self) -> int:
        value: int = self._u32.unpack_from(self._data, self._take(4, 4))[0]
        return value

    def int32(self) -> int:
        value: int = struct.unpack_from(self._order + "i", self._data, self._take(4, 4))[0]
        return value

    def string(self, most: int, what: str) -> str:
        length = self.uint32()  # with its terminating NUL; some writers give an empty string length 0
        if length > most + 1:
            raise JointStateUnreadable(f"its {what} is {length - 1:,} bytes long (at most {most})")
        at = self._take(length, 1)
        try:
            return self._data[at : at + max(length - 1, 0)].decode("utf-8")
        except UnicodeDecodeError:
            raise JointStateUnreadable(f"its {what} is not UTF-8") from None

    def count(self, least_bytes: int, most: int, what: str) -> int:
        """A sequence's length, each element at least `least_bytes`: at most `most`, and what the bytes left hold."""
        count = self.uint32()
        if count > most:
            raise JointStateUnreadable(f"it names {count:,} {what} (at most {most:,})")
        if count * least_bytes > len(self._data) - self._at:
            raise JointStateUnreadable(f"it says {count:,} {what} but has {len(self._data) - self._at:,} bytes left")
        return count

    def float64s(self, what: str) -> np.ndarray:
        count = self.count(8, MAX_NAMES, what)
        if not count:
            return np.empty(0, np.float64)
        at = self._take(8 * count, 8)
        return np.frombuffer(self._data, self._order + "f8", count, at).astype(np.float64)


def read_joint_state(payload: bytes) -> tuple[int, tuple[str, ...], np.ndarray]:
    """(header stamp ns, names, positions) of a JointState in CDR; JointStateUnreadable otherwise. Velocity and effort are
    checked to fit, not kept."""
    cdr = _Cdr(payload)
    sec, nanosec = cdr.int32(), cdr.uint32()
    cdr.string(MAX_NAME_BYTES, "header's frame_id")
    names = tuple(cdr.string(MAX_NAME_BYTES, "joint name") for _ in range(cdr.count(5, MAX_NAMES, "joints")))
    positions = cdr.float64s("positions")
    cdr.float64s("velocities")
    cdr.float64s("efforts")
    return sec * 1_000_000_000 + nanosec, names, positions
