"""The recording a live view sends to when the caller gives none: to a viewer (spawned here, or at a URL) and/or a
file, with the config's application id."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rerun import RecordingStream

SPAWNED_VIEWER = "rerun+http://127.0.0.1:9876/proxy"  # where `rerun.spawn()` starts Rerun's viewer


def live_recording(application_id: str, spawn: bool, connect: str | None, save: str | os.PathLike[str] | Path | None) -> RecordingStream:
    """A new recording whose sinks are a viewer started now (`spawn`; one already there is used), the viewer at
    `connect`, and the file `save`, as asked."""
    import rerun as rr

    sinks: list[Any] = []
    if spawn:
        rr.spawn(connect=False)
        sinks.append(rr.GrpcSink(SPAWNED_VIEWER))
    if connect is not None:
        sinks.append(rr.GrpcSink(connect))
    if save is not None:
        sinks.append(rr.FileSink(str(save)))
    recording = rr.RecordingStream(application_id)
    recording.set_sinks(*sinks)
    return recording
