"""`McapFollowFeed`: an MCAP file followed while a real writer (the MCAP project's, in a child process:
tests/live_views/mcap_appender.py) appends JointState messages to it. Every message arrives once, in order, equal to what
follow_motion.py says message k is; the follow ends at the footer, waits for a file not there yet, reads a restarted
recorder's new file, and refuses a wrong schema, a file that is no MCAP and damaged records with a located line.

No timed assertion: the tests wait for what they expect, with a watchdog (`close()` after WATCHDOG_SECONDS) that turns
a hang into a failure.
"""

from __future__ import annotations

import logging
import os
import struct
import subprocess
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from urdf_pipeline.errors import UserError, Where
from urdf_pipeline.live_views.joint_state import JointStateSample
from urdf_pipeline.live_views.mcap_follow import McapFollowFeed
from urdf_pipeline.live_views.mcap_records import MAGIC, RecordSplitter

from ..bag_inputs import write_bomb_bag, write_robot_bag
from ..edge_helpers import RIG_URDF, write_config
from .follow_motion import TOPIC, header_ns, log_time_ns, names, position, publish_time_ns

REPO = Path(__file__).resolve().parents[2]
WATCHDOG_SECONDS = 60.0
Step = Callable[[list[JointStateSample]], None]


@contextmanager
def watchdog(feed: McapFollowFeed) -> Iterator[None]:
    timer = threading.Timer(WATCHDOG_SECONDS, feed.close)
    timer.start()
    try:
        yield
    finally:
        timer.cancel()
        timer.join()


def follow(feed: McapFollowFeed, step: Step | None = None) -> list[JointStateSample]:
    """Every sample until the feed ends; `step(samples so far)` after each batch (to act on the file meanwhile)."""
    samples: list[JointStateSample] = []
    with watchdog(feed):
        for batch in feed.batches():
            samples.extend(batch)
            if step is not None:
                step(samples)
    return samples


def assert_motion(samples: list[JointStateSample], count: int, seed: int = 0, topic: str = TOPIC) -> None:
    """The samples are messages 0..count-1 of follow_motion, in order, each field as written."""
    assert [sample.header_ns for sample in samples] == [header_ns(k, seed) for k in range(count)]
    for k, sample in enumerate(samples):
        assert sample.topic == topic
        assert sample.names == names(k, seed)
        np.testing.assert_array_equal(sample.positions, [position(joint, k, seed) for joint in sample.names])
        assert (sample.log_time_ns, sample.publish_time_ns) == (log_time_ns(k, seed), publish_time_ns(k, seed))
    distinct = {sample.names for sample in samples}
    assert len({id(sample.names) for sample in samples}) == len(distinct), "equal name lists are one tuple object"


def lines(caplog: pytest.LogCaptureFixture) -> str:
    return "\n".join(record.getMessage() for record in caplog.records)


@pytest.fixture(autouse=True)
def _info_lines(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="urdf_pipeline")


@pytest.mark.parametrize("form", [("--compression", "zstd"), ("--compression", "lz4"), ("--compression", "none"), ("--unchunked",)])
def test_every_message_arrives_once_in_order_while_the_file_grows(
    tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]], caplog: pytest.LogCaptureFixture, form: tuple[str, ...]
) -> None:
    """The recorder writes 120 messages (and a String topic between them), pauses with all of them in the file, and
    goes on only once the feed has yielded them: the feed reads the file as it grows, not at its end."""
    path, go = tmp_path / "run.mcap", tmp_path / "go"
    recorder = appender(path, "--count", "300", "--pause-at", "120", "--go", str(go), "--other-every", "7", *form)
    received_before_the_footer: list[int] = []

    def step(samples: list[JointStateSample]) -> None:
        if len(samples) >= 120 and not go.exists():
            received_before_the_footer.append(len(samples))
            assert recorder.poll() is None, "the recorder waits for the go file"
            go.touch()

    samples = follow(McapFollowFeed(path, {TOPIC: None}), step)
    assert received_before_the_footer == [120]
    assert_motion(samples, 300)
    assert f"live: {path} was closed by its writer after 300 messages" in lines(caplog)
    assert recorder.wait() == 0


