"""One WebSocket connection to a Foxglove server: the client's side of RFC 6455, read by our own code so that every
byte read has a bound. The handshake (TCP connect, the HTTP answer to the upgrade: at most MAX_HEAD_BYTES and
MAX_HEAD_LINES, its body never read) is done within CONNECT_SECONDS overall; every message (its frames, control
frames between them included) within MESSAGE_SECONDS of its first byte, in at most MAX_FRAGMENTS frames, each
frame's size checked from its header before its payload is read. The feed's one thread reads; `goodbye`, from any
thread, ends whatever that thread waits for (a connect, a read, a send) at once.

Its failures come in two kinds: `Lost` (refused, closed, reset, silent, too slow: the feed reconnects) and `UserError`
(no Foxglove server at that URL, a frame too large or malformed: reconnecting would not help).
"""

from __future__ import annotations

import base64
import contextlib
import errno
import hashlib
import os
import re
import selectors
import socket
import ssl
import struct
import threading
import time
from urllib.parse import urlsplit

from ..errors import UserError, has_control_character, quoted, shown
from .foxglove_protocol import MAX_FRAME_BYTES, MAX_TEXT_BYTES, SUBPROTOCOLS

CONNECT_SECONDS = 5.0  # TCP connect and the WebSocket handshake together; the server's first message again
MESSAGE_SECONDS = 10.0  # a message's bytes, from its first to its last (a 16 MiB one needs 13 Mbit/s)
PING_AFTER_SECONDS = 2.0  # a connection silent this long is pinged (servers answer pings, foxglove_bridge included)
SILENT_SECONDS = 10.0  # silent this long, pings unanswered: lost (a pulled cable or a frozen robot sends no FIN)
CLOSE_SECONDS = 0.25  # how long a polite close waits for the server's close frame
STEP_SECONDS = 0.1  # a connect is waited for in steps this long, so `goodbye` ends it
MAX_HEAD_BYTES = 16 * 1024  # the HTTP answer to the upgrade, headers included (a server's is a few hundred bytes)
MAX_HEAD_LINES = 100
MAX_FRAGMENTS = 1024  # frames of one message (servers send one; control frames between them count too)
CONT, TEXT, BINARY, CLOSE, PING, PONG = 0x0, 0x1, 0x2, 0x8, 0x9, 0xA
_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"  # RFC 6455's, for Sec-WebSocket-Accept
_FIX = "give --from the address of the robot's Foxglove WebSocket server (foxglove_bridge listens on ws://ROBOT:8765)"
_STATUS = re.compile(rb"HTTP/1\.[01] (\d{3})(?: (.*))?")


