"""`urdf-pipeline serve DIR`: what it refuses, what it serves (inside DIR only, the wasm as application/wasm, to this
machine only), and how it ends (Ctrl-C, SIGTERM); what it answers to hostile requests built here on raw sockets (bad
bytes, endless or half-sent heads, idle connections, a flood), and that a signal ends it whatever clients hold."""

from __future__ import annotations

import http.client
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from urdf_pipeline.web import SiteServer, site_folder, static_server
from urdf_pipeline.web.static_server import MAX_CONNECTIONS

from ..conftest import REPO


@pytest.fixture
def site(tmp_path: Path) -> Path:
    root = tmp_path / "site"
    (root / "viewer").mkdir(parents=True)
    (root / "index.html").write_text("<!doctype html><title>site</title>\n")
    (root / "viewer" / "re_viewer_bg.wasm").write_bytes(b"\0asm\1\0\0\0")
    (root / "viewer" / "boot.js").write_text("'use strict';\n")
    (root / "a.rrd").write_bytes(b"RRF2")
    (root / "inside.html").symlink_to(root / "index.html")
    (tmp_path / "secret.txt").write_text("not for the browser")
    (root / "escape.txt").symlink_to(tmp_path / "secret.txt")
    (root / "escape_folder").symlink_to(tmp_path)
    return root


@pytest.fixture
def server(site: Path) -> Iterator[SiteServer]:
    running = SiteServer(site_folder(site), 0)
    threading.Thread(target=running.serve_forever, daemon=True).start()
    try:
        yield running
    finally:
        running.shutdown()
        running.server_close()


def _get(server: SiteServer, path: str, host: str | None = None) -> tuple[int, dict[str, str], bytes]:
    """One GET with the path exactly as given (no client-side normalising of `..`)."""
    connection = http.client.HTTPConnection("127.0.0.1", server.port, timeout=10)
    try:
        connection.putrequest("GET", path, skip_host=True)
        connection.putheader("Host", host if host is not None else f"127.0.0.1:{server.port}")
        connection.endheaders()
        answer = connection.getresponse()
        return answer.status, {k.lower(): v for k, v in answer.getheaders()}, answer.read()
    finally:
        connection.close()


def test_it_serves_the_site_with_the_types_a_browser_needs(server: SiteServer) -> None:
    assert server.url == f"http://127.0.0.1:{server.port}/"
    status, headers, body = _get(server, "/viewer/re_viewer_bg.wasm")
    assert (status, headers["content-type"], body[:4]) == (200, "application/wasm", b"\0asm")
    assert headers["cache-control"] == "no-cache" and headers["x-content-type-options"] == "nosniff"
    assert _get(server, "/viewer/boot.js")[1]["content-type"] == "text/javascript"
    assert _get(server, "/a.rrd")[1]["content-type"] == "application/octet-stream"
    status, headers, body = _get(server, "/")
    assert status == 200 and headers["content-type"] == "text/html" and b"<title>site</title>" in body
    assert _get(server, "/inside.html")[0] == 200  # a link that stays inside is followed


@pytest.mark.parametrize(
    "path", ["/../secret.txt", "/viewer/../../secret.txt", "/%2e%2e/secret.txt", "/escape.txt", "/escape_folder/secret.txt", "/nothing"]
)
def test_nothing_outside_the_folder_is_served(server: SiteServer, path: str) -> None:
    status, _, body = _get(server, path)
    assert status == 404 and b"not for the browser" not in body


def test_folders_are_not_listed(server: SiteServer) -> None:
    assert _get(server, "/viewer/")[0] == 404


@pytest.mark.parametrize("host", ["evil.example", "evil.example:80", "127.0.0.1.evil.example", ""])
def test_it_answers_only_to_its_own_name(server: SiteServer, host: str) -> None:
    """A page elsewhere whose name was pointed at 127.0.0.1 (DNS rebinding) gets nothing."""
    assert _get(server, "/index.html", host)[0] == 421
    assert _get(server, "/index.html", f"localhost:{server.port}")[0] == 200


def test_it_listens_on_this_machine_only(server: SiteServer) -> None:
    assert server.server_address[0] == "127.0.0.1"


def test_refusals_are_located_user_errors(run_cli, tmp_path: Path) -> None:
    missing = tmp_path / "missing"
    result = run_cli("serve", str(missing))
    assert result.code == 1 and result.err.splitlines() == [
        f"error: {missing}: does not exist; serve takes the folder a site was written to (plan --html DIR, diff --html DIR, browse -o DIR)"
    ]
    a_file = tmp_path / "index.html"
    a_file.write_text("x")
    result = run_cli("serve", str(a_file))
    assert result.code == 1 and "is not a folder" in result.err
    empty = tmp_path / "empty"
    empty.mkdir()
    result = run_cli("serve", str(empty))
    assert result.code == 1 and result.err.startswith(f"error: {empty}: holds no index.html") and "Traceback" not in result.err
    assert run_cli("serve", str(empty), "--port", "70000").code == 2


