"""The Ray executor on a local instance it starts and on a cluster it only joins (a `ray start --head` subprocess)."""

from __future__ import annotations

import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import ray
from ray import cloudpickle

from urdf_pipeline.dataset import ray_executor
from urdf_pipeline.dataset.ray_executor import run_on_ray
from urdf_pipeline.errors import UserError

from ..local_processes import free_port, stop
from .ray_auth import reset_auth_token_state

pytestmark = pytest.mark.slow  # a real Ray cluster or catalog server

# Workers find this module by the driver's working directory only; pickled by value, the tests run from anywhere.
cloudpickle.register_pickle_by_value(sys.modules[__name__])


@dataclass(frozen=True)
class Job:
    n: int
    how: str = "ok"  # ok | raise | exit | slow | stuck
    marker_dir: str = ""


def work(job: Job) -> tuple[int, str]:
    """Top-level, as the real job function is; returns the worker's Python prefix to show it runs the venv."""
    if job.how == "raise":
        raise ValueError(f"boom {job.n}")
    if job.how == "exit":
        os._exit(3)  # the worker dies, as on a segfault or the OOM killer
    if job.how in ("slow", "stuck"):
        try:
            for _ in range(600):
                time.sleep(0.05 if job.how == "slow" else 30)  # "stuck" stays in C, where a KeyboardInterrupt cannot land
        except BaseException as exc:
            Path(job.marker_dir, f"cleanup-{job.n}-{type(exc).__name__}").touch()
            raise
    return job.n * job.n, sys.prefix


@dataclass
class Calls:
    done: dict[int, tuple[int, str]]
    crashed: dict[int, BaseException]

    def on_done(self, job: Job, result: tuple[int, str]) -> None:
        self.done[job.n] = result

    def on_crash(self, job: Job, error: BaseException) -> None:
        self.crashed[job.n] = error


def calls() -> Calls:
    return Calls({}, {})


@pytest.fixture(scope="module", autouse=True)
def ray_env() -> Iterator[None]:
    """Token authentication with a throwaway token (Ray would otherwise create ~/.ray/auth_token), no usage stats.

    Ray reads the authentication settings once, when imported: they are reloaded after each change of the environment.
    """
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("RAY_USAGE_STATS_ENABLED", "0")
        mp.setenv("RAY_AUTH_MODE", "token")
        mp.setenv("RAY_AUTH_TOKEN", secrets.token_hex(16))
        mp.delenv("RAY_AUTH_TOKEN_PATH", raising=False)
        mp.delenv("RAY_ADDRESS", raising=False)
        reset_auth_token_state()
        yield
    reset_auth_token_state()


@dataclass(frozen=True)
class Head:
    address: str
    process: subprocess.Popen[bytes]


@pytest.fixture(scope="module")
def head(ray_env: None) -> Iterator[Head]:
    """A one-node cluster of 2 CPUs in a subprocess: stopped by its pid, as `ray stop` would stop every Ray on the machine."""
    port, client_port = free_port(), free_port()
    temp_dir = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths live under it
    ray_cli = str(Path(sys.executable).with_name("ray"))
    command = [ray_cli, "start", "--head", "--block", "--num-cpus", "2", "--port", str(port), "--temp-dir", temp_dir]
    command += ["--ray-client-server-port", str(client_port), "--include-dashboard", "false", "--disable-usage-stats"]  # not 10001
    env = os.environ | {"RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S": "0"}  # stop now, not after draining for 30 s
    log = Path(temp_dir, "head.log")
    with log.open("w") as out:
        process = subprocess.Popen(command, env=env, stdout=out, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 60
        while True:
            try:
                socket.create_connection(("127.0.0.1", client_port), timeout=1).close()  # the client server starts last
                break
            except OSError:
                if process.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"ray start --head failed (exit {process.poll()}):\n{log.read_text()[-3000:]}") from None
                time.sleep(0.1)
        yield Head(f"127.0.0.1:{port}", process)
    finally:
        stop(process)
        shutil.rmtree(temp_dir, ignore_errors=True)


def test_local_instance_runs_every_job_in_the_venv_and_stops(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("RAY_ADDRESS", "192.0.2.1:1")  # ignored: no address means a local instance
    got = calls()
    run_on_ray(work, [Job(n) for n in range(5)], None, got.on_done, got.on_crash, num_cpus=2)
    assert got.done == {n: (n * n, sys.prefix) for n in range(5)}
    assert got.crashed == {}
    assert not ray.is_initialized()


def test_crashes_are_reported_per_job_and_the_cluster_is_left_running(head: Head) -> None:
    got = calls()
    jobs = [Job(0), Job(1, "raise"), Job(2), Job(3, "exit"), Job(4)]
    run_on_ray(work, jobs, head.address, got.on_done, got.on_crash)
    assert got.done == {n: (n * n, sys.prefix) for n in (0, 2, 4)}
    assert set(got.crashed) == {1, 3}
    raised = got.crashed[1]
    assert isinstance(raised, ValueError) and str(raised) == "boom 1"
    assert any('raise ValueError(f"boom {job.n}")' in note for note in getattr(raised, "__notes__", []))  # the worker's traceback
    assert isinstance(got.crashed[3], ray.exceptions.WorkerCrashedError)
    assert not ray.is_initialized()
    assert head.process.poll() is None


def test_ctrl_c_interrupts_running_tasks_and_cancels_the_rest(head: Head, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(ray_executor, "STOP_GRACE", 1.0)
    jobs = [Job(0), Job(1, "slow", str(tmp_path)), Job(2, "stuck", str(tmp_path)), Job(3, "slow", str(tmp_path))]
    got = calls()

    def on_done(job: Job, result: tuple[int, str]) -> None:
        got.on_done(job, result)
        threading.Timer(1.0, os.kill, (os.getpid(), signal.SIGINT)).start()  # Ctrl-C while jobs 1 and 2 run, 3 waits

    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        run_on_ray(work, jobs, head.address, on_done, got.on_crash)
    assert time.monotonic() - started < 20
    assert set(got.done) == {0} and got.crashed == {}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["cleanup-1-KeyboardInterrupt"]  # 2 was killed, 3 never started
    assert not ray.is_initialized()
    assert head.process.poll() is None


@pytest.mark.parametrize("address", ["127.0.0.1:{port}", "ray://127.0.0.1:{port}", "localhost"])
def test_bad_address_is_a_user_error_at_once(address: str) -> None:
    address = address.format(port=free_port())  # nothing listens there
    started = time.monotonic()
    with pytest.raises(UserError, match=address):
        run_on_ray(work, [Job(0)], address, calls().on_done, calls().on_crash)
    assert time.monotonic() - started < 3
    assert not ray.is_initialized()


def test_without_ray_installed(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "ray", None)  # `import ray` now raises ImportError
    with pytest.raises(UserError, match=r"pip install 'urdf-pipeline\[ray\]'"):
        run_on_ray(work, [Job(0)], None, calls().on_done, calls().on_crash)
