"""FoxgloveFeed against a real Foxglove WebSocket server (foxglove-sdk in a child process, `foxglove_server.py`):
what arrives is recomputed from the published motion (`joint_motion`), and every refusal is a UserError naming the
URL or the topic, strangers' text escaped."""

from __future__ import annotations

import json
import logging
import re
import signal
import struct
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.errors import UserError, Where, has_control_character
from urdf_pipeline.live_views import FoxgloveFeed, JointStateSample, foxglove_socket
from urdf_pipeline.live_views.foxglove_protocol import (
    Advertised,
    ProtocolError,
    advertised,
    message_data,
    server_message,
    subscribe,
    unadvertised,
)

from ..local_processes import free_port, stop
from .conftest import FoxgloveServer, ready_line
from .joint_motion import LOG_DELAY_NS, NAMES, index_of, order, values

WAIT_SECONDS = 60.0  # generous bounds on waits for what must come; no test asserts how fast
RATE = 200  # messages per second
PERIOD_NS = 1_000_000_000 // RATE
WHERE = Where(Path("live.yaml"), 7, "sources.0.topic", 12)

Start = Callable[..., FoxgloveServer]


def collect(batches: Iterator[list[JointStateSample]], done: Callable[[list[JointStateSample]], bool]) -> list[JointStateSample]:
    """The samples of the batches until `done` says enough (within WAIT_SECONDS)."""
    samples: list[JointStateSample] = []
    deadline = time.monotonic() + WAIT_SECONDS
    for batch in batches:
        samples.extend(batch)
        if done(samples):
            return samples
        assert time.monotonic() < deadline, f"{len(samples)} samples came within {WAIT_SECONDS:.0f} s"
    raise AssertionError(f"the feed ended after {len(samples)} samples")


def at_least(count: int) -> Callable[[list[JointStateSample]], bool]:
    return lambda samples: len(samples) >= count


def lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [record.getMessage() for record in caplog.records if record.name == "urdf_pipeline"]


def assert_is_the_motion(sample: JointStateSample, topic: str = "/joint_states") -> int:
    """The sample is message k of the published motion, exactly; returns k."""
    k = index_of(sample.header_ns, PERIOD_NS)
    shuffled = order(k, len(NAMES))
    assert sample.topic == topic
    assert sample.names == tuple(NAMES[i] for i in shuffled)
    np.testing.assert_array_equal(sample.positions, values(k, NAMES)[shuffled])
    assert sample.log_time_ns == sample.publish_time_ns == sample.header_ns + LOG_DELAY_NS
    return k


@pytest.fixture
def said(caplog: pytest.LogCaptureFixture) -> pytest.LogCaptureFixture:
    caplog.set_level(logging.INFO, logger="urdf_pipeline")
    return caplog


def test_samples_are_the_published_messages(foxglove_server: Start) -> None:
    server = foxglove_server("--count", "60", "--rate", str(RATE))
    feed = FoxgloveFeed(server.url, {"joint_states": WHERE})  # no leading slash: matches /joint_states
    batches = feed.batches()
    samples = collect(batches, at_least(60))
    feed.close()
    assert list(batches) in ([], [[]])  # it ends
    assert [assert_is_the_motion(sample, "joint_states") for sample in samples] == list(range(60))
    received = [sample.received_ns for sample in samples]
    assert received == sorted(received)
    assert len({id(sample.names) for sample in samples}) == len({sample.names for sample in samples})  # one tuple per order


def test_a_topic_advertised_later_is_subscribed(foxglove_server: Start, said: pytest.LogCaptureFixture) -> None:
    server = foxglove_server("--count", "5", "--advertise-on-input")
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
    batches = feed.batches()
    collect(batches, lambda _: any("has no topic" in line for line in lines(said)))  # connected, told the user
    assert f"live: {server.url} has no topic '/joint_states' yet (it advertises no topic); waiting for it" in lines(said)[-1]
    server.advertise()
    assert [assert_is_the_motion(sample) for sample in collect(batches, at_least(5))] == list(range(5))
    feed.close()