def test_a_topic_matches_with_or_without_its_slash(tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]]) -> None:
    path = tmp_path / "run.mcap"
    assert appender(path, "--count", "30").wait() == 0
    assert_motion(follow(McapFollowFeed(path, {"joint_states": None})), 30, topic="joint_states")


def test_a_file_that_appears_after_the_feed_starts(
    tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]], caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "later.mcap"
    started: list[bool] = []

    def step(samples: list[JointStateSample]) -> None:
        if not started and "waiting for" in lines(caplog):
            started.append(True)
            appender(path, "--count", "50")

    samples = follow(McapFollowFeed(path, {TOPIC: None}, wait_seconds=WATCHDOG_SECONDS), step)
    assert_motion(samples, 50)
    assert f"live: waiting for {path} to appear" in lines(caplog)


def test_a_file_that_never_appears_is_named(tmp_path: Path) -> None:
    where = Where(tmp_path / "robot.yaml", 9, "sources.arm.mcap")
    with pytest.raises(UserError, match=r"nowhere\.mcap did not appear within 0\.2 s") as raised:
        follow(McapFollowFeed(tmp_path / "nowhere.mcap", {TOPIC: None}, where, wait_seconds=0.2))
    assert raised.value.where == where


@pytest.mark.parametrize("restart", ["replace", "truncate", "new"])
def test_a_restarted_recorder_is_followed_into_its_new_file(
    tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]], caplog: pytest.LogCaptureFixture, restart: str
) -> None:
    """The first recording ends without a footer (the recorder stopped); the second, another motion (seed 1), is
    written at the same path: a new file (new inode), the same file truncated then appended to, or opened "wb"."""
    path = tmp_path / "run.mcap"
    assert appender(path, "--count", "40", "--no-footer").wait() == 0
    started: list[bool] = []

    def step(samples: list[JointStateSample]) -> None:
        if len(samples) < 40 or started:
            return
        if restart == "truncate":
            if "shrank" not in lines(caplog):
                if path.stat().st_size:
                    os.truncate(path, 0)
                return
            appender(path, "--count", "30", "--seed", "1", "--mode", "append")
        else:
            appender(path, "--count", "30", "--seed", "1", "--mode", restart)
        started.append(True)

    samples = follow(McapFollowFeed(path, {TOPIC: None}), step)
    assert_motion(samples[:40], 40)
    assert_motion(samples[40:], 30, seed=1)
    said = lines(caplog)
    assert "(the recorder restarted?)" in said
    assert {"replace": "was replaced", "truncate": "shrank"}.get(restart, "restarted") in said
    assert f"live: {path} was closed by its writer after 30 messages" in said


def test_a_wrong_schema_on_the_topic_is_refused_by_name(tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]]) -> None:
    path = tmp_path / "run.mcap"
    assert appender(path, "--count", "20", "--wrong-schema").wait() == 0
    where = Where(tmp_path / "robot.yaml", 7, "sources.arm.topic")
    with pytest.raises(
        UserError, match=r"topic '/joint_states' carries std_msgs/msg/String \(ros2msg, cdr\), not ROS 2 sensor_msgs"
    ) as raised:
        follow(McapFollowFeed(path, {TOPIC: where}))
    assert raised.value.where == where


