"""`urdf-pipeline serve DIR`: a site on http://127.0.0.1:PORT/ (the wasm does not load from `file://`).

Whatever a local client sends (docs/security.md lists the bounds: 127.0.0.1 and its Host only, files inside DIR only,
the request's head read by us within bytes and seconds, at most MAX_CONNECTIONS at once), it gets a status, never a
traceback, and holds nothing for long. Stopping (Ctrl-C, SIGTERM) closes the listening socket and every open connection.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import socket
import threading
import time
import urllib.parse
from collections.abc import Callable
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

from ..errors import UserError, Where
from ..logs import detail

HOST = "127.0.0.1"
REQUEST_LINE_LIMIT = 8192  # bytes of `GET /path HTTP/1.1`: a longer one is a 414
HEAD_LIMIT = 32768  # bytes of the request line and its headers: more is a 431
HEADER_LINES = 100  # header lines: more is a 431
HEAD_SECONDS = 5.0  # from the connection's start to the end of its request's head, however it trickles in
SEND_SECONDS = 10.0  # a client that takes no part of an answer for this long is dropped
MAX_CONNECTIONS = 64  # connections served at once (a browser opens 6 per host); one more is answered 503 and closed
BACKLOG = 128  # connections the system holds before they are accepted (and served or answered 503)
HEAD_END = re.compile(rb"\r?\n\r?\n")
REQUEST_LINE = re.compile(rb"[\x21-\x7e]+ /[\x21-\x7e]* HTTP/[0-9.]+")  # printable ASCII only, three words, an absolute path
HEADER_BYTES = re.compile(rb"[\t\x20-\x7e\x80-\xff]*")  # field text (obs-text allowed): no NUL, no control character
BAD_ESCAPE = re.compile(r"%(?![0-9A-Fa-f]{2})")
CONTROL = re.compile("[\x00-\x1f\x7f]")
BUSY = (
    b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: 31\r\n"
    b"X-Content-Type-Options: nosniff\r\nCache-Control: no-store\r\nRetry-After: 1\r\nConnection: close\r\n\r\n"
    b"503 too many connections; retry"
)
TYPES = {
    ".wasm": "application/wasm",
    ".js": "text/javascript",
    ".mjs": "text/javascript",
    ".json": "application/json",
    ".css": "text/css",
    ".html": "text/html",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".ico": "image/x-icon",
    ".rrd": "application/octet-stream",
    ".rbl": "application/octet-stream",
}


def site_folder(folder: Path) -> Path:
    """DIR resolved, once it is a folder holding an index.html; else a user error naming the fix."""
    if not folder.is_dir():
        what = "does not exist" if not folder.exists() else "is not a folder"
        raise UserError(
            f"{what}; serve takes the folder a site was written to (plan --html DIR, diff --html DIR, browse -o DIR)", Where(folder, 0)
        )
    if not (folder / "index.html").is_file():
        raise UserError(
            "holds no index.html, so it is not a site; give the folder that plan --html, diff --html or browse -o wrote", Where(folder, 0)
        )
    return folder.resolve()


class SiteServer(ThreadingHTTPServer):
    """The HTTP server of one folder, bound to 127.0.0.1: a thread per connection, at most MAX_CONNECTIONS."""

    daemon_threads = True  # a client's connection does not hold up the end
    allow_reuse_address = False  # another server on the port is an error, not a neighbour
    request_queue_size = BACKLOG

    def __init__(self, folder: Path, port: int) -> None:
        self.folder = folder
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)
        self._open: set[socket.socket] = set()
        self._open_lock = threading.Lock()
        try:
            super().__init__((HOST, port), partial(_Handler, directory=str(folder)))
        except OSError as exc:
            if exc.errno == errno.EADDRINUSE:
                raise UserError(f"port {port} on {HOST} is in use; choose another with --port N, or --port 0 for a free one") from None
            if exc.errno in (errno.EACCES, errno.EPERM):
                raise UserError(f"port {port} on {HOST} needs privileges; choose one above 1023, or --port 0 for a free one") from None
            raise

    @property
    def port(self) -> int:
        return int(self.server_address[1])

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.port}/"

    def process_request(self, request: Any, client_address: Any) -> None:
        """A thread for the connection while fewer than MAX_CONNECTIONS are open; else a 503 at once (never waiting on
        the client: the accepting thread sends into an empty buffer without blocking) and the connection closed."""
        if not self._slots.acquire(blocking=False):
            with contextlib.suppress(OSError):  # the client is gone already
                request.setblocking(False)
                request.send(BUSY)
            self.shutdown_request(request)
            return
        with self._open_lock:
            self._open.add(request)
        try:
            super().process_request(request, client_address)
        except BaseException:  # no thread could be started: the slot and the connection go back
            self._done(request)
            self.shutdown_request(request)
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._done(request)

    def _done(self, request: socket.socket) -> None:
        with self._open_lock:
            if request not in self._open:
                return
            self._open.discard(request)
        self._slots.release()

    def server_close(self) -> None:
        """The listening socket closed, and every open connection shut down: their threads end at once."""
        super().server_close()
        with self._open_lock:
            still_open = list(self._open)
        for connection in still_open:
            with contextlib.suppress(OSError):  # closed meanwhile
                connection.shutdown(socket.SHUT_RDWR)


class _Handler(SimpleHTTPRequestHandler):
    server: SiteServer
    extensions_map = {**SimpleHTTPRequestHandler.extensions_map, **TYPES}
    error_message_format = "%(code)d %(message)s\n"  # plain text: nothing of a request is ever HTML
    error_content_type = "text/plain; charset=utf-8"
    default_request_version = "HTTP/1.0"  # never 0.9's bare body: every answer has its status line and headers

    def handle(self) -> None:
        with contextlib.suppress(OSError):  # the client went away, or stopped taking the answer (a reload, a closed tab, SEND_SECONDS)
            super().handle()

    def handle_one_request(self) -> None:
        """One request: its head read and checked by us (bounded in bytes and time), then answered."""
        self.close_connection = True
        self.requestline, self.request_version, self.command = "", self.default_request_version, ""  # what send_error needs
        head = self._read_head()
        if head is None:
            return
        line, _, rest = head.partition(b"\n")
        line = line.rstrip(b"\r")
        if len(line) > REQUEST_LINE_LIMIT:
            self.send_error(HTTPStatus.REQUEST_URI_TOO_LONG, "request line too long")
            return
        headers = [header.removesuffix(b"\r") for header in rest.split(b"\n")] if rest else []  # a lone CR stays, and is refused
        if len(headers) > HEADER_LINES:
            self.send_error(HTTPStatus.REQUEST_HEADER_FIELDS_TOO_LARGE, "too many header lines")
            return
        if not REQUEST_LINE.fullmatch(line) or not all(HEADER_BYTES.fullmatch(header) for header in headers):
            self.send_error(HTTPStatus.BAD_REQUEST, "a byte no request may hold, or not METHOD /PATH HTTP/x.y")
            return
        self.raw_requestline = line + b"\r\n"
        socket_file, self.rfile = self.rfile, io.BytesIO(rest + b"\r\n")  # parse_request reads the headers we read
        try:
            parsed = self.parse_request()
        finally:
            self.rfile = socket_file
        if not parsed:
            return
        if not _plain_path(self.path):
            self.send_error(HTTPStatus.BAD_REQUEST, "a path with a bad percent-escape, a control character or not UTF-8")
            return
        self.close_connection = True  # one request per connection: no idle connection is kept
        self.connection.settimeout(SEND_SECONDS)
        method = getattr(self, f"do_{self.command}", None)
        if method is None:
            self.send_error(HTTPStatus.NOT_IMPLEMENTED, "only GET and HEAD")
            return
        method()
        self.wfile.flush()

    def _read_head(self) -> bytes | None:
        """The request line and headers (without the blank line), read within HEAD_SECONDS of the connection's start
        and HEAD_LIMIT bytes; None when the client sent nothing (closed quietly) or an error was answered."""
        deadline = time.monotonic() + HEAD_SECONDS
        received = bytearray()
        while (end := HEAD_END.search(received)) is None:
            if len(received) > HEAD_LIMIT or (b"\n" not in received and len(received) > REQUEST_LINE_LIMIT):
                too_long = b"\n" not in received
                self.send_error(
                    HTTPStatus.REQUEST_URI_TOO_LONG if too_long else HTTPStatus.REQUEST_HEADER_FIELDS_TOO_LARGE,
                    "request line too long" if too_long else "request headers too large",
                )
                return None
            left = deadline - time.monotonic()
            try:
                if left <= 0:
                    raise TimeoutError
                self.connection.settimeout(left)
                chunk = self.connection.recv(4096)
            except TimeoutError:
                if received:  # a half-sent request: said; an idle connection is just closed
                    self.send_error(HTTPStatus.REQUEST_TIMEOUT, f"the request did not arrive within {HEAD_SECONDS:g} s")
                return None
            if not chunk:
                return None
            received += chunk
        return bytes(received[: end.start()])

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """The error answer, given SEND_SECONDS to go out (the head's deadline may be all but spent)."""
        self.connection.settimeout(SEND_SECONDS)
        super().send_error(code, message, explain)

    def translate_path(self, path: str) -> str:
        """The file inside the site for a request path, or a path that does not exist (a 404) for one outside it."""
        translated = super().translate_path(path)
        root = self.server.folder
        try:
            real = Path(translated).resolve()
        except (OSError, RuntimeError, ValueError):
            return str(root / ".urdf-pipeline-not-found")
        if real != root and root not in real.parents:
            return str(root / ".urdf-pipeline-not-found")
        return str(real)

    def send_head(self):  # type: ignore[no-untyped-def]  # the base class's own signature (a file object or None)
        if not self._host_allowed():
            self.send_error(HTTPStatus.MISDIRECTED_REQUEST, "this server answers to 127.0.0.1 and localhost only")
            return None
        return super().send_head()

    def _host_allowed(self) -> bool:
        host = (self.headers.get("Host") or "").strip().lower()
        name, _, port = host.rpartition(":") if host.count(":") == 1 else (host, "", "")
        return name in (HOST, "localhost") and port in ("", str(self.server.port))

    def list_directory(self, path: str | os.PathLike[str]) -> None:
        """Folders are not listed: a site has an index.html where it has a page."""
        self.send_error(HTTPStatus.NOT_FOUND, "not found")
        return None

    def end_headers(self) -> None:
        self.send_header("Cache-Control", "no-cache")
        self.send_header("X-Content-Type-Options", "nosniff")
        super().end_headers()

    def log_message(self, format: str, *args: object) -> None:  # (the base class's parameter name)
        detail(f"serve: {self.address_string()} {format % args}")


def _plain_path(target: str) -> bool:
    """The request's path (before `?`) is `/`-rooted, its percent-escapes well formed, and it decodes to UTF-8 text
    without a control character (NUL included): anything else is a 400, never a file name."""
    path = target.split("?", 1)[0].split("#", 1)[0]
    if not path.startswith("/") or BAD_ESCAPE.search(target):
        return False
    try:
        decoded = urllib.parse.unquote_to_bytes(path).decode("utf-8")
    except UnicodeDecodeError:
        return False
    return not CONTROL.search(decoded)


def serve_site(folder: Path, port: int = 0, ready: Callable[[SiteServer], None] | None = None) -> None:
    """Serve the site in `folder` on 127.0.0.1:`port` (0: a free port) until Ctrl-C or SIGTERM, which end it (the
    KeyboardInterrupt goes on to the command line's exit point: 130 or 143). `ready` is called once it listens."""
    server = SiteServer(site_folder(folder), port)
    try:
        if ready is not None:
            ready(server)
        server.serve_forever(poll_interval=0.2)
    finally:
        server.server_close()