def test_a_topic_of_another_type_is_refused_naming_it(foxglove_server: Start) -> None:
    server = foxglove_server("--schema-name", "std_msgs/msg/String")
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
    with pytest.raises(UserError) as refused:
        collect(feed.batches(), at_least(1))
    assert refused.value.where == WHERE
    assert "topic '/joint_states' carries std_msgs/msg/String (ros2msg, cdr), not ROS 2 sensor_msgs/msg/JointState" in refused.value.message
    assert server.url in refused.value.message


def test_a_restarted_server_is_reconnected(foxglove_server: Start, said: pytest.LogCaptureFixture) -> None:
    first = foxglove_server("--rate", str(RATE))
    feed = FoxgloveFeed(first.url, {"/joint_states": WHERE}, reconnects=30)
    batches = feed.batches()
    before = collect(batches, at_least(10))
    first.kill()
    foxglove_server("--rate", str(RATE), "--first", "100000", port=first.port)
    after = collect(batches, lambda samples: any(index_of(s.header_ns, PERIOD_NS) >= 100000 for s in samples))
    feed.close()
    ks = [assert_is_the_motion(sample) for sample in before + after]
    assert ks[:10] == list(range(10)) and ks[-1] >= 100000
    said_lines = lines(said)
    lost = [line for line in said_lines if line.startswith(f"urdf-pipeline: live: lost {first.url} (")]
    assert lost and all("; reconnecting in " in line for line in lost), said_lines
    assert lost[0].endswith(" (1 of 30)")
    assert said_lines.count(f"urdf-pipeline: live: reconnected to {first.url}") == 1


def test_a_silent_server_is_taken_for_lost(foxglove_server: Start, said: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    """A server that stops answering without closing (a frozen robot; here SIGSTOP) is pinged, then taken for lost
    and reconnected when it answers again. The silence allowed is shortened for the test."""
    monkeypatch.setattr(foxglove_socket, "PING_AFTER_SECONDS", 0.2)
    monkeypatch.setattr(foxglove_socket, "SILENT_SECONDS", 1.0)
    server = foxglove_server("--rate", str(RATE))
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
    batches = feed.batches()
    collect(batches, at_least(1))
    server.process.send_signal(signal.SIGSTOP)
    try:
        collect(batches, lambda _: any(" lost " in line for line in lines(said)))
    finally:
        server.process.send_signal(signal.SIGCONT)
    assert (
        lines(said)[0]
        == f"urdf-pipeline: live: lost {server.url} (no frame, and no answer to pings, for 1 s); reconnecting in 0.25 s (1 of 10)"
    )
    collect(batches, lambda samples: bool(samples) and any("reconnected" in line for line in lines(said)))
    feed.close()


def test_reconnects_used_up_raise_naming_the_url(foxglove_server: Start, said: pytest.LogCaptureFixture) -> None:
    server = foxglove_server("--rate", str(RATE))
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE}, reconnects=2)
    batches = feed.batches()
    collect(batches, at_least(1))
    server.kill()
    with pytest.raises(UserError) as refused:
        collect(batches, lambda _: False)
    assert refused.value.message.startswith(f"lost {server.url} after 2 reconnects: connection refused;")
    assert [line.split(";")[-1] for line in lines(said)] == [" reconnecting in 0.25 s (1 of 2)", " reconnecting in 0.5 s (2 of 2)"]


def test_nobody_there_is_refused_after_the_retries(said: pytest.LogCaptureFixture) -> None:
    url = f"ws://127.0.0.1:{free_port()}"
    with pytest.raises(UserError) as refused:
        collect(FoxgloveFeed(url, {"/joint_states": WHERE}, reconnects=1).batches(), at_least(1))
    assert refused.value.message.startswith(f"cannot reach {url} (connection refused) in 2 attempts;")
    assert lines(said) == [f"urdf-pipeline: live: cannot reach {url} (connection refused); trying again in 0.25 s (1 of 1)"]