def test_a_message_that_is_no_joint_state_is_refused_at_its_offset(tmp_path: Path) -> None:
    """A JointState channel whose second message is not CDR JointState: refused naming the topic and the record."""
    from mcap.writer import Writer
    from mcap_ros2._dynamic import serialize_dynamic

    from urdf_pipeline.examples import JOINT_STATE_MSGDEF
    from urdf_pipeline.sources import JOINT_STATE

    from .follow_motion import message

    path = tmp_path / "run.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream, use_chunking=False)
        writer.start(profile="ros2")
        channel = writer.register_channel(TOPIC, "cdr", writer.register_schema(JOINT_STATE, "ros2msg", JOINT_STATE_MSGDEF.encode()))
        writer.add_message(channel, 1, serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE](message(0)), 1)
        at = stream.tell()
        writer.add_message(channel, 2, b"\x00\x01\x00\x00\xff\xff\xff\x7f", 2)
        writer.finish()
    where = Where(tmp_path / "robot.yaml", 7, "sources.arm.topic")
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {TOPIC: where}))
    assert raised.value.message.startswith(f"MCAP file {path}, byte {at}: a message on '/joint_states' is not a readable sensor_msgs")
    assert raised.value.where == where


def test_a_file_defining_endless_schemas_and_channels_is_refused_at_the_record(tmp_path: Path) -> None:
    """What a followed file defines is kept within bounds: schemas past DEFINITIONS_KEPT are refused at the record that
    crosses it, before the file's memory grows with them (a schema of another type keeps no text at all)."""
    from mcap.writer import Writer

    from urdf_pipeline.live_views.mcap_follow import DEFINITIONS_KEPT

    path = tmp_path / "run.mcap"
    with path.open("wb") as stream:
        writer = Writer(stream, use_chunking=False)
        writer.start(profile="ros2")
        for index in range(DEFINITIONS_KEPT + 1):
            writer.register_schema(f"pkg/msg/T{index}", "ros2msg", b"string s\n")
        writer.finish()
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {TOPIC: None}))
    assert raised.value.message.startswith(f"MCAP file {path}, byte ")
    assert f": it defines more than {DEFINITIONS_KEPT:,} schemas or channels" in raised.value.message


def test_a_file_without_the_topic_ends_saying_which_it_has(
    tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]], caplog: pytest.LogCaptureFixture
) -> None:
    path = tmp_path / "run.mcap"
    assert appender(path, "--count", "20", "--topic", "/arm/joint_states").wait() == 0
    assert follow(McapFollowFeed(path, {"/leg/joint_states": None})) == []
    assert "after 0 messages; it has no channel on '/leg/joint_states' (its topics: '/arm/joint_states')" in lines(caplog)


def test_a_file_that_is_no_mcap_is_refused_at_byte_0(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    path.write_text("time,joint\n0,1\n")
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {TOPIC: None}))
    assert f"MCAP file {path}, byte 0: not an MCAP file" in raised.value.message
    assert "\n" not in raised.value.message


def records(data: bytes) -> list[tuple[int, int, int]]:
    """(offset, opcode, content length) of each record after the magic, from the framing alone."""
    found, at = [], len(MAGIC)
    while at + 9 <= len(data):
        opcode, length = struct.unpack_from("<BQ", data, at)
        found.append((at, opcode, length))
        at += 9 + length
    return found


def first_chunk(data: bytes) -> int:
    return next(at for at, opcode, _ in records(data) if opcode == 0x06)


def _huge_record(data: bytes) -> tuple[bytes, int, str]:
    at = records(data)[1][0]  # after the header
    return data[:at] + struct.pack("<BQ", 0x06, 1 << 40), at, "of 1,099,511,627,776 bytes, beyond 17 MiB"


def _short_channel(data: bytes) -> tuple[bytes, int, str]:
    at = records(data)[1][0]
    return data[:at] + struct.pack("<BQ", 0x04, 3) + b"abc" + data[at:], at, "whose content ends before its fields do"


def _garbled_zstd(data: bytes) -> tuple[bytes, int, str]:
    at = first_chunk(data)
    body = at + 9 + 8 + 8 + 8 + 4 + 4 + len(b"zstd") + 8  # the compressed bytes, after the chunk's fields
    return data[:body] + bytes(b ^ 0x5A for b in data[body : body + 40]) + data[body + 40 :], at, "a zstd chunk that does not inflate ("


