"""`urdf-pipeline serve DIR`: a site on http://127.0.0.1:PORT/ (the wasm does not load from `file://`).

Only this machine can connect (127.0.0.1, never every interface), and only with a Host header naming it (a web page
elsewhere cannot reach the server by pointing its own name at 127.0.0.1). Only files inside DIR are served: a path
that leaves it, also through a symbolic link, is not found; folders are not listed. `.wasm` goes out as
`application/wasm` (the browser compiles it while it downloads), every file with `Cache-Control: no-cache` (a site
written again shows at once; unchanged files are answered 304).
"""

from __future__ import annotations

import errno
import os
import threading
from collections.abc import Callable
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

from ..errors import UserError, Where
from ..progress import detail

HOST = "127.0.0.1"
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
    """The HTTP server of one folder, bound to 127.0.0.1."""

    daemon_threads = True  # a browser's idle connection does not hold up the end
    allow_reuse_address = False  # another server on the port is an error, not a neighbour

    def __init__(self, folder: Path, port: int) -> None:
        self.folder = folder
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

    def serve_in_thread(self) -> threading.Thread:
        """For tests and embedding: serve on a daemon thread until `shutdown()`."""
        thread = threading.Thread(target=self.serve_forever, name="urdf-pipeline-serve", daemon=True)
        thread.start()
        return thread


class _Handler(SimpleHTTPRequestHandler):
    server: SiteServer
    extensions_map = {**SimpleHTTPRequestHandler.extensions_map, **TYPES}

    def translate_path(self, path: str) -> str:
        """The file inside the site for a request path, or a path that does not exist (a 404) for one outside it."""
        translated = super().translate_path(path)
        root = self.server.folder
        try:
            real = Path(translated).resolve()
        except (OSError, RuntimeError):
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

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 (the base class's parameter name)
        detail(f"serve: {self.address_string()} {format % args}")

    def handle(self) -> None:
        try:
            super().handle()
        except (TimeoutError, ConnectionResetError, BrokenPipeError):
            pass  # the browser went away mid-answer (a reload, a closed tab): nothing to say


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