class Lost(Exception):
    """The connection failed or ended in a way a reconnect may mend; `reason` is for the line the user reads."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


class _Late(Exception):
    """A deadline passed (the caller says which)."""


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


def _lost_reason(exc: OSError) -> str:
    if isinstance(exc, ConnectionResetError | BrokenPipeError):
        return "connection closed"
    return shown(exc.strerror or exc)


def _frame(opcode: int, payload: bytes) -> bytes:
    """A client's frame: final, masked (RFC 6455 5.3)."""
    size = len(payload)
    length = bytes([0x80 | size]) if size < 126 else struct.pack("!BH", 0xFE, size) if size < 65536 else struct.pack("!BQ", 0xFF, size)
    mask = os.urandom(4)
    keys = (mask * (size // 4 + 1))[:size]
    masked = (int.from_bytes(payload, "big") ^ int.from_bytes(keys, "big")).to_bytes(size, "big")
    return bytes([0x80 | opcode]) + length + mask + masked


class Connection:
    """A WebSocket to a Foxglove server. `open`, `receive`, `pending`, `send`, `keep_alive` and `close` are called by
    the feed's one reading thread; `goodbye` from any thread."""

    def __init__(self, url: str) -> None:
        self.url = url
        self._parts = urlsplit(url)
        self._sock: socket.socket | None = None
        self._buffer = bytearray()  # bytes read and not yet taken
        self._ended = threading.Event()  # goodbye came
        self._sending = threading.Lock()
        self._heard = self._pinged = time.monotonic()

    # -- the handshake

    def open(self) -> None:
        """TCP, TLS for wss, and the upgrade, all within CONNECT_SECONDS; the subprotocol the server chose is checked."""
        deadline = time.monotonic() + CONNECT_SECONDS
        host, secure = self._parts.hostname or "", self._parts.scheme == "wss"
        port = self._parts.port or (443 if secure else 80)
        try:
            self._connect(host, port, deadline)
            if secure:
                assert self._sock is not None
                self._sock.settimeout(max(deadline - time.monotonic(), 0.01))
                self._sock = ssl.create_default_context().wrap_socket(self._sock, server_hostname=host)
            key = base64.b64encode(os.urandom(16)).decode()
            self._send_raw(self._request(host, port, key).encode())
            head = self._head(deadline)
        except (_Late, OSError) as exc:
            raise self._open_failure(exc) from None
        self._check_head(head, key)
        self._heard = self._pinged = time.monotonic()

    def _open_failure(self, exc: Exception) -> Exception:
        """What a failed open means: Lost (try again later) or UserError (this URL is wrong)."""
        if self._ended.is_set():
            return Lost("closed")
        if isinstance(exc, _Late):
            return Lost(f"no WebSocket handshake within {CONNECT_SECONDS:g} s")
        if isinstance(exc, TimeoutError):  # the TCP connect or the TLS handshake
            return Lost(f"no answer within {CONNECT_SECONDS:g} s")
        if isinstance(exc, ssl.SSLError):
            return UserError(
                f"{shown(self.url)}: the TLS connection failed ({shown(exc)}); a wss:// server needs a certificate this machine trusts"
            )
        if isinstance(exc, socket.gaierror):
            return Lost(f"cannot resolve its host: {shown(exc.strerror or exc)}")
        if isinstance(exc, ConnectionRefusedError):
            return Lost("connection refused")
        assert isinstance(exc, OSError)
        return Lost(_lost_reason(exc))

    def _connect(self, host: str, port: int, deadline: float) -> None:
        """Each of the host's addresses in turn, in steps, so `goodbye` (which sets _ended) ends a connect at once."""
        failure: OSError = ConnectionRefusedError()
        for family, kind, protocol, _, address in socket.getaddrinfo(host, port, type=socket.SOCK_STREAM):
            sock = socket.socket(family, kind, protocol)
            sock.setblocking(False)
            self._sock = sock
            error = sock.connect_ex(address)
            if error not in (0, errno.EINPROGRESS):
                sock.close()
                failure = OSError(error, os.strerror(error))
                continue
            with selectors.DefaultSelector() as selector:
                selector.register(sock, selectors.EVENT_WRITE)
                while not selector.select(min(STEP_SECONDS, max(deadline - time.monotonic(), 0))):
                    if self._ended.is_set():
                        raise Lost("closed")
                    if time.monotonic() >= deadline:
                        raise TimeoutError
            error = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if not error:
                sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                return
            sock.close()
            failure = ConnectionRefusedError() if error == errno.ECONNREFUSED else OSError(error, os.strerror(error))
        raise failure

    def _request(self, host: str, port: int, key: str) -> str:
        resource = (self._parts.path or "/") + (f"?{self._parts.query}" if self._parts.query else "")
        named = f"[{host}]" if ":" in host else host
        default = 443 if self._parts.scheme == "wss" else 80
        return (
            f"GET {resource} HTTP/1.1\r\nHost: {named}{'' if port == default else f':{port}'}\r\nUpgrade: websocket\r\n"
            f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            f"Sec-WebSocket-Protocol: {', '.join(SUBPROTOCOLS)}\r\n\r\n"
        )

    def _head(self, deadline: float) -> bytes:
        """The answer's status line and headers; what follows them (the server's first frames) stays buffered."""
        searched = 0
        while (end := self._buffer.find(b"\r\n\r\n", max(searched - 3, 0))) < 0:
            searched = len(self._buffer)
            if searched > MAX_HEAD_BYTES or self._buffer.count(b"\n") > MAX_HEAD_LINES:
                raise UserError(
                    f"{shown(self.url)} is not a Foxglove WebSocket server: its answer to the WebSocket handshake has no end "
                    f"within {MAX_HEAD_BYTES:,} bytes and {MAX_HEAD_LINES} lines; {_FIX}"
                )
            self._fill(deadline, "connection closed during the handshake")
        head = bytes(self._buffer[:end])
        del self._buffer[: end + 4]
        return head

    def _check_head(self, head: bytes, key: str) -> None:
        lines = head.split(b"\r\n")
        status = _STATUS.fullmatch(lines[0])
        if status is None:
            raise self._refused("answered the WebSocket handshake with something other than HTTP")
        if status[1] != b"101":
            reason = (status[2] or b"").decode("latin-1")
            raise self._refused(f"answered the WebSocket handshake with HTTP {status[1].decode()} {shown(reason)}".rstrip())
        headers: dict[str, str] = {}
        for line in lines[1:]:
            name, colon, value = line.decode("latin-1").partition(":")
            if not colon:
                raise self._refused("answered the WebSocket handshake with a header line without a ':'")
            headers[name.strip().lower()] = value.strip()
        accept = base64.b64encode(hashlib.sha1(key.encode() + _GUID).digest()).decode()
        upgrade = headers.get("upgrade", "").lower() == "websocket" and "upgrade" in headers.get("connection", "").lower()
        if not upgrade or headers.get("sec-websocket-accept") != accept or "sec-websocket-extensions" in headers:
            raise self._refused("did not complete the WebSocket upgrade as RFC 6455 says")
        chosen = headers.get("sec-websocket-protocol")
        if chosen not in SUBPROTOCOLS:
            raise self._refused(
                f"did not accept the Foxglove WebSocket subprotocol ({' or '.join(SUBPROTOCOLS)}; it chose {quoted(chosen)})"
            )

    def _refused(self, answer: str) -> UserError:
        return UserError(f"{shown(self.url)} is not a Foxglove WebSocket server: it {answer}; {_FIX}")

    # -- reading

    def _fill(self, deadline: float, closed: str = "connection closed") -> None:
        """One read into the buffer, waiting until `deadline` at most (_Late after it)."""
        left = deadline - time.monotonic()
        if left <= 0 or self._sock is None:
            raise _Late
        self._sock.settimeout(left)
        try:
            data = self._sock.recv(65536)
        except TimeoutError:
            raise _Late from None
        if not data:
            raise Lost(closed)
        self._buffer += data

    def _take(self, size: int, deadline: float) -> bytes:
        while len(self._buffer) < size:
            self._fill(deadline)
        taken = bytes(self._buffer[:size])
        del self._buffer[:size]
        return taken

    def receive(self, timeout: float) -> tuple[int, bytes, int] | None:
        """The next data message: (opcode, bytes, time.monotonic_ns() when it was read), or None when none began
        within `timeout` seconds (or a ping or pong came). A close frame raises Lost."""
        try:
            if not self._buffer:
                self._fill(time.monotonic() + timeout)
        except _Late:
            return None
        except OSError as exc:
            raise Lost(self._closed_reason(exc)) from None
        try:
            return self._message(time.monotonic() + MESSAGE_SECONDS)
        except _Late:
            raise Lost(f"a message did not arrive whole within {MESSAGE_SECONDS:g} s of its first byte") from None
        except OSError as exc:
            raise Lost(self._closed_reason(exc)) from None

    def _message(self, deadline: float) -> tuple[int, bytes, int] | None:
        opcode, parts, size = 0, [], 0
        for _ in range(MAX_FRAGMENTS):
            final, kind, payload = self._next_frame(deadline, opcode, size)
            received_ns = time.monotonic_ns()
            self._heard = received_ns / 1e9
            if kind == CLOSE:
                with contextlib.suppress(OSError, _Late):
                    self._send_raw(_frame(CLOSE, payload[:2]), CLOSE_SECONDS)
                raise Lost(_close_reason(payload))
            if kind in (PING, PONG):
                if kind == PING:
                    self.send_frame(PONG, payload)
                if not opcode:
                    return None
                continue
            if (kind == CONT) != bool(opcode):
                raise self._malformed("a continuation frame outside a message" if opcode == 0 else "a new message inside a fragmented one")
            opcode = opcode or kind
            parts.append(payload)
            size += len(payload)
            if final:
                return opcode, b"".join(parts), received_ns
        raise self._malformed(f"a message in more than {MAX_FRAGMENTS:,} frames")

    def _next_frame(self, deadline: float, opcode: int, size: int) -> tuple[bool, int, bytes]:
        """(final, opcode, payload) of the next frame; its size checked from its header before its payload is read."""
        first, second = self._take(2, deadline)
        kind, length = first & 0x0F, second & 0x7F
        if first & 0x70 or second & 0x80:
            raise self._malformed("a frame with reserved bits set or a mask (a server's frames have neither)")
        if length == 126:
            length = struct.unpack("!H", self._take(2, deadline))[0]
        elif length == 127:
            length = struct.unpack("!Q", self._take(8, deadline))[0]
        if kind in (CLOSE, PING, PONG):
            if not first & 0x80 or length > 125:
                raise self._malformed(f"a control frame of {length:,} bytes{'' if first & 0x80 else ', fragmented'} (at most 125, whole)")
        elif kind in (CONT, TEXT, BINARY):
            limit = MAX_TEXT_BYTES if (opcode or kind) == TEXT else MAX_FRAME_BYTES
            if size + length > limit:
                what = "text message" if limit == MAX_TEXT_BYTES else "message"
                raise UserError(
                    f"{shown(self.url)} sent a {what} of {size + length:,} bytes (at most {limit:,}); no JointState is that large"
                )
        else:
            raise self._malformed(f"a frame of opcode {kind}, which WebSocket does not define")
        return bool(first & 0x80), kind, self._take(length, deadline)

    def _malformed(self, what: str) -> UserError:
        return UserError(f"{shown(self.url)} sent a malformed WebSocket frame ({what}); is it a Foxglove WebSocket server?")

    def _closed_reason(self, exc: OSError) -> str:
        return "closed" if self._ended.is_set() else _lost_reason(exc)

    def pending(self) -> bool:
        """Whether a frame that ends a message is here whole (read now, without waiting): a drain reads on, and never
        holds the samples it has for a message still on its way."""
        if self._whole_frame():
            return True
        sock = self._sock
        if sock is None or sock.fileno() < 0:
            return False
        if not (isinstance(sock, ssl.SSLSocket) and sock.pending()):
            with selectors.DefaultSelector() as selector:
                selector.register(sock, selectors.EVENT_READ)
                if not selector.select(0):
                    return False
        try:
            self._fill(time.monotonic() + 0.001)
        except _Late:
            return False
        except OSError as exc:
            raise Lost(self._closed_reason(exc)) from None
        return self._whole_frame()

    def _whole_frame(self) -> bool:
        """Whether the buffer holds, from its start, whole frames up to one with its final bit set."""
        data, at = self._buffer, 0
        for _ in range(MAX_FRAGMENTS):
            if len(data) < at + 2:
                return False
            final, length, head = data[at] & 0x80, data[at + 1] & 0x7F, 2
            if length >= 126:
                head += 2 if length == 126 else 8
                if len(data) < at + head:
                    return False
                length = int.from_bytes(data[at + 2 : at + head], "big")
            at += head + length
            if len(data) < at:
                return False
            if final:
                return True
        return True  # more frames than a message may have: `receive` refuses them at once

    # -- writing

    def _send_raw(self, data: bytes, seconds: float = CONNECT_SECONDS) -> None:
        with self._sending:
            if self._sock is None:
                raise Lost("closed")
            self._sock.settimeout(seconds)
            try:
                self._sock.sendall(data)
            except TimeoutError:
                raise Lost(f"sending timed out after {seconds:g} s") from None

    def send_frame(self, opcode: int, payload: bytes) -> None:
        try:
            self._send_raw(_frame(opcode, payload))
        except OSError as exc:
            raise Lost(self._closed_reason(exc)) from None

    def send(self, text: str) -> None:
        self.send_frame(TEXT, text.encode())

    def keep_alive(self) -> None:
        """A ping after PING_AFTER_SECONDS of silence; Lost after SILENT_SECONDS of it."""
        now = time.monotonic()
        if now - self._heard > SILENT_SECONDS:
            raise Lost(f"no frame, and no answer to pings, for {SILENT_SECONDS:g} s")
        if now - max(self._heard, self._pinged) > PING_AFTER_SECONDS:
            self._pinged = now
            self.send_frame(PING, b"")

    # -- ending

    def goodbye(self) -> None:
        """From another thread: the socket shut down, so a connect, read or send under way ends at once (the server
        sees the connection closed)."""
        self._ended.set()
        sock = self._sock
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        """A close frame and a short wait for the server's (skipped after goodbye), then the socket closed."""
        sock = self._sock
        if sock is None:
            return
        if not self._ended.is_set():
            with contextlib.suppress(OSError, Lost, UserError, _Late):
                self._send_raw(_frame(CLOSE, struct.pack("!H", 1000)), CLOSE_SECONDS)
                deadline = time.monotonic() + CLOSE_SECONDS
                while True:  # until the server's close frame (Lost), or the deadline (_Late)
                    self._message(deadline)
        with contextlib.suppress(OSError):
            sock.close()
