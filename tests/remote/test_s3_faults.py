"""S3 faults against real endpoints on 127.0.0.1, nothing patched in the client: a moto_server of the test's own that
is killed while `run` downloads from it, one that checks credentials (403), a key deleted after planning, an address
where nothing listens, and a server that accepts connections but never answers. Each is one located error naming the
URL and what bounded it, and the download cache keeps nothing partial."""

from __future__ import annotations

import os
import signal
import socket
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from urdf_pipeline import load
from urdf_pipeline.dataset import RunOptions, run_dataset
from urdf_pipeline.remote import s3_objects
from urdf_pipeline.sources.csv import CSV_BLOCK_BYTES

from ..conftest import S3
from ..local_processes import free_port
from ..s3_server import CREDENTIALS, moto_server, s3_endpoint
from ..source_helpers import PANDA_JOINTS, panda_config

HEADER = ("frame," + ",".join(PANDA_JOINTS) + "\n0," + ",".join(["0.1"] * len(PANDA_JOINTS)) + "\n").encode()
HANG_GUARD_SECONDS = 300  # a fault that hung would stop the test here, not the suite; every fault ends within seconds

needs_moto = pytest.mark.skipif(moto_server() is None, reason="no moto_server: pip install 'moto[server]' (the test extra has it)")


def _cache_files(cache: Path) -> list[Path]:
    """Everything in the download cache's entries: complete objects and partial downloads alike."""
    return sorted(p for p in cache.glob("*/*/*") if not p.name.endswith(".lock")) if cache.exists() else []


@pytest.fixture
def own_environment(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """The environment a test's own endpoint needs (credentials, the cache, the allowed bucket); the process's client
    is made anew before and after, so no other test talks to an endpoint this one stopped."""
    for name, value in CREDENTIALS.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_URLS", "s3://faults/")
    cache = tmp_path / "download-cache"
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(cache))
    s3_objects._client.cache_clear()
    yield cache
    s3_objects._client.cache_clear()


