"""The run's per-segment progress lines (one long segment's meter: tests/execute/test_progress_meter.py)."""

from __future__ import annotations

import io
from types import SimpleNamespace

from urdf_pipeline.logs import SegmentProgress


def test_a_segment_line_shows_a_hostile_label_and_reason_escaped() -> None:
    """The plain per-segment line (stderr not a terminal): a segment id from a file name, a reason quoting a joint name."""
    stream = io.StringIO()
    progress = SegmentProgress(stream)
    progress.start(total=1, frames_expected=0, skipped=0)
    result = SimpleNamespace(label="::error::ep\x1b[2J", status="failed", frames=0, seconds=0.5, reason="joint 'a\r::warning::b'\nmore")
    progress.done(result, None)
    assert stream.getvalue() == "urdf-pipeline: [1/1] ::error::ep\\x1b[2J failed (0 frames, 0.5 s): joint 'a\n"  # its first line only