def _garbled_records(data: bytes) -> tuple[bytes, int, str]:
    """An uncompressed chunk's records changed: its CRC says so."""
    at = first_chunk(data)
    body = at + 9 + 8 + 8 + 8 + 4 + 4 + 8 + 40
    return data[:body] + bytes(b ^ 0x5A for b in data[body : body + 8]) + data[body + 8 :], at, "a chunk whose records do not match its CRC"


def _chunk_too_large(data: bytes) -> tuple[bytes, int, str]:
    at = first_chunk(data)
    size = at + 9 + 16  # uncompressed_size, after the start and end times
    return data[:size] + struct.pack("<Q", 1 << 50) + data[size + 8 :], at, "bytes uncompressed, beyond the 16 MiB a chunk may hold"


def _chunk_larger_than_stated(data: bytes) -> tuple[bytes, int, str]:
    at = first_chunk(data)
    size = at + 9 + 16
    return data[:size] + struct.pack("<Q", 100) + data[size + 8 :], at, "stating 100 bytes uncompressed inflates to more bytes"


@pytest.mark.parametrize(
    "damage, compression",
    [
        (_huge_record, "zstd"),
        (_short_channel, "zstd"),
        (_garbled_zstd, "zstd"),
        (_garbled_records, "none"),
        (_chunk_too_large, "lz4"),
        (_chunk_larger_than_stated, "zstd"),
        (_chunk_larger_than_stated, "lz4"),
    ],
)
def test_a_damaged_record_is_refused_at_its_offset(
    tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]], damage: Callable[[bytes], tuple[bytes, int, str]], compression: str
) -> None:
    good = tmp_path / "good.mcap"
    assert appender(good, "--count", "60", "--compression", compression).wait() == 0
    data, at, why = damage(good.read_bytes())
    path = tmp_path / "run.mcap"
    path.write_bytes(data)
    where = Where(tmp_path / "robot.yaml", 3, "sources.arm.mcap")
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {TOPIC: None}, where))
    assert raised.value.message.startswith(f"MCAP file {path}, byte {at}: ")
    assert why in raised.value.message
    assert "\n" not in raised.value.message and raised.value.where == where


@pytest.mark.parametrize("compression", ["zstd", "lz4"])
def test_a_chunk_that_inflates_beyond_its_stated_size_is_not_inflated(compression: str) -> None:
    """A chunk stating 64 bytes whose frame inflates to 512 MiB (the zstd frame says so in its header): refused after
    reading 65 bytes of it, not 512 MiB (the process's peak memory grows by far less)."""
    import resource

    import zstandard
    from lz4 import frame as lz4_frame
    from mcap.data_stream import RecordBuilder
    from mcap.records import Chunk

    zeros, size = bytes(1 << 20), 512 << 20
    if compression == "zstd":
        packer = zstandard.ZstdCompressor().compressobj(size=size)
        compressed = b"".join(packer.compress(zeros) for _ in range(size // len(zeros))) + packer.flush()
    else:
        packer = lz4_frame.LZ4FrameCompressor()  # begin() without the size: the frame does not state it
        compressed = packer.begin() + b"".join(packer.compress(zeros) for _ in range(size // len(zeros))) + packer.flush()
    builder = RecordBuilder()
    Chunk(
        compression=compression, data=compressed, message_end_time=0, message_start_time=0, uncompressed_crc=0, uncompressed_size=64
    ).write(builder)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    with pytest.raises(UserError, match=r"run\.mcap, byte 8: a chunk stating 64 bytes uncompressed inflates to more bytes"):
        RecordSplitter("run.mcap", None).feed(MAGIC + builder.end())
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - peak < 64 << 10  # KiB: far from 512 MiB


def test_records_are_whole_however_the_bytes_come(tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]]) -> None:
    """The splitter gives the same records, each once, whether the file comes whole or in pieces of 1 to 97 bytes."""
    path = tmp_path / "run.mcap"
    assert appender(path, "--count", "80", "--other-every", "3").wait() == 0
    data = path.read_bytes()
    whole = RecordSplitter("run.mcap", None).feed(data)
    pieces, splitter, at = [], RecordSplitter("run.mcap", None), 0
    for size in np.random.default_rng(3).integers(1, 98, size=len(data)):
        pieces.extend(splitter.feed(data[at : at + size]))
        at += int(size)
    assert pieces == whole and splitter.footer
    assert sum(type(record).__name__ == "Message" for _, record in whole) == 80 + 27


def test_a_file_written_a_few_bytes_at_a_time(tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]]) -> None:
    """A thread appends a finished file's bytes to the followed path in pieces of 1 to 300 bytes: the feed reads
    records cut anywhere (the magic too), each when its last byte is there."""
    source = tmp_path / "source.mcap"
    assert appender(source, "--count", "40", "--compression", "lz4").wait() == 0
    data, path = source.read_bytes(), tmp_path / "run.mcap"
    path.touch()
    done = threading.Event()

    def write() -> None:
        at, sizes = 0, np.random.default_rng(5).integers(1, 301, size=len(data))
        with path.open("ab", buffering=0) as stream:
            for size in sizes:
                if at >= len(data) or done.wait(0.002):
                    return
                stream.write(data[at : at + int(size)])
                at += int(size)

    writer = threading.Thread(target=write)
    writer.start()
    try:
        assert_motion(follow(McapFollowFeed(path, {TOPIC: None})), 40)
    finally:
        done.set()
        writer.join()


