"""Expand a xacro file from an untrusted config in a bounded child process (the sandbox is xacro_sandbox).

The child gets no environment but ROS_PACKAGE_PATH / AMENT_PREFIX_PATH (and the loader's library path), runs with
`-I -S` (no user site, no .pth files, no PYTHON* variables), is limited in address space, CPU seconds and output size,
and is killed when the wall clock runs out. Every way it can fail ends in a UserError naming the xacro file.
"""

from __future__ import annotations

import importlib.util
import json
import os
import signal
import subprocess
import sys
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from ..confine import Confinement
from ..errors import UserError, Where

MEMORY_ENV = "URDF_PIPELINE_XACRO_MEMORY_MB"  # the runner may raise the bounds for a huge robot; a config cannot
TIMEOUT_ENV = "URDF_PIPELINE_XACRO_TIMEOUT"
DEFAULT_MEMORY_MB = 1024
DEFAULT_TIMEOUT_S = 60.0
OUTPUT_BYTES = 64 << 20  # the expanded URDF text, at most
SHOWN_STDERR = 16 << 10  # xacro's own warnings passed on, at most
_PASSED_ENV = ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH", "LD_LIBRARY_PATH", "DYLD_LIBRARY_PATH", "SYSTEMROOT")
_BOOTSTRAP = "import sys; sys.path[:0] = sys.argv[1:]; from urdf_pipeline.urdf.xacro_sandbox import main; main()"


@dataclass(frozen=True)
class XacroRequest:
    file: Path  # resolved, already allowed by the confinement
    shown: str  # as the config writes it
    args: Mapping[str, str]
    package_paths: Mapping[str, Path]
    confinement: Confinement


@dataclass(frozen=True)
class Limits:
    memory_mb: int
    timeout_s: float

    @staticmethod
    def from_environment(where: Where | None) -> Limits:
        def number(name: str, default: float) -> float:
            text = os.environ.get(name, "")
            try:
                value = float(text) if text else default
            except ValueError:
                value = -1.0
            if value <= 0:
                raise UserError(f"{name}={text!r} must be a positive number", where)
            return value

        return Limits(int(number(MEMORY_ENV, DEFAULT_MEMORY_MB)), number(TIMEOUT_ENV, DEFAULT_TIMEOUT_S))


def _search_path() -> list[str]:
    """The folders the child imports urdf_pipeline, xacro and yaml from (it runs without site-packages)."""
    folders = [str(Path(__file__).resolve().parents[2])]  # the folder holding the urdf_pipeline package
    for module in ("xacro", "yaml"):
        spec = importlib.util.find_spec(module)
        if spec is None or not spec.submodule_search_locations:
            raise ImportError(module)
        folders.append(str(Path(next(iter(spec.submodule_search_locations))).parent))
    return list(dict.fromkeys(folders))


def expand_xacro(request: XacroRequest, where: Where | None) -> str:
    """The URDF text of `request.file` expanded with its args, or a UserError at `where` naming the xacro file."""
    limits = Limits.from_environment(where)
    try:
        search = _search_path()
    except ImportError as exc:
        raise UserError(f"expanding {request.shown} needs the {exc.args[0]} package: pip install xacro", where) from None
    payload = {
        "file": str(request.file),
        "shown": request.shown,
        "args": dict(request.args),
        "packages": {name: str(path) for name, path in request.package_paths.items()},
        "config_dir": str(request.confinement.config_dir),
        "read_roots": [str(root) for root in request.confinement.read_roots],
        "limits": {
            "memory_bytes": limits.memory_mb << 20,
            "cpu_seconds": int(limits.timeout_s) + 1,
            "output_bytes": OUTPUT_BYTES + (1 << 20),
        },
    }
    try:
        answer = _run([sys.executable, "-I", "-S", "-X", "utf8", "-c", _BOOTSTRAP, *search], payload, request, limits, where)
    except OSError as exc:  # no process, no temporary file: still about expanding this file
        raise UserError(f"cannot expand {request.shown}: {exc}", where) from None
    if "error" in answer:
        raise UserError(str(answer["error"]), where)
    return str(answer["text"])


def _run(command: list[str], payload: dict[str, Any], request: XacroRequest, limits: Limits, where: Where | None) -> dict[str, Any]:
    """The child's answer; the child is gone when this returns or raises (killed at the time bound, or on Ctrl-C)."""
    environment = {name: os.environ[name] for name in _PASSED_ENV if name in os.environ}
    with tempfile.TemporaryFile() as out, tempfile.TemporaryFile() as err:
        child = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=out, stderr=err, env=environment, close_fds=True)
        try:
            child.communicate(json.dumps(payload).encode("utf-8"), timeout=limits.timeout_s)
        except subprocess.TimeoutExpired:
            raise UserError(
                f"xacro expansion of {request.shown} did not end within {limits.timeout_s:g} s and was stopped (a macro or "
                f"expression that never ends?); the person running the tool can raise the bound with {TIMEOUT_ENV}",
                where,
            ) from None
        except BrokenPipeError:
            pass  # the child ended before reading: its exit status says why
        finally:
            if child.poll() is None:
                child.kill()
            child.wait()
        answer = _answer(out)
        if answer is None:
            raise UserError(_failure(request, limits, child.returncode, err), where)
        _pass_on(err)
        return answer


def _answer(out: IO[bytes]) -> dict[str, Any] | None:
    out.seek(0)
    data = out.read(OUTPUT_BYTES + (2 << 20))
    try:
        answer = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError):
        return None
    return answer if isinstance(answer, dict) and ("text" in answer or "error" in answer) else None


def _failure(request: XacroRequest, limits: Limits, code: int, err: IO[bytes]) -> str:
    """Why the child gave no answer, from its exit status and the last line it printed."""
    err.seek(0)
    lines = err.read(SHOWN_STDERR).decode("utf-8", "replace").strip().splitlines()
    last = f": {lines[-1][:500]}" if lines else ""
    if code in (-signal.SIGXCPU, -signal.SIGKILL):
        return (
            f"xacro expansion of {request.shown} used more than {limits.timeout_s:g} s of CPU time and was stopped (a macro "
            f"or expression that never ends?); the person running the tool can raise the bound with {TIMEOUT_ENV}"
        )
    # Out of address space shows as MemoryError, a crash, or a shared library that cannot be mapped while importing.
    if "MemoryError" in last or "failed to map segment" in last or "cannot allocate memory" in last.lower() or code == -signal.SIGSEGV:
        return (
            f"xacro expansion of {request.shown} needs more than {limits.memory_mb} MB of memory (a property or macro "
            f"that grows without end?); the person running the tool can raise the bound with {MEMORY_ENV}"
        )
    if "File too large" in last or "EFBIG" in last:
        return f"xacro expansion of {request.shown} is larger than {OUTPUT_BYTES >> 20} MB of URDF text"
    status = f"signal {-code}" if code < 0 else f"exit status {code}"
    return f"xacro expansion of {request.shown} failed ({status}){last}"


def _pass_on(err: IO[bytes]) -> None:
    """xacro's own warnings (deprecations, unknown attributes), as it would have printed them, shortened."""
    err.seek(0)
    data = err.read(SHOWN_STDERR + 1)
    if data:
        text = data[:SHOWN_STDERR].decode("utf-8", "replace")
        sys.stderr.write(text if text.endswith("\n") else text + "\n")
        if len(data) > SHOWN_STDERR:
            sys.stderr.write(f"(xacro printed more; the first {SHOWN_STDERR >> 10} KB are shown)\n")
