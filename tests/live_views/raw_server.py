"""Hostile WebSocket servers for the live tests, built on a raw socket on 127.0.0.1 in a thread of the test: each
connection runs a `behaviour(connection)` that says (and misbehaves) byte by byte, where a real server cannot be
made to: endless headers, an 8 GB error body, a frame trickled a byte at a time, endless fragments, a huge control
frame. The helpers speak the real protocol up to the point a behaviour breaks it."""

from __future__ import annotations

import base64
import contextlib
import hashlib
import json
import socket
import ssl
import struct
import threading
from collections.abc import Callable, Iterator
from typing import Any

from urdf_pipeline.examples import JOINT_STATE_MSGDEF

JOINT_STATE = "sensor_msgs/msg/JointState"
_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"


class Gone(Exception):
    """The client went away (or the test is over): the behaviour ends."""


class Peer:
    """One accepted connection, as a behaviour sees it."""

    def __init__(self, sock: socket.socket, stopping: threading.Event, index: int = 0) -> None:
        self.sock, self.stopping = sock, stopping
        self.index = index  # which connection of the server this is: 1, 2, ...
        self.buffer = b""

    def send(self, data: bytes) -> None:
        if self.stopping.is_set():
            raise Gone
        try:
            self.sock.sendall(data)
        except OSError:
            raise Gone from None

    def wait(self, seconds: float) -> None:
        if self.stopping.wait(seconds):
            raise Gone

    def _read(self, size: int) -> bytes:
        while len(self.buffer) < size:
            try:
                data = self.sock.recv(65536)
            except TimeoutError:
                if self.stopping.is_set():
                    raise Gone from None
                continue
            except OSError:
                raise Gone from None
            if not data:
                raise Gone
            self.buffer += data
        taken, self.buffer = self.buffer[:size], self.buffer[size:]
        return taken

    def request(self) -> str:
        """The client's upgrade request (its Sec-WebSocket-Key)."""
        head = b""
        while not head.endswith(b"\r\n\r\n"):
            head += self._read(1)
        for line in head.decode().split("\r\n"):
            name, _, value = line.partition(":")
            if name.lower() == "sec-websocket-key":
                return value.strip()
        raise AssertionError(f"no key in {head!r}")

    def upgrade(self, protocol: str = "foxglove.websocket.v1") -> None:
        key = self.request()
        accept = base64.b64encode(hashlib.sha1(key.encode() + _GUID).digest()).decode()
        self.send(
            "HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Accept: {accept}\r\nSec-WebSocket-Protocol: {protocol}\r\n\r\n".encode()
        )

    def client_frame(self) -> tuple[int, bytes]:
        """The client's next frame (masked, as a client's must be): (opcode, payload)."""
        first, second = self._read(2)
        assert second & 0x80, "a client frame must be masked"
        length = second & 0x7F
        if length == 126:
            length = struct.unpack("!H", self._read(2))[0]
        elif length == 127:
            length = struct.unpack("!Q", self._read(8))[0]
        mask = self._read(4)
        data = self._read(length)
        return first & 0x0F, bytes(b ^ mask[i % 4] for i, b in enumerate(data))

    def subscribed(self) -> dict[str, Any]:
        """The serverInfo and the JointState channel advertised, and the client's subscribe message."""
        self.send(frame(1, json.dumps({"op": "serverInfo", "name": "hostile", "capabilities": []}).encode()))
        channel = {"id": 1, "topic": "/joint_states", "encoding": "cdr", "schemaName": JOINT_STATE, "schema": JOINT_STATE_MSGDEF}
        self.send(frame(1, json.dumps({"op": "advertise", "channels": [channel]}).encode()))
        while True:
            opcode, data = self.client_frame()
            if opcode == 1:
                message: dict[str, Any] = json.loads(data)
                if message["op"] == "subscribe":
                    return message


def frame(opcode: int, payload: bytes, fin: bool = True, length: int | None = None) -> bytes:
    """A server's frame (unmasked); `length` claims another length than the payload's."""
    size = len(payload) if length is None else length
    if size < 126:
        head = bytes([size])
    elif size < 65536:
        head = struct.pack("!BH", 126, size)
    else:
        head = struct.pack("!BQ", 127, size)
    return bytes([(0x80 if fin else 0) | opcode]) + head + payload


def message_data(subscription: int, timestamp_ns: int, payload: bytes) -> bytes:
    """A Foxglove message-data frame."""
    return frame(2, struct.pack("<BIQ", 1, subscription, timestamp_ns) + payload)


class RawServer:
    """Listens on 127.0.0.1; each connection runs `behaviour(peer)` on a thread of its own until it returns, the
    client goes, or `stop()`. `connections` counts those accepted. With `tls`, each connection is TLS (a wss:// URL)."""

    def __init__(self, behaviour: Callable[[Peer], None], tls: ssl.SSLContext | None = None) -> None:
        self.behaviour, self.tls = behaviour, tls
        self.listener = socket.create_server(("127.0.0.1", 0))
        self.listener.settimeout(0.1)
        self.port = self.listener.getsockname()[1]
        self.url = f"{'wss' if tls else 'ws'}://127.0.0.1:{self.port}"
        self.connections = 0
        self.stopping = threading.Event()
        self._threads: list[threading.Thread] = []
        self._accepting = threading.Thread(target=self._accept, daemon=True)
        self._accepting.start()

    def _accept(self) -> None:
        while not self.stopping.is_set():
            try:
                sock, _ = self.listener.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            self.connections += 1
            thread = threading.Thread(target=self._serve, args=(sock, self.connections), daemon=True)
            self._threads.append(thread)
            thread.start()

    def _serve(self, sock: socket.socket, index: int) -> None:
        if self.tls is not None:
            sock.settimeout(5.0)
            try:
                sock = self.tls.wrap_socket(sock, server_side=True)
            except OSError:  # the client refused the certificate, or went
                sock.close()
                return
        sock.settimeout(0.1)
        with sock, contextlib.suppress(Gone):
            self.behaviour(Peer(sock, self.stopping, index))
            while True:  # done misbehaving: hold the connection open, silent, until the client or the test ends
                Peer(sock, self.stopping).wait(0.1)

    def stop(self) -> None:
        self.stopping.set()
        self.listener.close()
        self._accepting.join(10)
        for thread in self._threads:
            thread.join(10)


@contextlib.contextmanager
def raw_server(behaviour: Callable[[Peer], None], tls: ssl.SSLContext | None = None) -> Iterator[RawServer]:
    server = RawServer(behaviour, tls)
    try:
        yield server
    finally:
        server.stop()
