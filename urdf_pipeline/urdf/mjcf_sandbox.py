"""The child process that compiles one MJCF model with MuJoCo, bounded by rlimits (mjcf.py spawns it, checks every
file the model names first and kills it at the wall-clock bound), and answers its URDF text.

Protocol: one JSON request on stdin ({"file", "shown", "name", "limits"}), one JSON answer on stdout: {"text": URDF,
"notes": [geoms left undrawn]} or {"error": message}.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
from collections.abc import Mapping
from typing import Any

from ..process import limit_this_process


def compile_answer(request: Mapping[str, Any]) -> dict[str, Any]:
    """The answer for one request."""
    try:
        import mujoco
    except ImportError:
        return {"error": "MJCF robots need the mujoco package: pip install 'urdf-pipeline[mjcf]'"}
    from .mjcf_urdf import NotRepresentable, urdf_from_model

    megabytes = request["limits"]["memory_bytes"] >> 20
    try:
        model = mujoco.MjModel.from_xml_path(request["file"])
    except ValueError as exc:  # MuJoCo's compile errors: the message names the element and the line
        text = " ".join(str(exc).split())
        if "Could not allocate memory" in text:
            return {
                "error": f"compiling {request['shown']} with MuJoCo needs more than {megabytes} MB of memory ({text[:300]}); the person running the tool can raise the bound with URDF_PIPELINE_MJCF_MEMORY_MB"
            }
        return {"error": f"MuJoCo cannot compile {request['shown']}: {text[:2000]}"}
    except RuntimeError as exc:  # a C++ exception MuJoCo's binding does not name: std::bad_alloc under the memory bound
        return {
            "error": f"compiling {request['shown']} with MuJoCo failed ({exc}): it may need more than {megabytes} MB of memory; the person running the tool can raise the bound with URDF_PIPELINE_MJCF_MEMORY_MB"
        }
    try:
        text, notes = urdf_from_model(model, mujoco, request["name"], os.path.dirname(request["file"]))
    except NotRepresentable as exc:
        return {"error": f"{request['shown']} cannot be drawn as a URDF robot: {exc}"}
    return {"text": text, "notes": notes}


def main() -> None:
    """Entry point of the child process."""
    request = json.load(sys.stdin)
    limit_this_process(request["limits"])
    try:
        with contextlib.redirect_stdout(sys.stderr):  # MuJoCo's own prints are not the answer
            answer = compile_answer(request)
    except MemoryError:
        answer = {"error": f"compiling {request['shown']} needs more than {request['limits']['memory_bytes'] >> 20} MB of memory"}
    json.dump(answer, sys.stdout)
    sys.stdout.flush()