def open_handles(path: Path) -> int:
    return sum(1 for fd in Path("/proc/self/fd").iterdir() if os.path.realpath(fd) == str(path.resolve()))


def test_close_from_another_thread_ends_the_follow(tmp_path: Path, appender: Callable[..., subprocess.Popen[bytes]]) -> None:
    """A recorder that goes on for minutes: close() from another thread ends batches(), leaving no handle open."""
    path = tmp_path / "run.mcap"
    appender(path, "--count", "100000", "--rate", "200", "--unchunked", "--no-footer")
    feed = McapFollowFeed(path, {TOPIC: None})
    threads = threading.active_count()
    closers: list[threading.Thread] = []

    def step(samples: list[JointStateSample]) -> None:
        if samples and not closers:
            assert open_handles(path) == 1
            closers.append(threading.Thread(target=feed.close))
            closers[0].start()

    samples = follow(feed, step)
    closers[0].join()
    assert samples and samples[-1].header_ns < header_ns(100000 - 1)  # it ended before the recorder did
    assert_motion(samples, len(samples))
    assert open_handles(path) == 0 and threading.active_count() == threads


def test_close_while_waiting_for_the_file(tmp_path: Path) -> None:
    feed = McapFollowFeed(tmp_path / "nowhere.mcap", {TOPIC: None}, wait_seconds=WATCHDOG_SECONDS)
    batches = 0

    def step(samples: list[JointStateSample]) -> None:
        nonlocal batches
        batches += 1
        if batches == 2:
            threading.Thread(target=feed.close).start()

    assert follow(feed, step) == []


@pytest.fixture(scope="module")
def rig_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("rig") / "good.mcap"
    write_robot_bag(path, [RIG_URDF], [], ["shoulder"], np.linspace(0.0, 1.0, 12)[:, None])
    return path


