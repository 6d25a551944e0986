"""`urdf-pipeline serve DIR`: what it refuses, what it serves (inside DIR only, the wasm as application/wasm, to this
machine only), and how it ends (Ctrl-C, SIGTERM)."""

from __future__ import annotations

import http.client
import os
import signal
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from urdf_pipeline.web import SiteServer, site_folder

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
    running.serve_in_thread()
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


@pytest.mark.parametrize(("sent", "status"), [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_ctrl_c_and_sigterm_end_it(site: Path, sent: signal.Signals, status: int) -> None:
    """The command as a user runs it: its URL alone on stdout, answered, then ended by the signal with 128 + its number."""
    process = subprocess.Popen(
        [sys.executable, "-m", "urdf_pipeline", "serve", str(site)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "PYTHONPATH": str(REPO)},
    )
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
