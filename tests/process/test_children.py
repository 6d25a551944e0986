"""The one runner of a bounded child (`process.run_bounded_child`), with children written here as `python -c`."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from urdf_pipeline.process.children import ChildOutcome, run_bounded_child

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups and /proc: Linux")


def run(code: str, *, timeout_s: float = 20.0, answer_bytes: int = 1 << 20, stop_on: re.Pattern[str] | None = None) -> ChildOutcome:
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    return run_bounded_child(
        [sys.executable, "-c", code], {"n": 1}, timeout_s=timeout_s, env=env, answer_bytes=answer_bytes, stop_on=stop_on
    )


def alive(pid: int) -> bool:
    """Whether `pid` runs (a zombie is dead: it only waits for its parent to reap it)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, IndexError):
        return False


def gone(pids: list[int], within: float = 10.0) -> bool:
    end = time.monotonic() + within  # a hang guard, not a timing
    while any(map(alive, pids)) and time.monotonic() < end:
        time.sleep(0.05)
    return not any(map(alive, pids))


def test_the_answer_is_the_last_stdout_line_and_the_request_comes_on_stdin() -> None:
    outcome = run("import json, sys; r = json.load(sys.stdin); print('noise'); print(json.dumps({'got': r, 'pad': 'x' * 500000}))")
    assert outcome.kind == "answered" and outcome.answer is not None and outcome.answer["got"] == {"n": 1}  # over a pipe's 64 KiB


def test_a_child_beyond_its_memory_bound() -> None:
    limits = "{'memory_bytes': 200 << 20, 'cpu_seconds': 10, 'output_bytes': 1 << 20}"
    outcome = run(f"from urdf_pipeline.process.children import limit_this_process as l; l({limits}); b = bytearray(1 << 30)")
    assert outcome.kind == "memory" and outcome.answer is None and "MemoryError" in outcome.last


def test_a_child_sleeping_past_its_time_is_stopped() -> None:
    started = time.monotonic()
    outcome = run("import time; time.sleep(60)", timeout_s=0.5)
    assert outcome.kind == "time" and time.monotonic() - started < 10


def test_a_100_mb_answer_is_stopped_at_its_bound() -> None:
    outcome = run("import sys; sys.stdout.buffer.write(b'x' * (100 << 20))", answer_bytes=1 << 20)
    assert outcome.kind == "oversized" and outcome.answer is None


def test_a_child_killed_by_a_signal() -> None:
    outcome = run("import os, signal; os.kill(os.getpid(), signal.SIGUSR1)")
    assert outcome.kind == "failed" and outcome.code == -signal.SIGUSR1 and outcome.status == f"signal {signal.SIGUSR1.value}"


def test_garbage_is_no_answer_and_a_failure_keeps_stderr_s_last_line() -> None:
    assert run("print('{not json')").kind == "no answer"
    failed = run("import sys; print('first', file=sys.stderr); sys.exit('the \\x1b[31mlast\\x1b[0m line')")
    assert failed.kind == "failed" and failed.status == "exit status 1" and failed.last == "the last line"


def test_a_stderr_line_matching_stop_on_stops_the_child() -> None:
    outcome = run(
        "import sys, time; print('ERROR mcap: bad chunk', file=sys.stderr, flush=True); time.sleep(60)", stop_on=re.compile("ERROR")
    )
    assert outcome.kind == "stopped" and outcome.stopped_by == "ERROR mcap: bad chunk"


PARENT = """
import os, signal, subprocess, sys
from urdf_pipeline.process.children import run_bounded_child
if sys.argv[2] == "handled":  # as the CLI does: SIGTERM becomes an exception
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
child = ("import os, signal, subprocess, sys, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
         "g = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(60)']); "
         "open(sys.argv[1], 'w').write(f'{os.getpid()} {g.pid}'); time.sleep(60)")
run_bounded_child([sys.executable, "-c", child, sys.argv[1]], None, timeout_s=60, env=dict(os.environ), answer_bytes=1024)
"""


@pytest.mark.parametrize("parent", ["handled", "default"])
def test_sigterm_to_the_parent_leaves_no_child(tmp_path: Path, parent: str) -> None:
    """The child ignores SIGTERM and starts a grandchild: a parent that handles SIGTERM kills the whole group; one that
    dies of it takes its child along (PR_SET_PDEATHSIG; the readers' children may start no process of their own)."""
    pids = tmp_path / "pids"
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    process = subprocess.Popen([sys.executable, "-c", PARENT, str(pids), parent], env=env)
    end = time.monotonic() + 20
    while not (pids.exists() and len(pids.read_text().split()) == 2) and time.monotonic() < end:
        time.sleep(0.05)
    child, grandchild = map(int, pids.read_text().split())
    process.send_signal(signal.SIGTERM)
    assert process.wait(10) in (143, -signal.SIGTERM)
    assert gone([child] if parent == "default" else [child, grandchild])
    if parent == "default" and alive(grandchild):  # only its own child dies with it: the readers may start none
        os.kill(grandchild, signal.SIGKILL)
