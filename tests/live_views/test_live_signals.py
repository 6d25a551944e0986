"""SIGTERM and Ctrl-C end `urdf-pipeline live` whatever its feed is doing (a server stalled in the middle of a frame, a
trickling server, a reconnect's backoff, the first message never arriving, a followed file with no new data): the
process is gone promptly, with no traceback and no raw errno message, and `--save` holds every sample sent (a complete
recording) or, when none was, no file at all. The hostile servers are raw sockets in a thread of the test
(raw_server.py); `live` runs as a child process, as a person runs it."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from mcap_ros2._dynamic import serialize_dynamic

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

from ..rrd_frames import read_frames
from .joint_motion import message, stamp_ns
from .raw_server import JOINT_STATE, Gone, Peer, frame, message_data, raw_server
from .test_live_command import UR5_JOINTS, LiveChild, live_config, ws_config

HANG_GUARD = 10.0  # the bound is 2 s (measured by hand, see the report); this only keeps a hang from lasting
PERIOD_NS = 10_000_000
SENT = 10  # messages each server sends before it misbehaves

# The exit status every command has after Ctrl-C and SIGTERM (docs/security.md's table; errors.ExitCode.for_signal).
EXIT_STATUS = {signal.SIGINT: 130, signal.SIGTERM: 143}


def _encode() -> Callable[[dict[str, object]], bytes]:
    encode = serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE]
    return lambda fields: bytes(encode(fields))


def _publish(peer: Peer) -> None:
    """The handshake, then SENT messages of the UR5's joints (joint_motion's motion), as a Foxglove server sends them."""
    peer.upgrade()
    subscription = peer.subscribed()["subscriptions"][0]["id"]
    encode = _encode()
    for k in range(SENT):
        peer.send(message_data(subscription, stamp_ns(k, PERIOD_NS), encode(message(k, UR5_JOINTS, PERIOD_NS))))


def stalled_mid_frame(peer: Peer) -> None:
    _publish(peer)
    peer.send(message_data(1, 0, bytes(500))[:40])  # a frame begun, never ended


def trickling(peer: Peer) -> None:
    _publish(peer)
    for byte in message_data(1, 0, bytes(500)):
        peer.send(bytes([byte]))
        peer.wait(1.0)


def gone_after_its_messages(peer: Peer) -> None:
    """Its messages, then closed: live reconnects with backoff, and each later connection is closed at once."""
    if peer.index == 1:
        _publish(peer)
        peer.send(frame(8, b"\x03\xe8"))
    raise Gone


def never_publishing(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()


def _stop(live: LiveChild, signum: signal.Signals) -> tuple[int, str]:
    """The signal, then the exit status and everything said, the process waited for within HANG_GUARD."""
    assert live.process.stderr is not None
    live.process.send_signal(signum)
    rest = live.process.stderr.read()
    code = live.process.wait(timeout=HANG_GUARD)
    live.process.stderr.close()
    said = "".join(live.lines) + rest
    assert "Traceback" not in said and "Errno" not in said and "internal error" not in said, said
    return code, said


def _wait_for_the_recording(tmp_path: Path, live: LiveChild) -> None:
    """Until the views are made (the partial file of --save exists), and a moment for the samples to be sent."""
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".take.rrd.partial-*")):
        assert time.monotonic() < deadline and live.process.poll() is None
        time.sleep(0.05)
    time.sleep(1.0)


def _sent(said: str) -> int:
    return int(said.split(" sent (")[0].rsplit(", ", 1)[1])


@pytest.mark.parametrize(
    ("behaviour", "signum"),
    [
        (stalled_mid_frame, signal.SIGTERM),
        (stalled_mid_frame, signal.SIGINT),
        (trickling, signal.SIGTERM),
        (gone_after_its_messages, signal.SIGTERM),
    ],
)
def test_a_signal_ends_live_whatever_the_server_does(
    examples_dir: Path, tmp_path: Path, behaviour: Callable[[Peer], None], signum: signal.Signals
) -> None:
    config = ws_config(examples_dir, f"live_signal_{behaviour.__name__}_{signum.name}")
    saved = tmp_path / "take.rrd"
    with raw_server(behaviour) as server:
        live = LiveChild(examples_dir, str(config), "--from", server.url, "--save", str(saved), "--reconnects", "1000")
        _wait_for_the_recording(tmp_path, live)
        if behaviour is gone_after_its_messages:
            live.wait_for("reconnecting in")
        code, said = _stop(live, signum)
    assert code == EXIT_STATUS[signum], said
    stopped = "stopped by Ctrl-C" if signum == signal.SIGINT else "stopped by SIGTERM"
    assert f"({stopped})" in said and f"saved {saved}" in said, said
    sent = _sent(said)
    assert sent == SENT  # every message before the stall, the trickle or the close
    assert len(read_frames(saved, "ros2_timestamp").temporal["shoulder_link"]) == sent  # complete: reads to its end
    assert {p.name for p in tmp_path.iterdir()} == {"take.rrd"}


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_before_the_first_message_saves_nothing(examples_dir: Path, tmp_path: Path, signum: signal.Signals) -> None:
    config = ws_config(examples_dir, f"live_signal_first_{signum.name}")
    saved = tmp_path / "take.rrd"
    with raw_server(never_publishing) as server:
        live = LiveChild(examples_dir, str(config), "--from", server.url, "--save", str(saved))
        live.wait_for(f"from {server.url}")
        deadline = time.monotonic() + 60
        while server.connections == 0:
            assert time.monotonic() < deadline
            time.sleep(0.05)
        time.sleep(0.5)  # subscribed, waiting for a message that never comes
        code, said = _stop(live, signum)
    assert code == EXIT_STATUS[signum], said
    assert "live: 0 samples in" in said and "saved" not in said, said
    assert not list(tmp_path.iterdir())


def test_a_signal_ends_the_follow_of_a_file_with_no_new_data(examples_dir: Path, tmp_path: Path, appender) -> None:
    config = live_config(examples_dir, "live_signal_quiet_file")
    bag, saved = tmp_path / "quiet.mcap", tmp_path / "take.rrd"
    assert appender(bag, "--count", "30", "--no-footer").wait(60) == 0  # the recorder stopped writing, the file open
    live = LiveChild(examples_dir, str(config), "--from", str(bag), "--save", str(saved))
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".take.rrd.partial-*")):
        assert time.monotonic() < deadline and live.process.poll() is None
        time.sleep(0.05)
    time.sleep(1.0)  # the 30 messages are read and sent; then nothing comes
    code, said = _stop(live, signal.SIGTERM)
    assert code == EXIT_STATUS[signal.SIGTERM], said
    assert _sent(said) == 30 and "(stopped by SIGTERM)" in said, said
    assert len(read_frames(saved, "ros2_timestamp").temporal["shoulder_link"]) == 30
    assert {p.name for p in tmp_path.iterdir()} == {"quiet.mcap", "take.rrd"}
