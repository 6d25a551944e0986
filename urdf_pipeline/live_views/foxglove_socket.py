"""One WebSocket connection to a Foxglove server, through the `websockets` library's synchronous client, which speaks
RFC 6455 with its own bounds on what it reads (docs/security.md lists them all).

Ours around it, kept small: the TCP connect (in steps, and on a socket we hold, so that `goodbye` from another thread
ends a connect, a TLS or WebSocket handshake, a read or a send at once), the handshake's deadline, a JSON message's
tighter size bound, the silence rule (a frame on its way blocks pongs, so no frame takes longer), and the library's
exceptions in our one-line messages: `Lost` (refused, closed, reset, silent, too slow: the feed reconnects) or
`UserError` (no Foxglove server at that URL, a frame too large or malformed: reconnecting would not help).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import selectors
import socket
import ssl
import struct
import threading
import time
from typing import Any
from urllib.parse import urlsplit

from websockets.exceptions import (
    ConnectionClosed,
    InvalidMessage,
    InvalidStatus,
    NegotiationError,
    PayloadTooBig,
    ProtocolError,
    SecurityError,
    TooManyFragments,
    WebSocketException,
)
from websockets.frames import CloseCode
from websockets.protocol import State
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Subprotocol

from ..errors import UserError, has_control_character, quoted, shown
from .foxglove_protocol import MAX_FRAME_BYTES, MAX_TEXT_BYTES, SUBPROTOCOLS

CONNECT_SECONDS = 5.0  # TCP connect, TLS and the WebSocket handshake together; the server's first message again
PING_AFTER_SECONDS = 2.0  # a connection silent this long is pinged (servers answer pings, foxglove_bridge included)
SILENT_SECONDS = 10.0  # no message and no pong this long: lost (a pulled cable, a frozen robot, a frame trickled)
SEND_SECONDS = 2.0  # a send the server does not take (it reads nothing: its window is shut) fails after this long
CLOSE_SECONDS = 0.25  # how long a polite close waits for the server's close frame
STEP_SECONDS = 0.1  # a connect is waited for in steps this long, so `goodbye` ends it
MAX_QUEUE = 2  # the library stops reading while more whole frames than this wait for us (each <= MAX_FRAME_BYTES)
TEXT, BINARY = 0x1, 0x2
_FIX = "give --from the address of the robot's Foxglove WebSocket server (foxglove_bridge listens on ws://ROBOT:8765)"
# The library's own log lines are not ours to show: its failures reach us as exceptions, which we translate.
_QUIET = logging.getLogger("urdf_pipeline.live_views.websockets")
_QUIET.addHandler(logging.NullHandler())
_QUIET.propagate = False
# The library's protocol errors (a short phrase each), in our words; any other is "a frame RFC 6455 does not allow".
_MALFORMED = {
    "invalid opcode": "a frame of an opcode WebSocket does not define",
    "incorrect masking": "a frame with reserved bits set or a mask (a server's frames have neither)",
    "reserved bits must be 0": "a frame with reserved bits set or a mask (a server's frames have neither)",
    "fragmented control frame": "a control frame fragmented (at most 125 bytes, whole)",
    "control frame too long": "a control frame over 125 bytes (at most 125, whole)",
    "unexpected continuation frame": "a continuation frame outside a message",
    "expected a continuation frame": "a new message inside a fragmented one",
}


class Lost(Exception):
    """The connection failed or ended in a way a reconnect may mend; `reason` is for the line the user reads."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


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


def _lost_reason(exc: OSError) -> str:
    if isinstance(exc, ConnectionResetError | BrokenPipeError):
        return "connection closed"
    if isinstance(exc, TimeoutError | BlockingIOError | ssl.SSLWantWriteError):  # SO_SNDTIMEO: the server reads nothing
        return f"sending timed out after {SEND_SECONDS:g} s"
    return shown(exc.strerror or exc)