def _use(endpoint: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("AWS_ENDPOINT_URL", endpoint)
    s3_objects._client.cache_clear()


def _csv_config(examples_dir: Path, name: str, url: str) -> Path:
    return panda_config(examples_dir, name, {"csv": url, "index": "frame"})


@needs_moto
def test_the_endpoint_stopping_mid_download_fails_the_segment_by_url_and_keeps_nothing(
    own_environment: Path, examples_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """validate reads the CSV's first block; `run` downloads 256 MB in 16 MB ranges, 4 at a time; the endpoint is
    killed as the first bytes land in the cache's partial file."""
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    cache = own_environment
    with s3_endpoint() as (endpoint, process):
        _use(endpoint, monkeypatch)
        client = s3_objects.client()
        client.create_bucket(Bucket="faults")
        body = HEADER + b"#" * (256 << 20)  # never parsed: the download breaks off first
        client.put_object(Bucket="faults", Key="big/episode.csv", Body=body)
        del body
        url = "s3://faults/big/episode.csv"
        plan = load(_csv_config(examples_dir, "s3_fault_stopped", url))
        assert _cache_files(cache) == []

        killed = threading.Event()

        def kill_when_bytes_arrive() -> None:
            deadline = time.monotonic() + HANG_GUARD_SECONDS
            while time.monotonic() < deadline:
                partial = [p for p in cache.glob("*/*/.partial-*") if p.stat().st_size > 0] if cache.exists() else []
                if partial:
                    os.killpg(process.pid, signal.SIGKILL)  # the endpoint dies mid-transfer, without a goodbye
                    killed.set()
                    return
                time.sleep(0.002)

        killer = threading.Thread(target=kill_when_bytes_arrive, daemon=True)
        killer.start()
        started = time.monotonic()
        finished = run_dataset(plan, RunOptions(1, "local", None, True))
        print(f"endpoint stopped mid-download: the segment failed after {time.monotonic() - started:.1f} s")  # reported, not asserted
        killer.join(HANG_GUARD_SECONDS)
    assert killed.is_set(), "the download finished before the endpoint could be stopped"
    assert [r.status for r in finished.results] == ["failed"], finished.results
    reason = finished.results[0].reason
    assert "s3_fault_stopped.yaml:" in reason and f"cannot read {url}:" in reason, reason
    assert endpoint in reason and ("broke off during the transfer" in reason or "cannot connect to" in reason), reason
    assert _cache_files(cache) == [], "a broken download leaves no entry and no partial file"


@needs_moto
def test_credentials_the_endpoint_refuses_are_a_403_naming_the_url(
    own_environment: Path, examples_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    """moto_server with INITIAL_NO_AUTH_ACTION_COUNT=0 checks every request's signature: unknown keys get 403."""
    with s3_endpoint({"INITIAL_NO_AUTH_ACTION_COUNT": "0"}) as (endpoint, _):
        _use(endpoint, monkeypatch)
        result = run_cli("validate", str(_csv_config(examples_dir, "s3_fault_forbidden", "s3://faults/locked/episode.csv")))
    assert result.code == 1
    assert "s3_fault_forbidden.yaml:" in result.err and "sources.state.csv" in result.err, result.err
    assert "cannot read s3://faults/locked/episode.csv: access denied (403) for this run's AWS credentials" in result.err
    assert CREDENTIALS["AWS_ACCESS_KEY_ID"] not in result.err and CREDENTIALS["AWS_SECRET_ACCESS_KEY"] not in result.err


def test_a_key_deleted_after_planning_fails_its_segment_as_missing(
    s3: S3, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(tmp_path / "download-cache"))
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    s3.client().put_object(Bucket=s3.bucket, Key="gone/episode.csv", Body=HEADER)
    plan = load(_csv_config(examples_dir, "s3_fault_deleted", s3.url("gone/episode.csv")))
    s3.client().delete_object(Bucket=s3.bucket, Key="gone/episode.csv")
    finished = run_dataset(plan, RunOptions(1, "local", None, True))
    assert [r.status for r in finished.results] == ["failed"]
    assert f"cannot read {s3.url('gone/episode.csv')}: no such object (404)" in finished.results[0].reason
    assert _cache_files(tmp_path / "download-cache") == []


def test_an_endpoint_where_nothing_listens_fails_after_bounded_attempts(
    own_environment: Path, examples_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    endpoint = f"http://127.0.0.1:{free_port()}"
    _use(endpoint, monkeypatch)
    started = time.monotonic()
    result = run_cli("validate", str(_csv_config(examples_dir, "s3_fault_unreachable", "s3://faults/episode.csv")))
    print(f"unreachable endpoint: refused after {time.monotonic() - started:.1f} s")  # reported, not asserted
    assert result.code == 1 and "sources.state.csv" in result.err
    assert f"cannot read s3://faults/episode.csv: cannot connect to {endpoint} ({s3_objects.ATTEMPTS} attempts" in result.err, result.err


class _SilentServer:
    """Accepts TCP connections on 127.0.0.1 and never answers: an endpoint that hangs. Counts the connections."""

    def __init__(self) -> None:
        self.socket = socket.create_server(("127.0.0.1", 0))
        self.port = int(self.socket.getsockname()[1])
        self.connections: list[socket.socket] = []
        self.thread = threading.Thread(target=self._accept, daemon=True)
        self.thread.start()

    def _accept(self) -> None:
        while True:
            try:
                connection, _ = self.socket.accept()
            except OSError:
                return
            self.connections.append(connection)  # held open, unread, unanswered

    def close(self) -> None:
        self.socket.close()
        for connection in self.connections:
            connection.close()


def test_a_silent_endpoint_times_out_after_bounded_attempts(
    own_environment: Path, examples_dir: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    """The read timeout (30 s by default) shortened to 1 s: four connections, each given up, then one error."""
    monkeypatch.setattr(s3_objects, "READ_SECONDS", 1.0)
    server = _SilentServer()
    try:
        _use(f"http://127.0.0.1:{server.port}", monkeypatch)
        started = time.monotonic()
        result = run_cli("validate", str(_csv_config(examples_dir, "s3_fault_silent", "s3://faults/episode.csv")))
        print(f"silent endpoint: refused after {time.monotonic() - started:.1f} s")  # reported, not asserted
    finally:
        server.close()
    assert result.code == 1 and "sources.state.csv" in result.err
    assert (
        f"cannot read s3://faults/episode.csv: http://127.0.0.1:{server.port} did not answer within 1 s ({s3_objects.ATTEMPTS} attempts)"
        in result.err
    ), result.err
    assert len(server.connections) == s3_objects.ATTEMPTS  # the retries are bounded: one connection per attempt


def test_the_csv_header_is_one_bounded_ranged_read(s3: S3) -> None:
    """What a CSV source's validation fetches of a large object: one GET of CSV_BLOCK_BYTES."""
    from urdf_pipeline.remote import open_range, parse_url

    s3.client().put_object(Bucket=s3.bucket, Key="big.csv", Body=HEADER + b"1,2,3,4,5,6,7,8,9\n" * 200_000)
    remote = s3_objects.head(parse_url(s3.url("big.csv")), None)
    with open_range(remote, None, block=CSV_BLOCK_BYTES, max_requests=1) as reader:
        first = reader.read(CSV_BLOCK_BYTES)
        assert (reader.raw.requests, reader.raw.fetched) == (1, CSV_BLOCK_BYTES) and len(first) < remote.size
