"""One WebSocket connection to a Foxglove server, through websocket-client (synchronous: the feed's caller's thread
reads it, no thread of ours): opened offering both Foxglove subprotocols, every wait bounded (connect, handshake,
each receive), each message bounded in size before it is read, and ended from another thread by `goodbye`.

Its failures come in two kinds: `Lost` (refused, closed, reset, silent: the feed reconnects) and `UserError` (no
Foxglove server at that URL, a frame too large or malformed: reconnecting would not help).
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import ssl
import struct
import time
from typing import Any
from urllib.parse import urlsplit

import websocket

from ..errors import UserError, has_control_character, quoted, shown
from .foxglove_protocol import MAX_FRAME_BYTES, SUBPROTOCOLS

CONNECT_SECONDS = 5.0  # TCP connect, the WebSocket handshake, and the server's first message each
PING_AFTER_SECONDS = 2.0  # a connection silent this long is pinged (servers answer pings, foxglove_bridge included)
SILENT_SECONDS = 10.0  # silent this long, pings unanswered: lost (a pulled cable or a frozen robot sends no FIN)
CLOSE_SECONDS = 0.25  # how long a polite close waits for the server's close frame
TEXT, BINARY, CLOSE = websocket.ABNF.OPCODE_TEXT, websocket.ABNF.OPCODE_BINARY, websocket.ABNF.OPCODE_CLOSE
_DATA_OPCODES = (TEXT, BINARY, websocket.ABNF.OPCODE_CONT)
_FIX = "give --from the address of the robot's Foxglove WebSocket server (foxglove_bridge listens on ws://ROBOT:8765)"


class Lost(Exception):
    """The connection failed or ended in a way a reconnect may mend; `reason` is for the line the user reads."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class _TooLarge(Exception):
    def __init__(self, size: int) -> None:
        super().__init__(size)
        self.size = size


class _BoundedFrames(websocket.frame_buffer):
    """websocket-client's frame reader, refusing a message (its fragments summed) longer than MAX_FRAME_BYTES as soon
    as a frame header announces it, before reading its payload."""

    message_bytes = 0

    def recv_length(self) -> None:
        super().recv_length()
        assert self.header is not None and self.length is not None
        opcode = self.header[4]
        if opcode not in _DATA_OPCODES:
            return  # a control frame (ping, pong, close) between fragments: at most 125 bytes, not part of the message
        total = self.length + (self.message_bytes if opcode == websocket.ABNF.OPCODE_CONT else 0)
        if total > MAX_FRAME_BYTES:
            raise _TooLarge(total)
        self.message_bytes = total

    def buffered(self) -> bool:
        """Whether bytes beyond the last frame were read from the socket already."""
        return any(self.recv_buffer)


class _BoundedWebSocket(websocket.WebSocket):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.bounded = _BoundedFrames(self._recv, self.frame_buffer.skip_utf8_validation)
        self.frame_buffer = self.bounded


def check_url(url: str) -> str:
    """The URL as given, when it is a ws:// or wss:// URL with a host (wss: the system's certificate authorities)."""
    try:
        parts = urlsplit(url)
        port_ok = parts.port is None or parts.port > 0
    except ValueError:
        parts, port_ok = urlsplit(""), False
    if parts.scheme not in ("ws", "wss") or not parts.hostname or not port_ok or has_control_character(url) or " " in url:
        raise UserError(f"{quoted(url)} is not a WebSocket URL (ws://HOST:PORT); {_FIX}")
    return url


def _close_reason(data: bytes) -> str:
    if len(data) < 2:
        return "the server closed the connection"
    code = struct.unpack("!H", data[:2])[0]
    text = data[2:].decode("utf-8", "replace")
    return f"the server closed the connection: {code}{' ' + shown(text) if text else ''}"


def _refused_handshake(url: str, exc: websocket.WebSocketException) -> UserError:
    if isinstance(exc, websocket.WebSocketBadStatusException):
        answer = f"answered the WebSocket handshake with HTTP {exc.status_code} {shown(exc.status_message or '')}".rstrip()
    else:
        answer = f"did not accept the Foxglove WebSocket subprotocol ({' or '.join(SUBPROTOCOLS)}: {shown(exc)})"
    return UserError(f"{shown(url)} is not a Foxglove WebSocket server: it {answer}; {_FIX}")


def _open_failure(url: str, exc: Exception) -> Exception:
    """What a failed connect means: Lost (try again later) or UserError (this URL is wrong)."""
    if isinstance(exc, websocket.WebSocketTimeoutException | TimeoutError):
        return Lost(f"no answer within {CONNECT_SECONDS:g} s")
    if isinstance(exc, websocket.WebSocketConnectionClosedException):
        return Lost("connection closed during the handshake")
    if isinstance(exc, websocket.WebSocketAddressException | socket.gaierror):
        return Lost(f"cannot resolve its host: {shown(exc)}")
    if isinstance(exc, websocket.WebSocketProxyException):
        return Lost(f"proxy: {shown(exc)}")
    if isinstance(exc, ssl.SSLError):
        return UserError(f"{shown(url)}: the TLS connection failed ({shown(exc)}); a wss:// server needs a certificate this machine trusts")
    if isinstance(exc, ConnectionRefusedError):
        return Lost("connection refused")
    if isinstance(exc, OSError):
        return Lost(shown(exc.strerror or exc))
    if isinstance(exc, websocket.WebSocketException):
        return _refused_handshake(url, exc)
    return exc


