"""The recording a live view sends to when the caller gives none: to viewers (their URLs settled by the caller:
`process.spawn_viewer`, `process.require_viewer`) and/or a file, with the config's application id."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rerun import RecordingStream


def live_recording(application_id: str, save: str | os.PathLike[str] | Path | None, *viewers: str | None) -> RecordingStream:
    """A new recording whose sinks are the viewers at `viewers` (None: not one) and the file `save`, as asked."""
    import rerun as rr

    sinks: list[Any] = [rr.GrpcSink(url) for url in viewers if url is not None]
    if save is not None:
        sinks.append(rr.FileSink(str(save)))
    recording = rr.RecordingStream(application_id)
    recording.set_sinks(*sinks)
    return recording
