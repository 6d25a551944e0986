"""A real S3 endpoint for the tests: `moto_server` (moto's server mode, from PyPI) on 127.0.0.1, a separate process
that boto3, pyarrow and fsspec talk HTTP to, as they would to AWS or MinIO. Nothing in the test process is patched.

`s3_endpoint()` starts one and stops it (with its whole session); tests/conftest.py keeps one for the session, and a
test that stops its server mid-download starts its own.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from urdf_pipeline.process.children import die_with_parent, stop_session

from .local_processes import free_port

START_SECONDS = 60.0
# what boto3 reads; moto accepts any key. The region is fixed so no test reads ~/.aws or an instance's metadata.
CREDENTIALS = {
    "AWS_ACCESS_KEY_ID": "urdf-pipeline-test-key",
    "AWS_SECRET_ACCESS_KEY": "urdf-pipeline-test-secret",
    "AWS_DEFAULT_REGION": "us-east-1",
    "AWS_EC2_METADATA_DISABLED": "true",
    "AWS_CONFIG_FILE": os.devnull,
    "AWS_SHARED_CREDENTIALS_FILE": os.devnull,
}


def moto_server() -> str | None:
    found = Path(sys.executable).parent / "moto_server"
    return str(found) if found.is_file() else shutil.which("moto_server")


@contextmanager
def s3_endpoint(env: dict[str, str] | None = None) -> Iterator[tuple[str, subprocess.Popen[bytes]]]:
    """A running moto_server: its URL (`http://127.0.0.1:PORT`) and its process. `env` adds to its environment
    (`INITIAL_NO_AUTH_ACTION_COUNT=0`: it checks credentials, and refuses unknown ones with 403)."""
    binary = moto_server()
    assert binary is not None, "moto_server is not installed (pip install 'moto[server]': the test extra has it)"
    port = free_port()
    process = subprocess.Popen(
        [binary, "-H", "127.0.0.1", "-p", str(port)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,
        preexec_fn=die_with_parent(),
        env={**os.environ, **(env or {})},
    )
    try:
        deadline = time.monotonic() + START_SECONDS
        while True:
            try:
                socket.create_connection(("127.0.0.1", port), timeout=1).close()
                break
            except OSError:
                assert process.poll() is None, f"moto_server ended with {process.returncode}"
                assert time.monotonic() < deadline, f"moto_server did not listen on {port} within {START_SECONDS:.0f} s"
                time.sleep(0.1)
        yield f"http://127.0.0.1:{port}", process
    finally:
        stop_session(process)