class Connection:
    """A WebSocket to a Foxglove server. `open`, `receive`, `pending`, `send`, `keep_alive` and `close` are called by
    the feed's one reading thread; `goodbye` from any thread."""

    def __init__(self, url: str) -> None:
        self.url = url
        self._parts = urlsplit(url)
        self._sock: socket.socket | None = None  # ours until the library takes it (a TLS one replaces it)
        self._watch: socket.socket | None = None  # the same connection's other descriptor: `goodbye` shuts it down
        self._ws: ClientConnection | None = None
        self._held: tuple[int, bytes, int] | None = None  # a message `pending` took, for the next `receive`
        self._ended = threading.Event()  # goodbye came
        self._pong: threading.Event | None = None  # set when the last ping's answer came
        self._heard = self._pinged = time.monotonic()

    # -- the handshake

    def open(self) -> None:
        """TCP, TLS for wss, and the upgrade, all within CONNECT_SECONDS; the subprotocol the server chose is checked."""
        deadline = time.monotonic() + CONNECT_SECONDS
        host, secure = self._parts.hostname or "", self._parts.scheme == "wss"
        try:
            sock = self._connect(host, self._parts.port or (443 if secure else 80), deadline)
        except TimeoutError:
            raise Lost(f"no answer within {CONNECT_SECONDS:g} s") from None
        except OSError as exc:
            raise self._open_failure(exc) from None
        made: list[ClientConnection] = []

        class Recorded(ClientConnection):
            """The library's connection, kept as it is made: an answer the library refused while it waited for the
            server to end the connection (until open_timeout) is told as what it was, not as a timeout."""

            def __init__(self, *args: Any, **kwargs: Any) -> None:
                super().__init__(*args, **kwargs)
                made.append(self)

        try:
            self._ws = connect(
                self.url,
                sock=sock,
                create_connection=Recorded,
                subprotocols=[Subprotocol(name) for name in SUBPROTOCOLS],
                compression=None,  # no extension: what a frame says is what it carries
                proxy=None,
                user_agent_header=None,
                open_timeout=max(deadline - time.monotonic(), 0.01),
                ping_interval=None,  # keep_alive pings, on the silence rule the feed documents
                ping_timeout=None,
                close_timeout=CLOSE_SECONDS,
                max_size=MAX_FRAME_BYTES,
                max_queue=MAX_QUEUE,
                logger=_QUIET,
                legacy=True,  # the connection itself, kept across calls (not a `with` block)
            )
        except (WebSocketException, OSError, ValueError) as exc:
            refused = made[0].protocol.handshake_exc if made and isinstance(exc, TimeoutError) else None
            if refused is None or isinstance(refused.__cause__, EOFError):  # ended by the deadline, not refused
                refused = exc
            raise self._open_failure(refused) from None
        if self._ended.is_set():
            raise Lost("closed")
        if self._ws.subprotocol not in SUBPROTOCOLS:
            raise self._refused(f"did not accept the Foxglove WebSocket subprotocol ({' or '.join(SUBPROTOCOLS)}; it chose none)")
        self._heard = self._pinged = time.monotonic()

    def _connect(self, host: str, port: int, deadline: float) -> socket.socket:
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
                sock.setblocking(True)
                # A send the server does not take fails (the library's sends have no deadline of their own), TLS too.
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO, struct.pack("ll", int(SEND_SECONDS), 0))
                self._watch = sock.dup()
                return sock
            sock.close()
            failure = ConnectionRefusedError() if error == errno.ECONNREFUSED else OSError(error, os.strerror(error))
        raise failure

    def _open_failure(self, exc: BaseException) -> Exception:
        """What a failed open means: Lost (try again later) or UserError (this URL is wrong)."""
        cause = exc.__cause__
        if self._ended.is_set():
            return Lost("closed")
        if isinstance(exc, TimeoutError):  # the TLS or WebSocket handshake
            return Lost(f"no WebSocket handshake within {CONNECT_SECONDS:g} s")
        if isinstance(exc, ssl.SSLError):
            return UserError(
                f"{shown(self.url)}: the TLS connection failed ({shown(exc)}); a wss:// server needs a certificate this machine trusts"
            )
        answered = exc if isinstance(exc, InvalidStatus) else cause  # a redirect is refused as its status
        if isinstance(answered, InvalidStatus):
            response = answered.response
            status = f"HTTP {response.status_code} {shown(response.reason_phrase)}".rstrip()
            return self._refused(f"answered the WebSocket handshake with {status}")
        if isinstance(exc, SecurityError) or isinstance(cause, SecurityError):
            return self._refused(
                "answered the WebSocket handshake beyond the client's bounds (too many headers, a line too long or a body too large)"
            )
        if isinstance(exc, ConnectionClosed) or (isinstance(exc, InvalidMessage) and isinstance(cause, EOFError)):
            return Lost("connection closed during the handshake")
        if isinstance(exc, InvalidMessage):
            return self._refused("answered the WebSocket handshake with something other than HTTP/1.1")
        if isinstance(exc, NegotiationError):
            return self._refused(f"did not accept the Foxglove WebSocket subprotocol ({' or '.join(SUBPROTOCOLS)}), or chose an extension")
        if isinstance(exc, WebSocketException | ValueError):
            return self._refused("did not complete the WebSocket upgrade as RFC 6455 says")
        if isinstance(exc, socket.gaierror):
            return Lost(f"cannot resolve its host: {shown(exc.strerror or exc)}")
        if isinstance(exc, ConnectionRefusedError):
            return Lost("connection refused")
        return Lost(_lost_reason(exc) if isinstance(exc, OSError) else "connection closed during the handshake")

    def _refused(self, answer: str) -> UserError:
        return UserError(f"{shown(self.url)} is not a Foxglove WebSocket server: it {answer}; {_FIX}")

    # -- reading

    def receive(self, timeout: float) -> tuple[int, bytes, int] | None:
        """The next data message: (opcode, bytes, time.monotonic_ns() when it was taken), or None when none came
        whole within `timeout` seconds. A close frame raises Lost."""
        if self._held is not None:
            message, self._held = self._held, None
            return message
        if self._ws is None:
            raise Lost("closed")
        try:
            try:
                data = self._ws.recv(timeout)
            except TimeoutError:
                if self._ws.state is State.OPEN:
                    return None
                # Closing (the server's close frame came, or the library refused a frame): the library waits for the
                # server to end the connection; after CLOSE_SECONDS we end its reading (an end of stream, no error to
                # hide the reason). The messages that came before are taken first, then the reason is raised.
                if not self._ws.wait_closed(CLOSE_SECONDS) and self._watch is not None:
                    with contextlib.suppress(OSError):
                        self._watch.shutdown(socket.SHUT_RD)
                data = self._ws.recv(CLOSE_SECONDS)
        except TimeoutError:
            raise Lost("connection closed") from None
        except (WebSocketException, OSError) as exc:
            raise self._failure(exc) from None
        received_ns = time.monotonic_ns()
        self._heard = received_ns / 1e9
        if isinstance(data, str):  # a text message, checked valid UTF-8 by the library
            text = data.encode()
            if len(text) > MAX_TEXT_BYTES:  # before any JSON is parsed (the library's bound is MAX_FRAME_BYTES)
                raise UserError(
                    f"{shown(self.url)} sent a text message of {len(text):,} bytes (at most {MAX_TEXT_BYTES:,}); no Foxglove message is that large"
                )
            return TEXT, text, received_ns
        return BINARY, data, received_ns

    def pending(self) -> bool:
        """Whether a whole message is here (taken now, without waiting): a drain reads on, and never holds the samples
        it has for a message still on its way."""
        if self._held is None:
            self._held = self.receive(0)
        return self._held is not None

    def _failure(self, exc: BaseException) -> Lost | UserError:
        """What ended the connection, in our words: from the cause the library chains, else from the close frames."""
        if self._ended.is_set():
            return Lost("closed")
        closed = exc if isinstance(exc, ConnectionClosed) else None
        cause = exc.__cause__ if closed is not None else exc
        if isinstance(cause, PayloadTooBig) and cause.size is not None:
            whole = cause.size + (cause.current_size or 0)
            return UserError(
                f"{shown(self.url)} sent a message of {whole:,} bytes (at most {cause.max_size:,}); no JointState is that large"
            )
        if isinstance(cause, TooManyFragments):
            return self._malformed("a message in more frames than the client takes")
        if isinstance(cause, ProtocolError):
            return self._malformed(_MALFORMED.get(str(cause), "a frame RFC 6455 does not allow"))
        if isinstance(cause, UnicodeDecodeError):
            return self._malformed("text that is not UTF-8")
        if closed is not None and closed.sent is not None and (closed.rcvd is None or not closed.rcvd_then_sent):
            # We closed first: the library refused a frame (its cause may be masked by the wait for the server's end).
            if closed.sent.code == CloseCode.MESSAGE_TOO_BIG:
                return UserError(
                    f"{shown(self.url)} sent a message over {MAX_FRAME_BYTES:,} bytes or in too many frames; no JointState is that large"
                )
            if closed.sent.code == CloseCode.PROTOCOL_ERROR:
                return self._malformed(_MALFORMED.get(closed.sent.reason, "a frame RFC 6455 does not allow"))
            if closed.sent.code == CloseCode.INVALID_DATA:
                return self._malformed("text that is not UTF-8")
        if closed is not None and closed.rcvd is not None:
            if closed.rcvd.code == CloseCode.NO_STATUS_RCVD:
                return Lost("the server closed the connection")
            reason = f" {shown(closed.rcvd.reason)}" if closed.rcvd.reason else ""
            return Lost(f"the server closed the connection: {closed.rcvd.code}{reason}")
        return Lost(_lost_reason(cause) if isinstance(cause, OSError) else "connection closed")

    def _malformed(self, what: str) -> UserError:
        return UserError(f"{shown(self.url)} sent a malformed WebSocket frame ({what}); is it a Foxglove WebSocket server?")

    # -- writing

    def send(self, text: str) -> None:
        if self._ws is None:
            raise Lost("closed")
        try:
            self._ws.send(text)
        except (WebSocketException, OSError) as exc:
            raise self._failure(exc) from None

    def keep_alive(self) -> None:
        """A ping after PING_AFTER_SECONDS of silence; Lost after SILENT_SECONDS with no message and no pong."""
        now = time.monotonic()
        if self._pong is not None and self._pong.is_set():
            self._heard, self._pong = now, None
        if now - self._heard > SILENT_SECONDS:
            raise Lost(f"no frame, and no answer to pings, for {SILENT_SECONDS:g} s")
        if now - max(self._heard, self._pinged) > PING_AFTER_SECONDS and self._ws is not None:
            self._pinged = now
            try:
                self._pong = self._ws.ping()
            except (WebSocketException, OSError) as exc:
                raise self._failure(exc) from None

    # -- ending

    def goodbye(self) -> None:
        """From another thread: the connection shut down, so a connect, handshake, read or send under way ends at once
        (the server sees the connection closed)."""
        self._ended.set()
        for sock in (self._watch, self._sock):
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        """A close frame and a short wait for the server's (none after goodbye), then the sockets closed."""
        if self._ws is not None:
            with contextlib.suppress(WebSocketException, OSError):
                self._ws.close()
        for sock in (self._watch, self._sock):
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.close()