@pytest.mark.parametrize(
    "compression, options, why",
    [
        ("zstd", {}, "a chunk stating 1,073,741,824 bytes uncompressed, beyond the 16 MiB a chunk may hold"),
        ("lz4", {"stated": 64}, "a chunk stating 64 bytes uncompressed inflates to more bytes"),
        ("zstd", {"before": 6, "inflated": 17 << 20}, "a chunk stating 17,825,792 bytes uncompressed, beyond the 16 MiB"),
        ("zstd", {"in_summary": True}, "a chunk stating 1,073,741,824 bytes uncompressed, beyond the 16 MiB"),
    ],
)
def test_a_decompression_bomb_in_a_followed_file_is_refused_at_its_offset(
    rig_bag: Path, tmp_path: Path, compression: str, options: dict[str, Any], why: str
) -> None:
    """A chunk of a few KB that inflates to a GiB of zeros (or just past the 16 MiB a followed chunk may hold), stating it
    or stating 64 bytes, wherever it is (among the messages, in the summary section): refused after inflating at most
    the bound plus one byte."""
    path = tmp_path / "run.mcap"
    write_bomb_bag(rig_bag, path, "/joint_states", compression, options.pop("inflated", 1 << 30), **options)
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {"/joint_states": None}))
    assert raised.value.message.startswith(f"MCAP file {path}, byte ") and why in raised.value.message, raised.value.message
    assert "\n" not in raised.value.message


def test_live_from_a_bomb_is_one_error_line_and_saves_nothing(rig_bag: Path, tmp_path: Path, run_cli) -> None:
    bag, saved = tmp_path / "bomb.mcap", tmp_path / "take.rrd"
    write_bomb_bag(rig_bag, bag, "/joint_states", "zstd", 1 << 30)
    (tmp_path / "rig.urdf").write_text(RIG_URDF, encoding="utf-8")
    config = write_config(
        tmp_path,
        "live",
        {
            "version": 1,
            "sources": {"js": {"mcap": "bomb.mcap", "topic": "/joint_states", "names": ["shoulder"]}},
            "robots": {"rig": {"urdf": "rig.urdf", "joints": {"source": "js", "unit": "rad", "map": {"shoulder": "shoulder"}}}},
            "output": {"path": "out/{segment}.rrd", "application_id": "bomb", "segment": "live"},
        },
    )
    result = run_cli("live", str(config), "--from", str(bag), "--save", str(saved))
    assert result.code == 1, result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error: ")]
    assert len(errors) == 1 and f"MCAP file {bag}, byte " in errors[0] and "beyond the 16 MiB a chunk may hold" in errors[0], result.err
    assert "Traceback" not in result.err
    assert {p.name for p in tmp_path.iterdir()} == {"bomb.mcap", "rig.urdf", "live.yaml"}


def test_a_followed_file_inflates_in_proportion_to_its_bytes(rig_bag: Path, tmp_path: Path) -> None:
    """Chunks of 1 KB that each inflate to 16 MiB of zeros, within the bound one by one: refused once the reading has
    inflated 256 MiB plus 1000 times the compressed bytes read."""
    path = tmp_path / "run.mcap"
    write_bomb_bag(rig_bag, path, "/joint_states", "zstd", 16 << 20, count=40, before=12)
    with pytest.raises(UserError) as raised:
        follow(McapFollowFeed(path, {"/joint_states": None}))
    assert raised.value.message.startswith(f"MCAP file {path}, byte ")
    assert "more than 1000 times their size beyond the first 256 MiB: a decompression bomb" in raised.value.message


def test_one_step_gives_one_big_chunk_at_most(rig_bag: Path, tmp_path: Path) -> None:
    """Three chunks of 16 MiB each, fed at once: one step gives the first's messages and says a backlog waits; the
    next steps (no new bytes) give the others, each once, in order."""
    from mcap.records import Message

    path = tmp_path / "run.mcap"
    write_bomb_bag(rig_bag, path, "/joint_states", "zstd", 16 << 20, count=3, before=12)
    splitter = RecordSplitter("run.mcap", None)
    big: list[int] = []
    records = splitter.feed(path.read_bytes())
    while True:
        big.append(sum(1 for _, record in records if isinstance(record, Message) and len(record.data) > 1 << 20))
        if not splitter.backlog:
            break
        records = splitter.feed(b"")
    assert big[:3] == [1, 1, 1] and sum(big) == 3 and splitter.footer
