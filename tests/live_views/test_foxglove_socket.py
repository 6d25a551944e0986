"""The WebSocket client against hostile servers built here on raw sockets (raw_server.py): every wait has a deadline
and every read a size bound, whatever the server does; the feed gives up on a connection with one line and reconnects
as documented (bounded), or refuses a server that is no Foxglove server, naming it."""

from __future__ import annotations

import contextlib
import datetime
import ipaddress
import json
import logging
import socket
import ssl
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives import hashes, serialization
from cryptography.hazmat.primitives.asymmetric import ec
from cryptography.x509.oid import NameOID
from mcap_ros2._dynamic import serialize_dynamic

from urdf_pipeline.errors import UserError, has_control_character
from urdf_pipeline.examples import JOINT_STATE_MSGDEF
from urdf_pipeline.live_views import FoxgloveFeed, foxglove_socket
from urdf_pipeline.live_views.foxglove_protocol import MAX_FRAME_BYTES, MAX_TEXT_BYTES

from .joint_motion import message
from .raw_server import JOINT_STATE, Peer, frame, message_data, raw_server
from .test_foxglove_feed import WHERE, at_least, collect, lines

HANG_GUARD = 30.0  # no test asserts how fast; this only keeps a broken client from hanging the suite
GB8 = 8 * 1024**3


def refused(url: str, reconnects: int = 0) -> UserError:
    with pytest.raises(UserError) as error:
        collect(FoxgloveFeed(url, {"/joint_states": WHERE}, reconnects=reconnects).batches(), at_least(1))
    assert not has_control_character(error.value.message)
    return error.value


def endless_headers(peer: Peer) -> None:
    peer.request()
    peer.send(b"HTTP/1.1 101 Switching Protocols\r\n")
    for k in range(10**9):
        peer.send(f"X-Header-{k}: {'v' * 50}\r\n".encode())


def endless_line(peer: Peer) -> None:
    peer.request()
    peer.send(b"HTTP/1.1 101 Switching Protocols\r\nX-Long: ")
    while True:
        peer.send(b"a" * 65536)


def redirect(peer: Peer) -> None:
    peer.request()
    peer.send(b"HTTP/1.1 301 Moved Permanently\r\nLocation: ws://elsewhere.example/\r\nContent-Length: 0\r\n\r\n")


def small_error_body(peer: Peer) -> None:
    peer.request()
    peer.send(b"HTTP/1.1 500 Oops\r\nContent-Length: 4\r\n\r\noops")


def huge_error_body(peer: Peer) -> None:
    peer.request()
    peer.send(f"HTTP/1.1 500 Oops\r\nContent-Length: {GB8}\r\n\r\n".encode())
    while True:
        peer.send(b"x" * 65536)