def _consume_in_a_thread(feed: FoxgloveFeed) -> tuple[threading.Thread, threading.Event, list[BaseException]]:
    """Iterates the feed's batches on a thread; the event is set at its first sample."""
    first, errors = threading.Event(), []

    def consume() -> None:
        try:
            for batch in feed.batches():
                if batch:
                    first.set()
        except BaseException as exc:  # handed to the test
            errors.append(exc)

    thread = threading.Thread(target=consume, daemon=True)
    thread.start()
    return thread, first, errors


def test_close_from_another_thread_ends_batches(foxglove_server: Start) -> None:
    server = foxglove_server("--rate", str(RATE))
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
    thread, first, errors = _consume_in_a_thread(feed)
    assert first.wait(WAIT_SECONDS)
    feed.close()
    thread.join(WAIT_SECONDS)
    assert not thread.is_alive() and not errors


def test_close_ends_batches_waiting_to_reconnect() -> None:
    feed = FoxgloveFeed(f"ws://127.0.0.1:{free_port()}", {"/joint_states": WHERE}, reconnects=1000)
    thread, _, errors = _consume_in_a_thread(feed)
    feed.close()
    thread.join(WAIT_SECONDS)
    assert not thread.is_alive() and not errors


def test_a_plain_http_server_is_refused() -> None:
    port = free_port()
    process = subprocess.Popen(
        [sys.executable, "-u", "-m", "http.server", "--bind", "127.0.0.1", str(port)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL
    )
    try:
        assert ready_line(process).startswith("Serving HTTP")
        with pytest.raises(UserError) as refused:
            collect(FoxgloveFeed(f"ws://127.0.0.1:{port}", {"/joint_states": WHERE}).batches(), at_least(1))
    finally:
        stop(process)
        assert process.stdout is not None
        process.stdout.close()
    assert refused.value.message.startswith(
        f"ws://127.0.0.1:{port} is not a Foxglove WebSocket server: it answered the WebSocket handshake with something other than HTTP/1.1;"
    )
    assert "foxglove_bridge" in refused.value.message


@pytest.mark.parametrize(
    "url", ["http://127.0.0.1:8765", "127.0.0.1:8765", "ws://", "ws://robot:99999", "ws://ro\nbot:8765", "ws://robot :1"]
)
def test_a_url_that_is_no_websocket_url_is_refused(url: str) -> None:
    with pytest.raises(UserError, match="is not a WebSocket URL") as refused:
        FoxgloveFeed(url, {"/joint_states": WHERE})
    assert not has_control_character(refused.value.message)


def test_a_wss_url_is_taken() -> None:
    assert FoxgloveFeed("wss://robot.example:8765/", {"/joint_states": None}).description == "wss://robot.example:8765/"


def test_an_unreadable_message_is_refused_naming_the_topic(foxglove_server: Start) -> None:
    server = foxglove_server("--garbage-bytes", "7", "--count", "1")
    with pytest.raises(UserError) as refused:
        collect(FoxgloveFeed(server.url, {"/joint_states": WHERE}).batches(), at_least(1))
    assert refused.value.where == WHERE
    assert refused.value.message.startswith("a message on '/joint_states' is not a readable sensor_msgs/msg/JointState")
    assert refused.value.message.endswith(f"(from {server.url})")


def test_a_message_too_large_is_refused_before_it_is_read(foxglove_server: Start) -> None:
    server = foxglove_server("--garbage-bytes", str(17 * 1024 * 1024), "--count", "1")
    with pytest.raises(UserError) as refused:
        collect(FoxgloveFeed(server.url, {"/joint_states": WHERE}).batches(), at_least(1))
    size = 17 * 1024 * 1024 + 13  # the payload and the message-data header
    assert refused.value.message.startswith(f"{server.url} sent a message of {size:,} bytes (at most 16,777,216)")


HOSTILE_TOPIC = "/joint\x1b[31m_states\u202e\n"
HOSTILE_SCHEMA = "evil\x07\nschema"


def test_hostile_topic_and_schema_names_are_escaped(foxglove_server: Start, said: pytest.LogCaptureFixture) -> None:
    server = foxglove_server("--topic", HOSTILE_TOPIC, "--schema-name", HOSTILE_SCHEMA)
    with pytest.raises(UserError) as refused:
        collect(FoxgloveFeed(server.url, {HOSTILE_TOPIC: WHERE}).batches(), at_least(1))
    assert "topic '/joint\\x1b[31m_states\\u202e\\n' carries evil\\x07\\nschema (ros2msg, cdr)" in refused.value.message
    assert not has_control_character(refused.value.message)
    feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})  # another topic wanted: the note names the hostile one
    collect(feed.batches(), lambda _: any("has no topic" in line for line in lines(said)))
    feed.close()
    note = next(line for line in lines(said) if "has no topic" in line)
    assert "(it has '/joint\\x1b[31m_states\\u202e\\n')" in note and not has_control_character(note)


