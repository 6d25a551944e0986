"""A real Foxglove WebSocket server for the live tests (foxglove-sdk, the server the SDK's robots run; foxglove_bridge
speaks the same protocol): ROS 2 sensor_msgs/msg/JointState in CDR on one topic, the motion of `joint_motion`.

Run as a child process from the repository root: `python -m tests.live_views.foxglove_server --port P [--rate HZ]
[--count N] [--first K] ...`. It prints `ready PORT` once serving, waits for a subscriber, publishes messages
k = FIRST, FIRST+1, ... (N of them; 0: until killed) at HZ, then serves on until killed (or exits, `--exit-when-done`).
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Iterator

import foxglove
from foxglove.websocket import ChannelView, Client, ServerListener

from tests.live_views.joint_motion import LOG_DELAY_NS, LOWER, NAMES, UPPER, message, stamp_ns
from urdf_pipeline.examples import JOINT_STATE_MSGDEF

JOINT_STATE = "sensor_msgs/msg/JointState"


class _Subscribed(ServerListener):
    """The server's listener (the protocol's other callbacks do nothing): `event` is set once a client subscribes."""

    def __init__(self) -> None:
        self.event = threading.Event()

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.event.set()


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--rate", type=float, default=200.0, help="messages per second")
    parser.add_argument("--names", default=",".join(NAMES), help="the joints, comma-separated")
    parser.add_argument("--first", type=int, default=0, help="the index k of the first message")
    parser.add_argument("--count", type=int, default=0, help="messages to publish; 0: until killed")
    parser.add_argument("--topic", default="/joint_states")
    parser.add_argument("--schema-name", default=JOINT_STATE, help="another name advertises a wrong schema")
    parser.add_argument("--garbage-bytes", type=int, default=0, help="publish payloads of this many 0xff bytes instead")
    parser.add_argument("--advertise-on-input", action="store_true", help="advertise the topic after a line on stdin")
    parser.add_argument("--exit-when-done", action="store_true")
    parser.add_argument("--range", default=f"{LOWER},{UPPER}", help="LOW,HIGH: the values stay within it (joint_motion.values)")
    return parser.parse_args()


def _payloads(options: argparse.Namespace, period_ns: int) -> Iterator[tuple[int, bytes]]:
    """(log time, payload) of each message k, from the first on."""
    from mcap_ros2._dynamic import serialize_dynamic

    encode = serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE]
    names = options.names.split(",")
    lower, upper = (float(v) for v in options.range.split(","))
    k = options.first
    while options.count == 0 or k < options.first + options.count:
        stamp = stamp_ns(k, period_ns)
        payload = (
            b"\xff" * options.garbage_bytes if options.garbage_bytes else encode(message(k, names, period_ns, lower=lower, upper=upper))
        )
        yield stamp + LOG_DELAY_NS, payload
        k += 1


def _channel(options: argparse.Namespace) -> foxglove.Channel:
    schema_text = JOINT_STATE_MSGDEF if options.schema_name == JOINT_STATE else "string data\n"
    schema = foxglove.Schema(name=options.schema_name, encoding="ros2msg", data=schema_text.encode())
    return foxglove.Channel(options.topic, message_encoding="cdr", schema=schema)


def main() -> int:
    options = _arguments()
    listener = _Subscribed()
    # The channel exists before the server starts (unless it is to come later): the SDK's server refuses ("unknown
    # channel") a subscription from a client whose connection raced with the channel's creation.
    channel = None if options.advertise_on_input else _channel(options)
    server = foxglove.start_server(host="127.0.0.1", port=options.port, server_listener=listener)
    print(f"ready {server.port}", flush=True)
    if channel is None:
        sys.stdin.readline()
        channel = _channel(options)
    listener.event.wait()
    period_ns = round(1e9 / options.rate)
    next_time = time.monotonic()
    for log_time, payload in _payloads(options, period_ns):
        channel.log(payload, log_time=log_time)
        next_time += period_ns / 1e9
        time.sleep(max(next_time - time.monotonic(), 0.0))
    if not options.exit_when_done:
        threading.Event().wait()
    time.sleep(1.0)  # the server queues each client's messages: stopping at once would drop the last ones unsent
    server.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
