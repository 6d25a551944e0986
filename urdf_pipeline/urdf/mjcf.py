"""`urdf: {mjcf: FILE}`: a MuJoCo model (MJCF XML) turned into URDF text, so every later stage works unchanged.

MuJoCo itself compiles the model (defaults classes, every orientation form, angle units, includes, frames), in a bounded
child process (mjcf_sandbox), once every file the model names passed the config's read rule and its size was counted
(mjcf_files). `mujoco` is an optional dependency: without it the form is refused, saying how to install it.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from ..confine import Confinement
from ..errors import UserError, Where, listing, shown, warn
from ..process import ChildOutcome, bound_from_environment, passed_environment, run_bounded_child, sandboxed_python
from .mjcf_files import scan_mjcf

MEMORY_ENV = "URDF_PIPELINE_MJCF_MEMORY_MB"  # the runner may raise the bounds for a huge model; a config cannot
TIMEOUT_ENV = "URDF_PIPELINE_MJCF_TIMEOUT"
DEFAULT_MEMORY_MB = 4096  # address space: MuJoCo reserves its arena (dm_control's rodent needs more than 2 GB)
DEFAULT_TIMEOUT_S = 60.0
OUTPUT_BYTES = 64 << 20
INSTALL = "pip install 'urdf-pipeline[mjcf]'"
_PASSED_ENV = ("LD_LIBRARY_PATH", "DYLD_LIBRARY_PATH", "SYSTEMROOT")


def load_mjcf(path: Path, written: str, confinement: Confinement, where: Where) -> str:
    """The URDF text of the MJCF file at `path` (allowed, `written` as the config names it), or a UserError at `where`."""
    scan_mjcf(path, confinement, where)
    try:
        command = sandboxed_python("urdf_pipeline.urdf.mjcf_sandbox", "mujoco", "numpy")
    except ImportError as exc:
        raise UserError(f"MJCF robots need the {exc.args[0]} package: {INSTALL}", where) from None
    memory_mb = int(bound_from_environment(MEMORY_ENV, DEFAULT_MEMORY_MB, where))
    timeout = bound_from_environment(TIMEOUT_ENV, DEFAULT_TIMEOUT_S, where)
    request = {
        "file": str(path),
        "shown": written,
        "name": path.name.removesuffix(".xml"),
        "limits": {"memory_bytes": memory_mb << 20, "cpu_seconds": int(timeout) + 1, "output_bytes": OUTPUT_BYTES},
    }
    environment = passed_environment(_PASSED_ENV, OPENBLAS_NUM_THREADS="1")  # each BLAS thread reserves address space
    # In a folder of its own: MuJoCo writes MUJOCO_LOG.TXT into the working folder, never into the user's (and every
    # path it reads is absolute, so none is relative to ours).
    try:
        with tempfile.TemporaryDirectory() as folder:
            outcome = run_bounded_child(
                command, request, timeout_s=timeout, env=environment, answer_bytes=OUTPUT_BYTES + (1 << 20), cwd=folder
            )
    except OSError as exc:
        raise UserError(f"cannot compile {written}: {exc}", where) from None
    answer = outcome.answer
    if answer is None or not ("text" in answer or "error" in answer):
        raise UserError(_failure(written, memory_mb, timeout, outcome), where)
    if "error" in answer:
        raise UserError(str(answer["error"]), where)
    notes = [str(note) for note in answer.get("notes", [])]
    if notes:
        warn(f"{written}: {len(notes)} geom(s) a URDF cannot draw are left out: {listing(notes, limit=5)}", where)
    return str(answer["text"])


def _failure(model: str, memory_mb: int, timeout: float, outcome: ChildOutcome) -> str:
    """Why the child gave no answer (`run_bounded_child`'s kind), in MuJoCo's words."""
    compiling, raise_it = f"compiling {shown(model)} with MuJoCo", "the person running the tool can raise the bound with"
    return {
        "time": f"{compiling} did not end within {timeout:g} s and was stopped; {raise_it} {TIMEOUT_ENV}",
        "cpu": f"{compiling} used more than {timeout:g} s of CPU time and was stopped; {raise_it} {TIMEOUT_ENV}",
        "memory": f"{compiling} needs more than {memory_mb} MB of memory; {raise_it} {MEMORY_ENV}",
        "oversized": f"{compiling} gave more than {OUTPUT_BYTES >> 20} MB of URDF text",
    }.get(outcome.kind, f"{compiling} failed ({outcome.status})" + (f": {shown(outcome.last)}" if outcome.last else ""))
