"""`run --spawn` / `run --connect URL`: the run's recordings sent to a Rerun viewer (the command line has checked,
before the run, that one listens at the URL: `cli/viewer_target.py`).

One RecordingStream per segment, with the config's application id and the segment's recording id, so the viewer
merges what it receives into that segment (a layer lands on its base episode instead of opening beside it). In
the split layout the model's chunks are sent with every segment: each episode shows the robot moving.
"""

from __future__ import annotations

import importlib.util
import os
import shutil
import sys
from pathlib import Path

from ..errors import UserError
from ..plan import Plan
from .blueprint import recording_blueprint
from .segment_run import SegmentResult

DEFAULT_VIEWER_URL = "rerun+http://127.0.0.1:9876/proxy"


def viewer_binary() -> str | None:
    """The viewer that ships in rerun-sdk (rerun_cli's binary: the release of the SDK that sends, not the Python shim
    that would start it), else a `rerun` beside this Python, else one on PATH; None when there is none."""
    executable = "rerun.exe" if sys.platform.startswith("win") else "rerun"
    spec = importlib.util.find_spec("rerun_cli")
    candidates = [Path(spec.origin).parent / executable] if spec is not None and spec.origin else []
    candidates.append(Path(sys.executable).parent / executable)
    for candidate in candidates:
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return str(candidate)
    return shutil.which(executable)


def send_to_viewer(plan: Plan, results: tuple[SegmentResult, ...], url: str | None) -> int:
    """Send every written or up-to-date segment to the viewer at `url` (default: the local viewer's port); returns how
    many were sent."""
    import rerun as rr
    from rerun.chunk import RrdReader

    usable = [r for r in results if r.status in ("written", "skipped")]
    model = next((r.output for r in usable if r.label == "model"), None)
    model_store = RrdReader(model).store() if model is not None else None
    blueprint = recording_blueprint(plan)
    sent = 0
    for result in (r for r in usable if r.label != "model"):
        stream = rr.RecordingStream(plan.application_id, recording_id=result.label, send_properties=False)
        try:
            stream.connect_grpc(url or DEFAULT_VIEWER_URL, default_blueprint=blueprint)
            if model_store is not None:
                stream.send_chunks(model_store)
            stream.send_chunks(RrdReader(result.output).store())
            stream.flush()
        except (RuntimeError, ValueError, OSError) as exc:
            raise UserError(f"cannot send {result.label} to the viewer at {url or DEFAULT_VIEWER_URL}: {exc}") from None
        finally:
            stream.disconnect()
        sent += 1
    return sent