@pytest.mark.parametrize(
    ("behaviour", "says"),
    [
        (endless_headers, "it answered the WebSocket handshake beyond the client's bounds (too many headers,"),
        (endless_line, "it answered the WebSocket handshake beyond the client's bounds (too many headers, a line too long"),
        (
            huge_error_body,
            "it answered the WebSocket handshake beyond the client's bounds (too many headers, a line too long or a body too large);",
        ),
        (small_error_body, "it answered the WebSocket handshake with HTTP 500 Oops;"),
        (redirect, "it answered the WebSocket handshake with HTTP 301 Moved Permanently;"),  # not followed
    ],
)
def test_a_handshake_answer_is_read_only_as_far_as_its_bound(
    behaviour: Callable[[Peer], None], says: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(foxglove_socket, "CONNECT_SECONDS", 1.0)  # the library refuses at the handshake's deadline: 5 s
    with raw_server(behaviour) as server:
        error = refused(server.url)
    assert error.message.startswith(f"{server.url} is not a Foxglove WebSocket server:") and says in error.message, error.message
    assert "foxglove_bridge" in error.message


def wrong_accept(peer: Peer) -> None:
    peer.request()
    peer.send(b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Accept: x\r\n\r\n")


def no_subprotocol(peer: Peer) -> None:
    peer.upgrade(protocol="chat")


def control_character(peer: Peer) -> None:
    peer.upgrade(protocol="chat\x1b[31m")


@pytest.mark.parametrize(
    ("behaviour", "says"),
    [
        (wrong_accept, "did not complete the WebSocket upgrade as RFC 6455 says"),
        (no_subprotocol, "did not accept the Foxglove WebSocket subprotocol (foxglove.sdk.v1 or foxglove.websocket.v1)"),
        (control_character, "answered the WebSocket handshake with something other than HTTP/1.1"),
    ],
)
def test_an_upgrade_that_is_not_foxgloves_is_refused(behaviour: Callable[[Peer], None], says: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(foxglove_socket, "CONNECT_SECONDS", 1.0)  # a malformed answer is refused at the handshake's deadline
    with raw_server(behaviour) as server:
        assert says in refused(server.url).message


def trickled_handshake(peer: Peer) -> None:
    peer.request()
    for byte in b"HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\n" * 100:
        peer.send(bytes([byte]))
        peer.wait(0.05)


def test_a_trickled_handshake_is_given_up_and_retried(caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(foxglove_socket, "CONNECT_SECONDS", 0.5)
    with raw_server(trickled_handshake) as server:
        error = refused(server.url, reconnects=1)
    assert error.message.startswith(f"cannot reach {server.url} (no WebSocket handshake within 0.5 s) in 2 attempts;")
    assert lines(caplog) == [
        f"urdf-pipeline: live: cannot reach {server.url} (no WebSocket handshake within 0.5 s); trying again in 0.25 s (1 of 1)"
    ]
    assert server.connections == 2


def trickled_frame(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    for byte in message_data(1, 5, b"\x00\x01\x00\x00" + bytes(200)):
        peer.send(bytes([byte]))
        peer.wait(0.1)


def test_a_message_trickled_a_byte_at_a_time_is_given_up_and_retried(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A frame on its way blocks the answer to a ping: the connection falls silent, and is lost."""
    monkeypatch.setattr(foxglove_socket, "PING_AFTER_SECONDS", 0.2)
    monkeypatch.setattr(foxglove_socket, "SILENT_SECONDS", 1.0)
    with raw_server(trickled_frame) as server:
        error = refused(server.url, reconnects=1)
    reason = "no frame, and no answer to pings, for 1 s"
    assert error.message.startswith(f"lost {server.url} after 1 reconnect: {reason};"), error.message
    assert lines(caplog)[0] == f"urdf-pipeline: live: lost {server.url} ({reason}); reconnecting in 0.25 s (1 of 1)"
    assert server.connections == 2


def endless_empty_fragments(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    peer.send(frame(2, b"\x01", fin=False))
    while True:
        peer.send(frame(0, b"", fin=False) * 1000)


def fragments_beyond_the_bound(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    peer.send(frame(2, b"\x01" * 1024 * 1024, fin=False))
    while True:
        peer.send(frame(0, b"\x00" * 1024 * 1024, fin=False))


def huge_ping(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(9, b"", length=GB8))
    while True:
        peer.send(b"p" * 65536)


def long_ping(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(9, b"p" * 126))


def fragmented_ping(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(9, b"ping", fin=False))


def huge_text(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(1, b"", length=GB8))


def large_text(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(1, b" " * (MAX_TEXT_BYTES + 1)))


def not_utf8(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(1, b"{\xff}"))


def masked_frame(peer: Peer) -> None:
    peer.upgrade()
    peer.send(b"\x81\x84abcd" + b"{}{}")


def unknown_opcode(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(3, b"?"))


def deep_json(peer: Peer) -> None:
    peer.upgrade()
    peer.send(frame(1, b"[" * 1_000_000))


@pytest.mark.parametrize(
    ("behaviour", "says"),
    [
        (endless_empty_fragments, "sent a malformed WebSocket frame (a message in more frames than the client takes)"),
        (fragments_beyond_the_bound, f"sent a message of {MAX_FRAME_BYTES + 1024 * 1024:,} bytes (at most {MAX_FRAME_BYTES:,})"),
        (huge_ping, f"sent a message of {GB8:,} bytes (at most {MAX_FRAME_BYTES:,})"),
        (long_ping, "sent a malformed WebSocket frame (a control frame over 125 bytes (at most 125, whole))"),
        (fragmented_ping, "sent a malformed WebSocket frame (a control frame fragmented (at most 125 bytes, whole))"),
        (huge_text, f"sent a message of {GB8:,} bytes (at most {MAX_FRAME_BYTES:,})"),
        (large_text, f"sent a text message of {MAX_TEXT_BYTES + 1:,} bytes (at most {MAX_TEXT_BYTES:,})"),
        (not_utf8, "sent a malformed WebSocket frame (text that is not UTF-8)"),
        (masked_frame, "a frame with reserved bits set or a mask"),
        (unknown_opcode, "a frame of an opcode WebSocket does not define"),
        (deep_json, "does not speak the Foxglove WebSocket protocol: it sent a text frame of JSON nested too deep"),
    ],
)
def test_a_frame_beyond_its_bounds_is_refused_from_its_header(behaviour: Callable[[Peer], None], says: str) -> None:
    with raw_server(behaviour) as server:
        error = refused(server.url, reconnects=3)
    assert error.message.startswith(server.url) and says in error.message, error.message
    assert server.connections == 1  # refused: no reconnect would mend it


def _consuming(feed: FoxgloveFeed) -> tuple[threading.Thread, threading.Event, list[BaseException]]:
    """The feed's batches read on a thread; the event is set when they end (errors: what they raised)."""
    ended, errors = threading.Event(), []

    def consume() -> None:
        try:
            for _ in feed.batches():
                pass
        except BaseException as exc:  # handed to the test
            errors.append(exc)
        ended.set()

    thread = threading.Thread(target=consume, daemon=True)
    thread.start()
    return thread, ended, errors


def _closed_while_waiting(url: str, connections: Callable[[], int]) -> None:
    """A feed of `url` read on a thread, closed from this one once the client waits on the server (connected, then
    0.5 s): its batches() must end within HANG_GUARD, raising nothing."""
    feed = FoxgloveFeed(url, {"/joint_states": WHERE})
    _, ended, errors = _consuming(feed)
    deadline = time.monotonic() + HANG_GUARD
    while connections() == 0:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    time.sleep(0.5)  # the client is waiting on the server now
    feed.close()
    assert ended.wait(HANG_GUARD) and not errors


def stalled_mid_frame(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    peer.send(message_data(1, 5, bytes(100))[:20])  # a frame begun, never ended


def silent_after_upgrade(peer: Peer) -> None:
    peer.request()  # the upgrade is never answered


def no_answer_at_all(peer: Peer) -> None:
    pass


@pytest.mark.parametrize("behaviour", [stalled_mid_frame, silent_after_upgrade, no_answer_at_all])
def test_close_ends_a_feed_whatever_the_server_does(behaviour: Callable[[Peer], None]) -> None:
    """close() from another thread ends batches() under way at once: a read in the middle of a frame, a handshake
    without an answer (the test measures nothing; the report's figures are by hand)."""
    with raw_server(behaviour) as server:
        _closed_while_waiting(server.url, lambda: server.connections)
    assert server.connections == 1


def serve_then_close(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    encode = serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE]
    for k in range(3):
        peer.send(frame(9, b"hi"))  # a ping between messages: answered, not a sample
        peer.send(message_data(1, k, encode(message(k, ["a", "b"], 1_000_000))))
    peer.send(frame(8, b"\x03\xe8bye\x1b"))


def test_pings_are_answered_and_a_close_frame_is_a_lost_connection(caplog: pytest.LogCaptureFixture) -> None:
    with raw_server(serve_then_close) as server:
        feed = FoxgloveFeed(server.url, {"/joint_states": WHERE}, reconnects=0)
        batches = feed.batches()
        samples = collect(batches, at_least(3))  # those before the close frame, whole
        assert [s.log_time_ns for s in samples] == [0, 1, 2]
        with pytest.raises(UserError) as error:
            collect(batches, at_least(1))
    assert error.value.message.startswith(f"lost {server.url} after 0 reconnects: the server closed the connection: 1000 bye\\x1b;")


def test_the_subscribe_message_is_sent_as_a_client_frame() -> None:
    got: list[dict[str, object]] = []

    def record(peer: Peer) -> None:
        peer.upgrade()
        got.append(peer.subscribed())

    with raw_server(record) as server:
        feed = FoxgloveFeed(server.url, {"joint_states": WHERE})
        batches = feed.batches()
        deadline = time.monotonic() + HANG_GUARD
        while not got:
            next(batches)
            assert time.monotonic() < deadline
        feed.close()
    assert got == [json.loads('{"op": "subscribe", "subscriptions": [{"id": 1, "channelId": 1}]}')]


@pytest.fixture(autouse=True)
def _info_lines(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger="urdf_pipeline")


def three_then_a_stalled_frame(peer: Peer) -> None:
    peer.upgrade()
    peer.subscribed()
    encode = serialize_dynamic(JOINT_STATE, JOINT_STATE_MSGDEF)[JOINT_STATE]
    frames = b"".join(message_data(1, k, encode(message(k, ["a", "b"], 1_000_000))) for k in range(3))
    peer.send(frames + message_data(1, 9, bytes(100))[:30])  # in one write: three whole messages, then half a frame


def test_samples_before_a_stalled_frame_are_given_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """A drain reads on only while a whole message is here: the three samples are not held for the half frame after
    them (which would take SILENT_SECONDS, set here beyond the test's own guard)."""
    monkeypatch.setattr(foxglove_socket, "SILENT_SECONDS", 10 * HANG_GUARD)
    with raw_server(three_then_a_stalled_frame) as server:
        feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
        batches = feed.batches()
        taken: list[int] = []
        thread = threading.Thread(target=lambda: taken.extend(s.log_time_ns for s in collect(batches, at_least(3))), daemon=True)
        thread.start()
        thread.join(HANG_GUARD)
        before_close = list(taken)  # close() would hand over held samples too: what came before it is what counts
        feed.close()
    assert before_close == [0, 1, 2]


def endless_channels(peer: Peer) -> None:
    """Advertisements without end: other topics, and channels of the wanted topic under new ids."""
    peer.upgrade()
    peer.send(frame(1, json.dumps({"op": "serverInfo", "name": "hostile", "capabilities": []}).encode()))
    for k in range(10**6):
        others = [{"id": 10**6 + 100 * k + j, "topic": f"/other_{k}_{j}", "encoding": "cdr", "schemaName": "x"} for j in range(100)]
        wanted = {"id": k + 1, "topic": "/joint_states", "encoding": "cdr", "schemaName": JOINT_STATE, "schema": JOINT_STATE_MSGDEF}
        peer.send(frame(1, json.dumps({"op": "advertise", "channels": [*others, wanted]}).encode()))


def test_endless_advertisements_are_bounded() -> None:
    with raw_server(endless_channels) as server:
        error = refused(server.url, reconnects=3)
    assert error.message.startswith(f"{server.url} advertised more than 64 channels of '/joint_states';"), error.message
    assert server.connections == 1


def test_close_ends_a_connect_under_way() -> None:
    """A listener whose backlog is full drops the client's SYNs, as a host that is switched off does: the TCP connect
    waits, and close() ends it (not CONNECT_SECONDS later)."""
    with socket.socket() as listener:
        listener.bind(("127.0.0.1", 0))
        listener.listen(0)
        fillers = [socket.socket() for _ in range(3)]
        for filler in fillers:
            filler.settimeout(0.5)
            with contextlib.suppress(OSError):
                filler.connect(listener.getsockname())
        feed = FoxgloveFeed(f"ws://127.0.0.1:{listener.getsockname()[1]}", {"/joint_states": WHERE})
        thread, ended, errors = _consuming(feed)
        assert not ended.wait(1.0)  # still connecting
        feed.close()
        assert ended.wait(HANG_GUARD) and not errors
        for filler in fillers:
            filler.close()


def _certificate(folder: Path) -> tuple[Path, Path]:
    """A self-signed certificate for 127.0.0.1, made here (certificate and key files)."""
    key = ec.generate_private_key(ec.SECP256R1())
    name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "127.0.0.1")])
    now = datetime.datetime.now(datetime.UTC)
    certificate = (
        x509.CertificateBuilder()
        .subject_name(name)
        .issuer_name(name)
        .public_key(key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]), critical=False)
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .sign(key, hashes.SHA256())
    )
    cert_file, key_file = folder / "server.pem", folder / "server.key"
    cert_file.write_bytes(certificate.public_bytes(serialization.Encoding.PEM))
    key_file.write_bytes(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8, serialization.NoEncryption()))
    return cert_file, key_file


def _tls(tmp_path: Path) -> tuple[ssl.SSLContext, Path]:
    cert_file, key_file = _certificate(tmp_path)
    context = ssl.SSLContext(ssl.PROTOCOL_TLS_SERVER)
    context.load_cert_chain(cert_file, key_file)
    return context, cert_file


def test_a_wss_server_is_read_over_tls(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """wss://: TLS with the system's certificate authorities (here the test's own, through SSL_CERT_FILE, which
    OpenSSL reads), then the same protocol: the samples before the server's close frame are given whole."""
    context, cert_file = _tls(tmp_path)
    monkeypatch.setenv("SSL_CERT_FILE", str(cert_file))
    with raw_server(serve_then_close, tls=context) as server:
        assert server.url.startswith("wss://")
        batches = FoxgloveFeed(server.url, {"/joint_states": WHERE}, reconnects=0).batches()
        assert [s.log_time_ns for s in collect(batches, at_least(3))] == [0, 1, 2]
        with pytest.raises(UserError) as error:
            collect(batches, at_least(1))
    assert error.value.message.startswith(f"lost {server.url} after 0 reconnects: the server closed the connection: 1000 bye\\x1b;")


def test_a_wss_server_with_an_untrusted_certificate_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    context, _ = _tls(tmp_path)
    monkeypatch.setenv("SSL_CERT_FILE", str(tmp_path / "none.pem"))  # no authority trusts the server's certificate
    with raw_server(serve_then_close, tls=context) as server:
        error = refused(server.url, reconnects=3)
    assert (
        error.message.startswith(f"{server.url}: the TLS connection failed (")
        and "needs a certificate this machine trusts" in error.message
    )
    assert server.connections == 1


def test_close_ends_a_wss_read_under_way(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """close() from another thread ends a read over TLS too (the library's TLS socket wraps the one we shut down)."""
    context, cert_file = _tls(tmp_path)
    monkeypatch.setenv("SSL_CERT_FILE", str(cert_file))
    with raw_server(stalled_mid_frame, tls=context) as server:
        _closed_while_waiting(server.url, lambda: server.connections)
    assert server.connections == 1


def pings_never_reading(peer: Peer) -> None:
    """Pings without end, and never a read of the client's pongs: the client's sends stall (its buffer full)."""
    peer.upgrade()
    peer.subscribed()
    peer.sock.settimeout(None)  # its own sends wait as long as the client reads
    while True:
        peer.send(frame(9, b"x" * 125) * 100)


def test_a_server_that_reads_nothing_is_given_up() -> None:
    """The library's sends (its pongs, our pings) have no deadline of their own: the socket's send timeout is one."""
    with raw_server(pings_never_reading) as server:
        error = refused(server.url)
    reason = f"sending timed out after {foxglove_socket.SEND_SECONDS:g} s"
    assert error.message.startswith(f"lost {server.url} after 0 reconnects: {reason};"), error.message


def test_close_ends_a_feed_whose_sends_are_stalled() -> None:
    with raw_server(pings_never_reading) as server:
        feed = FoxgloveFeed(server.url, {"/joint_states": WHERE})
        _, ended, errors = _consuming(feed)
        time.sleep(1.5)  # the client's sends are stalled now (its buffer full)
        feed.close()
        assert ended.wait(HANG_GUARD) and not errors
