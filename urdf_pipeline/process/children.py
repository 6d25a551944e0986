"""The child processes the tool starts, each in a session of its own, dying with this process, and stopped whole; and
the one runner of a child that reads a stranger's file (the xacro, MJCF and MCAP readers), with the bounds it sets on
itself, which only the person running the tool may change (from the environment, never a config)."""

from __future__ import annotations

import collections
import contextlib
import importlib.util
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Literal

from ..errors import UserError, Where, shown
from .signals import held_off


def die_with_parent(sent: int = signal.SIGTERM) -> Callable[[], None] | None:
    """A `preexec_fn` for Linux: the child gets `sent` when this process dies, even by SIGKILL (prctl
    PR_SET_PDEATHSIG), so no viewer or reader outlives a killed command. None elsewhere."""
    if not sys.platform.startswith("linux"):
        return None
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)  # loaded here, in the parent: the child only calls it

    def arrange() -> None:
        libc.prctl(1, sent)

    return arrange


def stop_session(process: subprocess.Popen[bytes]) -> None:
    """SIGTERM to the child's session, SIGKILL after 5 s, with Ctrl-C and SIGTERM held off meanwhile (a second Ctrl-C
    must not leave the child running)."""
    with held_off():
        for sent in (signal.SIGTERM, signal.SIGKILL):
            if process.poll() is not None:
                return
            try:
                os.killpg(process.pid, sent)
            except ProcessLookupError:
                return
            with contextlib.suppress(subprocess.TimeoutExpired):
                process.wait(5.0)


def limit_this_process(limits: Mapping[str, int], threads: bool = False) -> None:
    """Bound this process before it reads a stranger's file: address space, CPU seconds, the size of any file written
    (stdout is one), no core dump, and no child process, nor (unless `threads`: Rerun's reader runs its own) thread:
    Linux counts both against RLIMIT_NPROC."""
    import resource

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # an oversized write fails (EFBIG) instead of killing silently
    bounds = [
        (resource.RLIMIT_AS, limits["memory_bytes"]),
        (resource.RLIMIT_CPU, limits["cpu_seconds"]),
        (resource.RLIMIT_FSIZE, limits["output_bytes"]),
        (resource.RLIMIT_CORE, 0),
    ]
    if not threads:
        bounds.append((resource.RLIMIT_NPROC, 0))
    for kind, value in bounds:
        with contextlib.suppress(ValueError, OSError):  # a limit the platform lacks or refuses stays as it was
            resource.setrlimit(kind, (value, value))


def bound_from_environment(name: str, default: float, where: Where | None = None) -> float:
    """A positive number the person running the tool may set in the environment variable `name` to raise (or lower) a
    child's bound; `default` when unset. A UserError at `where`, naming the variable, for anything else (NaN too)."""
    text = os.environ.get(name, "").strip()
    if not text:
        return default
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value > 0 or value == float("inf"):
        raise UserError(f"{name}='{shown(text)}' must be a positive number", where)
    return value


ANSI_ESCAPE = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")  # colours and cursor moves in a native program's lines
OUT_OF_MEMORY = re.compile(
    r"MemoryError|memory allocation of|unable to allocate|out of memory|bad_alloc|cannot allocate|failed to map segment", re.IGNORECASE
)
MEMORY_SIGNALS = (-signal.SIGSEGV, -signal.SIGABRT, -signal.SIGBUS)  # how running out of address space also ends a child
KEPT_LINES = 20  # of what the child printed last on stderr
Kind = Literal["answered", "stopped", "oversized", "time", "cpu", "memory", "failed", "no answer"]


@dataclass(frozen=True)
class ChildOutcome:
    """How a bounded child ended: `kind` says why, `answer` is its JSON object when it `answered`."""

    kind: Kind
    code: int  # its exit status, negative for a signal
    answer: dict[str, Any] | None
    head: bytes  # the first `stderr_bytes` + 1 bytes it printed on stderr (a reader's own warnings)
    lines: tuple[str, ...]  # the last lines it printed on stderr, without colours, each at most 500 characters
    stopped_by: str | None = None  # the stderr line that matched `stop_on`

    @property
    def status(self) -> str:
        return f"signal {-self.code}" if self.code < 0 else f"exit status {self.code}"

    @property
    def last(self) -> str:
        return self.lines[-1] if self.lines else ""


def passed_environment(names: Iterable[str], **extra: str) -> dict[str, str]:
    """Only the variables `names` of this process's environment, and `extra`: what a sandboxed child may see."""
    return {name: os.environ[name] for name in names if name in os.environ} | extra


