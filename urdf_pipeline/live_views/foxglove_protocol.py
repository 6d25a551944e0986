"""The Foxglove WebSocket protocol (ws-protocol v1, what foxglove_bridge and the Foxglove SDK serve), the part a
subscriber needs: the server's JSON messages (serverInfo, advertise, unadvertise) read strictly, the subscribe
message, and the binary "message data" frame. No network here: `foxglove_socket` moves the frames, the feed uses them.

Anything a Foxglove server never sends (JSON that is no object with an `op`, a channel without an integer id or a
string topic, a binary frame shorter than its header) raises `ProtocolError`, which the feed words with the URL.
"""

from __future__ import annotations

import json
import struct
from dataclasses import dataclass
from typing import Any

# The SDK's servers accept only `foxglove.sdk.v1` (and answer `foxglove.websocket.v1` with 400); foxglove_bridge and
# older servers speak `foxglove.websocket.v1`. A client offers both; the server picks.
SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
MAX_FRAME_BYTES = 16 * 1024 * 1024  # a JointState is a few kB; a bigger frame is no joint state, and memory is bounded
# A JSON message (serverInfo, advertise: every topic's definition, a few kB each) becomes Python objects, up to about
# 25 times its bytes (`[{},{},...]`): bounded tighter than a binary one.
MAX_TEXT_BYTES = 4 * 1024 * 1024
MESSAGE_DATA = 0x01  # the binary opcode of a subscribed message; the others (time, service responses) are not ours
_MESSAGE_HEADER = struct.Struct("<BIQ")  # opcode, subscription id, timestamp (ns), then the payload
_UINT32 = 2**32


class ProtocolError(Exception):
    """A frame no Foxglove server sends (the feed refuses the server, naming it)."""


@dataclass(frozen=True)
class Advertised:
    """One channel of an advertise message, as the server describes it."""

    id: int
    topic: str
    encoding: str  # the message encoding: "cdr" for ROS 2
    schema_name: str
    schema_encoding: str  # "ros2msg" for ROS 2 message definitions
    schema: str  # the schema text (a ros2msg definition is sent as text, not base64)


def server_message(data: bytes | str) -> dict[str, Any]:
    """A JSON text frame as the object it must be (with a string `op`)."""
    try:
        message = json.loads(data)
    except (ValueError, UnicodeDecodeError) as exc:
        raise ProtocolError(f"a text frame that is not JSON ({exc})") from None
    except RecursionError:
        raise ProtocolError("a text frame of JSON nested too deep") from None
    if not isinstance(message, dict) or not isinstance(message.get("op"), str):
        raise ProtocolError("a JSON message that is not an object with an 'op'")
    return message


def _channel_id(value: object, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < _UINT32:
        raise ProtocolError(f"{what} with an id that is not a 32-bit unsigned integer")
    return value


def _text(channel: dict[str, Any], key: str, default: str | None = None) -> str:
    value = channel.get(key, default)
    if not isinstance(value, str):
        raise ProtocolError(f"an advertised channel whose '{key}' is not a string")
    return value


def advertised(message: dict[str, Any]) -> list[Advertised]:
    """The channels of an `advertise` message. A server that omits `schemaEncoding` (older foxglove_bridge releases)
    means the one its message encoding implies: `ros2msg` for `cdr`."""
    channels = message.get("channels")
    if not isinstance(channels, list):
        raise ProtocolError("an advertise message without a list of channels")
    found = []
    for channel in channels:
        if not isinstance(channel, dict):
            raise ProtocolError("an advertised channel that is not an object")
        encoding = _text(channel, "encoding")
        found.append(
            Advertised(
                id=_channel_id(channel.get("id"), "an advertised channel"),
                topic=_text(channel, "topic"),
                encoding=encoding,
                schema_name=_text(channel, "schemaName"),
                schema_encoding=_text(channel, "schemaEncoding", "ros2msg" if encoding == "cdr" else ""),
                schema=_text(channel, "schema", ""),
            )
        )
    return found


def unadvertised(message: dict[str, Any]) -> list[int]:
    """The channel ids of an `unadvertise` message."""
    ids = message.get("channelIds")
    if not isinstance(ids, list):
        raise ProtocolError("an unadvertise message without a list of channel ids")
    return [_channel_id(value, "an unadvertised channel") for value in ids]


def subscribe(subscriptions: list[tuple[int, int]]) -> str:
    """The subscribe message for (subscription id, channel id) pairs; the client chooses the subscription ids."""
    return json.dumps({"op": "subscribe", "subscriptions": [{"id": sub, "channelId": channel} for sub, channel in subscriptions]})


def message_data(frame: bytes) -> tuple[int, int, memoryview] | None:
    """(subscription id, timestamp ns, payload) of a binary message-data frame; None for the binary frames a
    subscriber ignores (server time, service responses, assets)."""
    if not frame:
        raise ProtocolError("an empty binary frame")
    if frame[0] != MESSAGE_DATA:
        return None
    if len(frame) < _MESSAGE_HEADER.size:
        raise ProtocolError(f"a message-data frame of {len(frame)} bytes, shorter than its {_MESSAGE_HEADER.size}-byte header")
    _, subscription, timestamp = _MESSAGE_HEADER.unpack_from(frame)
    return subscription, timestamp, memoryview(frame)[_MESSAGE_HEADER.size :]
