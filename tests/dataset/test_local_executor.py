"""The local executor's worker processes: they leave pandas out when the run's own process does, and stopping the pool
stops every one of them."""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import forkserver
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest

from urdf_pipeline.dataset.local_executor import PRELOAD, _start_fork_server, _start_worker, _terminate, run_locally
from urdf_pipeline.package import PandasLeftOut

WAIT = 120.0  # seconds a state may take to come; a bound against hangs, not a measurement


def _pandas_after_an_array(job: int) -> tuple[int, bool]:
    time.sleep(0.2)  # long enough that the workers, not only this process, take jobs
    pa.array(np.zeros(3))  # pyarrow's first numpy array imports pandas when it can
    return os.getpid(), "pandas" in sys.modules


def test_workers_leave_pandas_out_as_the_run_does() -> None:
    finder = PandasLeftOut()
    sys.meta_path.insert(0, finder)  # type: ignore[arg-type]
    results: list[tuple[int, bool]] = []
    try:
        run_locally(
            _pandas_after_an_array,
            list(range(16)),
            2,
            lambda job, result: results.append(result),
            lambda job, error: results.append((0, True)),
        )
    finally:
        sys.meta_path.remove(finder)  # type: ignore[arg-type]
    in_workers = [loaded for pid, loaded in results if pid != os.getpid()]
    assert len(results) == 16 and in_workers
    assert not any(in_workers)


def test_the_fork_server_ignores_ctrl_c_and_sigterm_from_its_first_instruction() -> None:
    """A terminal's Ctrl-C reaches the whole process group, the fork server too, while it imports Rerun: it must
    ignore SIGINT and SIGTERM from its start (inherited across exec), or it prints a traceback. Linux: /proc."""
    import subprocess

    code = (
        "import multiprocessing, re\n"
        "from urdf_pipeline.dataset.local_executor import PRELOAD, _start_fork_server\n"
        "multiprocessing.get_context('forkserver').set_forkserver_preload(PRELOAD)\n"
        "_start_fork_server()\n"
        "from multiprocessing import forkserver\n"
        "status = open(f'/proc/{forkserver._forkserver._forkserver_pid}/status').read()\n"
        "print(int(re.search(r'SigIgn:\\s*([0-9a-f]+)', status).group(1), 16))\n"
    )
    ignored = int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert ignored & (1 << (2 - 1)) and ignored & (1 << (15 - 1)), f"SigIgn {ignored:x}: SIGINT and SIGTERM must be ignored"


def _sleep(seconds: float) -> None:
    time.sleep(seconds)


def _waiting_in(thread: threading.Thread, function: str) -> bool:
    """Whether `thread` is inside `function` now (its Python stack)."""
    frame = sys._current_frames().get(thread.ident or 0)
    while frame is not None:
        if frame.f_code.co_name == function:
            return True
        frame = frame.f_back
    return False


def _state(pid: int | None) -> str:
    """The process's state letter in /proc (Z: a zombie, exited but not reaped)."""
    return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]


def _until(condition: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + WAIT
    while not condition():
        assert time.monotonic() < deadline, f"gave up waiting for {what}"
        time.sleep(0.01)


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc to see a worker killed")
def test_stopping_the_pool_kills_a_worker_started_meanwhile(tmp_path: Path) -> None:
    """SIGTERM or Ctrl-C while a worker is being started (a `submit` waiting for the fork server): that worker is
    killed too. Left alive it hung the run at exit: the pool's manager thread, finding a killed worker, stops the
    others with SIGTERM (which they ignore) and joins them, and the interpreter joins that thread. The fork server is
    stopped (SIGSTOP) until the first worker is killed, so the second one starts after the pool was told to stop.
    Linux: /proc."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    _start_fork_server()
    pool = ProcessPoolExecutor(2, mp_context=context, initializer=_start_worker, initargs=(None, (), str(tmp_path), os.getpid(), False))
    fork_server = forkserver._forkserver._forkserver_pid
    processes = pool._processes  # type: ignore[attr-defined]
    manager: threading.Thread | None = None
    try:
        pool.submit(_sleep, WAIT)  # the first worker, busy: the next job needs a second one
        _until(lambda: len(processes) == 1, "the first worker")
        manager = pool._executor_manager_thread  # type: ignore[attr-defined]
        os.kill(fork_server, signal.SIGSTOP)
        starting = threading.Thread(target=lambda: pool.submit(_sleep, WAIT), daemon=True)
        starting.start()
        _until(lambda: _waiting_in(starting, "_spawn_process"), "the second worker's start to wait for the fork server")
        first = next(iter(processes.values()))
        stopping = threading.Thread(target=_terminate, args=(pool,), daemon=True)
        stopping.start()
        _until(lambda: _state(first.pid) == "Z", "the first worker to be killed")  # its parent, stopped, reaps it later
        os.kill(fork_server, signal.SIGCONT)
        stopping.join(WAIT)
        assert len(processes) == 2, "the second worker was started"
        assert not [p.pid for p in processes.values() if p.is_alive()], "a worker outlived the pool"
        assert manager is not None
        manager.join(WAIT)
        assert not manager.is_alive(), "the pool's manager thread hangs joining a worker"
    finally:
        os.kill(fork_server, signal.SIGCONT)
        for process in list(processes.values()):
            process.kill()