def sandboxed_python(module: str, *needs: str) -> list[str]:
    """The command of an isolated Python child (`-I -S`: no user site, no .pth files, no PYTHON* variables) running
    `module`'s main(), importing urdf_pipeline and the packages `needs` from where this process finds them (it has no
    site-packages). ImportError naming the first of `needs` that is not installed."""
    folders = [str(Path(__file__).resolve().parents[2])]  # the folder holding the urdf_pipeline package
    for name in needs:
        spec = importlib.util.find_spec(name)
        if spec is None or not spec.submodule_search_locations:
            raise ImportError(name)
        folders.append(str(Path(next(iter(spec.submodule_search_locations))).parent))
    bootstrap = f"import sys; sys.path[:0] = sys.argv[1:]; from {module} import main; main()"
    return [sys.executable, "-I", "-S", "-X", "utf8", "-c", bootstrap, *dict.fromkeys(folders)]


def run_bounded_child(
    command: Sequence[str],
    request: object | None,
    *,
    timeout_s: float,
    env: Mapping[str, str],
    answer_bytes: int,
    cwd: str | None = None,
    stop_on: re.Pattern[str] | None = None,
    stderr_bytes: int = 16 << 10,
) -> ChildOutcome:
    """Run `command` (which bounds itself: `limit_this_process`) with `request` as JSON on its stdin, in a session of
    its own that dies with this process, and return its last stdout line's JSON object, or why there is none. Both its
    outputs are read while it runs (so it never blocks on a full pipe), each within its bound; it is stopped at
    `timeout_s` s of wall clock, at an answer over `answer_bytes`, at a stderr line matching `stop_on`, and on any
    exception here (Ctrl-C, SIGTERM): its whole process group is killed before this returns or raises."""
    with tempfile.TemporaryFile() as stdin:
        if request is not None:
            stdin.write(json.dumps(request).encode("utf-8"))
            stdin.seek(0)
        child = subprocess.Popen(
            command,
            stdin=stdin if request is not None else subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            env=env,
            cwd=cwd,
            start_new_session=True,
            preexec_fn=die_with_parent(signal.SIGKILL),
        )
    output = _Output(answer_bytes, stderr_bytes, stop_on)
    assert child.stdout is not None and child.stderr is not None  # both are pipes
    readers = [threading.Thread(target=output.drain, args=(child.stdout,), daemon=True)]
    readers.append(threading.Thread(target=output.watch, args=(child.stderr,), daemon=True))
    for reader in readers:
        reader.start()
    deadline = time.monotonic() + timeout_s
    timed_out = False
    try:
        while child.poll() is None and not output.stop.wait(0.05):
            timed_out = time.monotonic() > deadline
            if timed_out:
                break
    finally:
        with held_off():  # a second Ctrl-C waits
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(child.pid, signal.SIGKILL)  # the whole group, even once the child itself has ended
            child.wait()
            for reader in readers:
                reader.join(timeout=5)
            child.stdout.close()
            child.stderr.close()
    return output.outcome(child.returncode, timed_out)


class _Output:
    """What a bounded child printed, read while it runs (by two threads), each output within its bound."""

    def __init__(self, answer_bytes: int, stderr_bytes: int, stop_on: re.Pattern[str] | None) -> None:
        self.answer_bytes, self.stderr_bytes, self.stop_on = answer_bytes, stderr_bytes, stop_on
        self.stop = threading.Event()
        self.answer = bytearray()
        self.over = False
        self.head = bytearray()
        self.lines: collections.deque[str] = collections.deque(maxlen=KEPT_LINES)
        self.matched: str | None = None

    def drain(self, stream: IO[bytes]) -> None:
        for piece in iter(lambda: stream.read(1 << 16), b""):
            if len(self.answer) + len(piece) > self.answer_bytes:
                self.over = True
                self.stop.set()
                return
            self.answer += piece

    def watch(self, stream: IO[bytes]) -> None:
        for raw in iter(lambda: stream.readline(1 << 13), b""):
            if len(self.head) <= self.stderr_bytes:
                self.head.extend(raw[: self.stderr_bytes + 1 - len(self.head)])
            line = ANSI_ESCAPE.sub("", raw.decode("utf-8", "replace")).strip()[:500]
            if self.stop_on is not None and self.matched is None and self.stop_on.search(line):
                self.matched = line
                self.stop.set()
            if line:
                self.lines.append(line)

    def outcome(self, code: int, timed_out: bool) -> ChildOutcome:
        output = self.answer  # its last line (JSON allows the newline after it), not copied when it is the only one
        start = output.rfind(b"\n", 0, len(output.rstrip(b"\n"))) + 1
        try:
            parsed = json.loads(output[start:] if start else output) if output.strip() else None
        except ValueError:  # UnicodeDecodeError too
            parsed = None
        parsed = parsed if isinstance(parsed, dict) else None
        kind: Kind = "answered" if parsed is not None else "no answer"
        if self.matched is not None or self.over or timed_out:
            kind = "stopped" if self.matched is not None else "oversized" if self.over else "time"
        elif code in (-signal.SIGXCPU, -signal.SIGKILL):
            kind = "cpu"
        elif code != 0:
            kind = "memory" if code in MEMORY_SIGNALS or any(map(OUT_OF_MEMORY.search, self.lines)) else "failed"
        return ChildOutcome(kind, code, parsed if kind == "answered" else None, bytes(self.head), tuple(self.lines), self.matched)