def test_a_port_in_use_is_a_user_error(run_cli, site: Path) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        result = run_cli("serve", str(site), "--port", str(taken.getsockname()[1]))
    assert result.code == 1 and "is in use" in result.err and "--port 0" in result.err


def _serve_command(site: Path, start_new_session: bool = False) -> subprocess.Popen[str]:
    """`urdf-pipeline serve SITE` as a user runs it, in a process of its own (stdout and stderr piped, as text)."""
    return subprocess.Popen(
        [sys.executable, "-m", "urdf_pipeline", "serve", str(site)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
        start_new_session=start_new_session,
    )


@pytest.mark.parametrize(("sent", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_and_sigterm_end_it(site: Path, sent: signal.Signals, status: int) -> None:
    """The command as a user runs it: its URL alone on stdout, answered, then ended by the signal with 128 + its number."""
    process = _serve_command(site)
    try:
        assert process.stdout is not None
        url = process.stdout.readline().strip()
        port = int(url.removeprefix("http://127.0.0.1:").rstrip("/"))
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        connection.request("GET", "/index.html")
        assert connection.getresponse().status == 200
        connection.close()
        process.send_signal(sent)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == status
    assert out == "" and "serving" in err and "a free port" in err and "Traceback" not in err


def _exchange(port: int, data: bytes, then: Callable[[socket.socket], None] | None = None) -> bytes:
    """`data` sent on a raw connection (`then` may go on sending), and everything the server answers until it closes."""
    received = bytearray()
    with socket.create_connection(("127.0.0.1", port), timeout=HANG_GUARD) as connection:
        connection.sendall(data)
        if then is not None:
            then(connection)
        try:
            while chunk := connection.recv(65536):
                received += chunk
        except ConnectionResetError:
            pass  # closed with our unread bytes in its buffer: what came before the reset is the answer
    return bytes(received)


def _status(answer: bytes) -> int:
    """The answer's status, once it is a whole HTTP/1.0 answer carrying nosniff."""
    head = answer.split(b"\r\n\r\n", 1)[0].decode("latin-1").lower()
    assert head.startswith("http/1.0 ") and "\r\nx-content-type-options: nosniff" in head, answer[:300]
    return int(head.split()[1])


HANG_GUARD = 30  # seconds: only so that a hang fails the test; the server's own bounds are a few seconds


@pytest.mark.parametrize(
    ("request_line", "status"),
    [
        (b"GET /index\x00.html HTTP/1.1", 400),  # NUL in the path
        (b"GET /%00 HTTP/1.1", 400),  # NUL, escaped
        (b"GET /index.html%00.rrd HTTP/1.1", 400),
        (b"GET /%zz HTTP/1.1", 400),  # not a percent-escape
        (b"GET /%e2%82 HTTP/1.1", 400),  # a cut UTF-8 sequence
        (b"GET /%ff%fe HTTP/1.1", 400),  # not UTF-8
        (b"GET /\xc3\xa9 HTTP/1.1", 400),  # a raw byte over 0x7f
        (b"GET /a\x01b HTTP/1.1", 400),
        (b"GET /a\x7fb HTTP/1.1", 400),
        (b"GET /%1b%5b31m HTTP/1.1", 400),  # an escape sequence, escaped
        (b"GET  /index.html HTTP/1.1", 400),
        (b"GET /index.html", 400),  # HTTP/0.9 (its answer would have no header at all)
        (b"GET /index.html HTTP/x.y", 400),
        (b"GET /index.html HTTP/2.0", 505),
        (b"GET index.html HTTP/1.1", 400),
        (b"POST /index.html HTTP/1.1", 501),
        (b"GET /" + b"a" * 9000 + b" HTTP/1.1", 414),
        (b"GET /%e2%82%ac HTTP/1.1", 404),  # well-formed UTF-8 that names no file
        (b"GET /index.html HTTP/1.1", 200),
    ],
)
def test_a_hostile_request_line_is_answered_never_a_traceback(
    server: SiteServer, request_line: bytes, status: int, capfd: pytest.CaptureFixture[str]
) -> None:
    answer = _exchange(server.port, request_line + f"\r\nHost: 127.0.0.1:{server.port}\r\n\r\n".encode())
    assert _status(answer) == status
    assert b"<" not in answer.split(b"\r\n\r\n", 1)[1] or status == 200  # error bodies are plain text
    assert "Traceback" not in capfd.readouterr().err


@pytest.mark.parametrize(
    ("headers", "status"),
    [
        (b"X-A: a\x00b\r\n", 400),
        (b"X-A: a\rb\r\n", 400),
        (b"X-A: \x1b[2J\r\n", 400),
        (b"X-A: b\r\n" * 150, 431),  # more than HEADER_LINES
        ((b"X-A: " + b"b" * 4000 + b"\r\n") * 10, 431),  # more than HEAD_LIMIT bytes
        (b"X-A: caf\xc3\xa9\r\n", 200),  # obs-text in a field is allowed
    ],
)
def test_hostile_headers_are_answered(server: SiteServer, headers: bytes, status: int, capfd: pytest.CaptureFixture[str]) -> None:
    answer = _exchange(server.port, f"GET /index.html HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n".encode() + headers + b"\r\n")
    assert _status(answer) == status
    assert "Traceback" not in capfd.readouterr().err


def test_a_half_sent_request_and_endless_trickled_headers_time_out(server: SiteServer, monkeypatch: pytest.MonkeyPatch) -> None:
    """A request whose blank line never comes, sent at once or a header line at a time forever: a 408 within
    HEAD_SECONDS of the connection's start, whatever the trickle (1 s here, 5 s as shipped)."""
    monkeypatch.setattr(static_server, "HEAD_SECONDS", 1.0)
    started = time.monotonic()
    assert _status(_exchange(server.port, b"GET /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\n")) == 408
    half = time.monotonic() - started

    def trickle(connection: socket.socket) -> None:
        connection.settimeout(0.2)
        for number in range(10 * HANG_GUARD):
            try:
                connection.sendall(f"X-{number}: b\r\n".encode())
                if connection.recv(1, socket.MSG_PEEK):
                    return  # answered
            except TimeoutError:
                continue
            except OSError:
                return  # closed
        pytest.fail("the server kept reading trickled headers")

    started = time.monotonic()
    assert _status(_exchange(server.port, b"GET /index.html HTTP/1.1\r\n", trickle)) == 408
    print(f"half-sent request answered 408 after {half:.1f} s, trickled headers after {time.monotonic() - started:.1f} s")


def test_an_idle_connection_is_closed(server: SiteServer, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(static_server, "HEAD_SECONDS", 1.0)
    assert _exchange(server.port, b"") == b""  # nothing sent, nothing answered: closed after HEAD_SECONDS


def test_a_flood_of_connections_is_bounded(server: SiteServer) -> None:
    """500 connections at once, none sending: at most MAX_CONNECTIONS threads, one more connection answered 503 at
    once (accepted after the flood: the flood was dealt with before it); once they are gone, the site is served."""
    before = threading.active_count()
    flood = [socket.create_connection(("127.0.0.1", server.port), timeout=HANG_GUARD) for _ in range(500)]
    try:
        assert _status(_exchange(server.port, f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n\r\n".encode())) == 503
        threads = threading.active_count() - before
        print(f"500 connections: {threads} serving threads")
        assert threads <= MAX_CONNECTIONS
    finally:
        for connection in flood:
            connection.close()
    deadline = time.monotonic() + HANG_GUARD
    while (status := _status(_exchange(server.port, f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{server.port}\r\n\r\n".encode()))) == 503:
        assert time.monotonic() < deadline, "the slots of closed connections never came back"
    assert status == 200


@pytest.mark.parametrize("sent", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_ends_it_while_clients_hold_connections(site: Path, sent: signal.Signals) -> None:
    """The command as a user runs it, with 500 connections open (idle, half-sent, trickling): the signal ends it
    within a few seconds, without a traceback, and leaves no process behind."""
    process = _serve_command(site, start_new_session=True)  # its own group: anything it started is found by it
    held: list[socket.socket] = []
    try:
        assert process.stdout is not None
        port = int(process.stdout.readline().strip().removeprefix("http://127.0.0.1:").rstrip("/"))
        for number in range(500):
            connection = socket.create_connection(("127.0.0.1", port), timeout=HANG_GUARD)
            if number % 3 == 1:
                connection.sendall(b"GET /index.html HTTP/1.1\r\nHost: 127.0.0.1\r\n")  # half-sent
            elif number % 3 == 2:
                connection.sendall(b"GET /index.html HTTP/1.1\r\nX-1: a")  # a header cut in its middle
            held.append(connection)
        started = time.monotonic()
        process.send_signal(sent)
        out, err = process.communicate(timeout=HANG_GUARD)
        print(f"{sent.name} with 500 connections held: ended in {time.monotonic() - started:.2f} s")
    finally:
        for connection in held:
            connection.close()
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + sent and "Traceback" not in err and out == "", err
    with pytest.raises(ProcessLookupError):
        os.killpg(process.pid, 0)  # nothing of its process group is left
