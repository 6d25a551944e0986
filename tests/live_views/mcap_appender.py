"""A recorder for the follow tests, run as a child process (`python -m tests.live_views.mcap_appender FILE ...`): it
appends JointState messages (tests/live_views/follow_motion.py's, message k a function of k) to an MCAP file with the MCAP
project's writer and ROS 2 encoder, in small chunks, flushing the file after each message so each chunk lands as it
is finished; then the footer after --count messages (`finish()`), or, with --no-footer or when killed, none.
--pause-at K --go FILE holds it after K messages (all in the file) until the test creates FILE.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path
from typing import IO, Any

from mcap.writer import CompressionType, Writer
from mcap_ros2._dynamic import serialize_dynamic

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

from .follow_motion import TOPIC, log_time_ns, message, publish_time_ns

JOINT_STATE = "sensor_msgs/msg/JointState"
STRING = "std_msgs/msg/String"
COMPRESSIONS = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("path", type=Path)
    parser.add_argument("--count", type=int, default=100, help="messages before the footer")
    parser.add_argument("--rate", type=float, default=0.0, help="messages a second (0: as fast as it can)")
    parser.add_argument("--compression", choices=sorted(COMPRESSIONS), default="zstd")
    parser.add_argument("--chunk-size", type=int, default=2048, help="bytes of records per chunk (a few KB: many chunks)")
    parser.add_argument("--unchunked", action="store_true", help="messages as top-level records, no chunks")
    parser.add_argument("--seed", type=int, default=0, help="follow_motion's seed: another recording's values and stamps")
    parser.add_argument("--topic", default=TOPIC)
    parser.add_argument("--wrong-schema", action="store_true", help=f"{STRING} on the topic, not {JOINT_STATE}")
    parser.add_argument("--other-every", type=int, default=0, help=f"a {STRING} on /chatter every N messages")
    parser.add_argument("--no-footer", action="store_true", help="end without the footer (the last chunk finished), as a killed recorder")
    parser.add_argument("--pause-at", type=int, default=-1, help="before message K: finish the chunk, then wait for --go to exist")
    parser.add_argument("--go", type=Path, help="the file whose creation ends the pause")
    parser.add_argument(
        "--mode", choices=("new", "replace", "append"), default="new", help="truncate, unlink first (a new inode), or append"
    )
    return parser.parse_args()


def _open(path: Path, mode: str) -> IO[bytes]:
    if mode == "replace":
        path.unlink(missing_ok=True)
        return path.open("xb")
    return path.open("ab" if mode == "append" else "wb")


def main() -> None:
    args = _arguments()
    stream = _open(args.path, args.mode)
    writer = Writer(stream, chunk_size=args.chunk_size, compression=COMPRESSIONS[args.compression], use_chunking=not args.unchunked)
    writer.start(profile="ros2", library="urdf-pipeline tests mcap_appender")
    stream.flush()
    channels: dict[str, tuple[int, Any]] = {}

    def channel(topic: str, datatype: str, msgdef: str) -> tuple[int, Any]:
        if topic not in channels:
            schema = writer.register_schema(datatype, "ros2msg", msgdef.encode())
            channels[topic] = writer.register_channel(topic, "cdr", schema), serialize_dynamic(datatype, msgdef)[datatype]
        return channels[topic]

    for k in range(args.count):
        if k == args.pause_at:
            writer.flush()  # the messages so far all in the file: the test sees them before this writes more
            while not args.go.exists():
                time.sleep(0.01)
        if args.wrong_schema:
            channel_id, encode = channel(args.topic, STRING, "string data\n")
            data = encode({"data": f"message {k}"})
        else:
            channel_id, encode = channel(args.topic, JOINT_STATE, JOINT_STATE_MSGDEF)
            data = encode(message(k, args.seed))
        writer.add_message(channel_id, log_time_ns(k, args.seed), data, publish_time_ns(k, args.seed), sequence=k)
        if args.other_every and k % args.other_every == 0:
            other_id, encode = channel("/chatter", STRING, "string data\n")
            writer.add_message(other_id, log_time_ns(k, args.seed), encode({"data": f"chatter {k}"}), publish_time_ns(k, args.seed))
        stream.flush()  # a finished chunk (or, unchunked, the message) reaches the file now
        if args.rate:
            time.sleep(1.0 / args.rate)
    if args.no_footer:
        writer.flush()
    else:
        writer.finish()
    stream.flush()
    os.fsync(stream.fileno())
    stream.close()


if __name__ == "__main__":
    main()
