"""`run --spawn` / `run --connect URL`: the run's recordings sent to a Rerun viewer (the command line has checked,
before the run, that one listens at the URL: `process/rerun_viewer.py`).

One RecordingStream per segment, with the config's application id and the segment's recording id, so the viewer
merges what it receives into that segment (a layer lands on its base episode instead of opening beside it). In
the split layout the model's chunks are sent with every segment: each episode shows the robot moving.
"""

from __future__ import annotations

from ..errors import UserError
from ..plan import Plan
from .blueprint import recording_blueprint
from .segment_run import SegmentResult


def send_to_viewer(plan: Plan, results: tuple[SegmentResult, ...], url: str) -> int:
    """Send every written or up-to-date segment to the viewer at `url`; returns how many were sent."""
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
            stream.connect_grpc(url, default_blueprint=blueprint)
            if model_store is not None:
                stream.send_chunks(model_store)
            stream.send_chunks(RrdReader(result.output).store())
            stream.flush()
        except (RuntimeError, ValueError, OSError) as exc:
            raise UserError(f"cannot send {result.label} to the viewer at {url}: {exc}") from None
        finally:
            stream.disconnect()
        sent += 1
    return sent