class Connection:
    """An open WebSocket to a Foxglove server. `receive`, `pending`, `send`, `keep_alive` and `close` are called by
    the feed's one reading thread; `goodbye` from any thread."""

    def __init__(self, url: str, socket_: _BoundedWebSocket) -> None:
        self.url = url
        self._ws = socket_
        self._heard = self._pinged = time.monotonic()

    @classmethod
    def open(cls, url: str) -> Connection:
        try:
            opened = websocket.create_connection(url, timeout=CONNECT_SECONDS, subprotocols=list(SUBPROTOCOLS), class_=_BoundedWebSocket)
        except (websocket.WebSocketException, OSError) as exc:
            raise _open_failure(url, exc) from None
        assert isinstance(opened, _BoundedWebSocket)
        return cls(url, opened)

    def receive(self, timeout: float) -> tuple[int, bytes, int] | None:
        """The next data frame: (opcode, bytes, time.monotonic_ns() when it was read), or None when none came within
        `timeout` seconds (or a ping or pong came). A close frame raises Lost."""
        self._ws.settimeout(timeout)
        try:
            opcode, frame = self._ws.recv_data_frame(control_frame=True)
        except websocket.WebSocketTimeoutException:
            return None
        except _TooLarge as exc:
            raise UserError(
                f"{shown(self.url)} sent a message of {exc.size:,} bytes (at most {MAX_FRAME_BYTES:,}); no JointState is that large"
            ) from None
        except (websocket.WebSocketProtocolException, websocket.WebSocketPayloadException) as exc:
            raise UserError(
                f"{shown(self.url)} sent a malformed WebSocket frame ({shown(exc)}); is it a Foxglove WebSocket server?"
            ) from None
        except (websocket.WebSocketException, OSError) as exc:
            raise Lost(_lost_reason(exc)) from None
        received_ns = time.monotonic_ns()
        self._heard = received_ns / 1e9
        if opcode == CLOSE:
            raise Lost(_close_reason(frame.data))
        return (opcode, frame.data, received_ns) if opcode in (TEXT, BINARY) else None

    def pending(self) -> bool:
        """Whether more bytes are here already (read from the socket, or waiting in it): a drain reads on."""
        if self._ws.bounded.buffered():
            return True
        sock = self._ws.sock
        if sock is None:
            return False
        if isinstance(sock, ssl.SSLSocket) and sock.pending():
            return True
        with selectors.DefaultSelector() as selector:
            selector.register(sock, selectors.EVENT_READ)
            return bool(selector.select(0))

    def send(self, text: str) -> None:
        self._ws.settimeout(CONNECT_SECONDS)
        try:
            self._ws.send(text)
        except (websocket.WebSocketException, OSError) as exc:
            raise Lost(_lost_reason(exc)) from None

    def keep_alive(self) -> None:
        """A ping after PING_AFTER_SECONDS of silence; Lost after SILENT_SECONDS of it."""
        now = time.monotonic()
        if now - self._heard > SILENT_SECONDS:
            raise Lost(f"no frame, and no answer to pings, for {SILENT_SECONDS:g} s")
        if now - max(self._heard, self._pinged) > PING_AFTER_SECONDS:
            self._pinged = now
            self._ws.settimeout(CONNECT_SECONDS)
            try:
                self._ws.ping()
            except (websocket.WebSocketException, OSError) as exc:
                raise Lost(_lost_reason(exc)) from None

    def goodbye(self) -> None:
        """From another thread: a close frame, which the server answers with its own before it closes the connection
        (released even when nobody reads it any more); a `receive` under way sees that answer as Lost. (websocket-client
        sends from one thread while another receives, under its lock.)"""
        with contextlib.suppress(websocket.WebSocketException, OSError):
            self._ws.send_close()

    def close(self) -> None:
        """A close frame and a short wait for the server's (a closed or woken connection skips both), then the
        socket closed."""
        with contextlib.suppress(websocket.WebSocketException, OSError):
            self._ws.close(timeout=CLOSE_SECONDS)
        self._ws.shutdown()


def _lost_reason(exc: Exception) -> str:
    if isinstance(exc, websocket.WebSocketConnectionClosedException | ConnectionResetError | BrokenPipeError):
        return "connection closed"
    if isinstance(exc, websocket.WebSocketTimeoutException | TimeoutError):
        return f"sending timed out after {CONNECT_SECONDS:g} s"
    return shown(exc.strerror if isinstance(exc, OSError) and exc.strerror else exc)