# The protocol's frames read strictly (what no Foxglove server sends is refused; the feed words it with the URL).


@pytest.mark.parametrize(
    ("frame", "says"),
    [
        (b"not json", "a text frame that is not JSON"),
        (b"\xff\xfe", "a text frame that is not JSON"),
        (b"[1, 2]", "not an object with an 'op'"),
        (b'{"op": 7}', "not an object with an 'op'"),
    ],
)
def test_a_json_frame_must_be_an_object_with_an_op(frame: bytes, says: str) -> None:
    with pytest.raises(ProtocolError, match=re.escape(says)):
        server_message(frame)


@pytest.mark.parametrize(
    ("channels", "says"),
    [
        (None, "without a list of channels"),
        ([1], "not an object"),
        ([{"id": -1, "topic": "/a", "encoding": "cdr", "schemaName": "x"}], "not a 32-bit unsigned integer"),
        ([{"id": True, "topic": "/a", "encoding": "cdr", "schemaName": "x"}], "not a 32-bit unsigned integer"),
        ([{"id": 1, "topic": 5, "encoding": "cdr", "schemaName": "x"}], "'topic' is not a string"),
        ([{"id": 1, "topic": "/a", "schemaName": "x"}], "'encoding' is not a string"),
    ],
)
def test_an_advertise_without_its_fields_is_refused(channels: object, says: str) -> None:
    with pytest.raises(ProtocolError, match=re.escape(says)):
        advertised({"op": "advertise", "channels": channels})


def test_an_advertise_without_schema_encoding_means_ros2msg_for_cdr() -> None:
    channel = {"id": 3, "topic": "/js", "encoding": "cdr", "schemaName": "sensor_msgs/msg/JointState", "schema": "x"}
    assert advertised({"op": "advertise", "channels": [channel]}) == [
        Advertised(3, "/js", "cdr", "sensor_msgs/msg/JointState", "ros2msg", "x")
    ]
    assert unadvertised({"op": "unadvertise", "channelIds": [3, 4]}) == [3, 4]
    with pytest.raises(ProtocolError, match="not a 32-bit unsigned integer"):
        unadvertised({"op": "unadvertise", "channelIds": [2**32]})


def test_binary_frames() -> None:
    frame = struct.pack("<BIQ", 1, 7, 123456789) + b"payload"
    subscription, timestamp, payload = message_data(frame) or (0, 0, memoryview(b""))
    assert (subscription, timestamp, bytes(payload)) == (7, 123456789, b"payload")
    assert message_data(b"\x02" + bytes(8)) is None  # server time: not ours
    with pytest.raises(ProtocolError, match="empty binary frame"):
        message_data(b"")
    with pytest.raises(ProtocolError, match="a message-data frame of 5 bytes, shorter than its 13-byte header"):
        message_data(b"\x01abcd")
    assert json.loads(subscribe([(1, 9)])) == {"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 9}]}
