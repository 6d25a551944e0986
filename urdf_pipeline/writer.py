"""Write a recording atomically: beside the target, then renamed; a failed run leaves nothing behind."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from .errors import UserError
from .plan import OutputPlan

if TYPE_CHECKING:
    from rerun.blueprint import BlueprintLike
    from rerun.chunk import ChunkStore


def write_atomically(store: ChunkStore, output: OutputPlan, blueprint: BlueprintLike | None = None) -> Path:
    """Through a RecordingStream (ChunkStore.write_rrd cannot add a blueprint store), without the stream's own
    recording properties (they would collide with a base recording's), then checked: the file sink reports some
    failures only in its log, so a file whose footer does not read back is an error, not a success."""
    target = output.path
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"cannot create output directory {target.parent}: {exc}", output.where) from None
    partial = target.with_name(f".{target.name}.partial-{os.getpid()}")
    try:
        _write(store, output, blueprint, partial)
        os.replace(partial, target)
    except (OSError, RuntimeError) as exc:  # disk full, a directory in the way, permissions: the machine, not a bug
        partial.unlink(missing_ok=True)
        raise UserError(f"cannot write {target}: {exc}", output.where) from None
    except BaseException:
        partial.unlink(missing_ok=True)
        raise
    return target


def _write(store: ChunkStore, output: OutputPlan, blueprint: BlueprintLike | None, partial: Path) -> None:
    import rerun as rr
    from rerun.chunk import RrdReader

    # NEVER: the store is already compacted for reading (OBJECT_STORE); the stream's batcher would only re-chunk it.
    stream = rr.RecordingStream(
        output.application_id, recording_id=output.recording_id, send_properties=False, batcher_config=rr.ChunkBatcherConfig.NEVER()
    )
    try:
        stream.save(partial, default_blueprint=blueprint)
        stream.send_chunks(store)
        stream.flush()
    finally:
        stream.disconnect()
    try:
        written = [(str(e.application_id), str(e.recording_id)) for e in RrdReader(partial).recordings()]
    except (OSError, ValueError, RuntimeError) as exc:
        raise OSError(f"the written file does not read back ({exc})") from None
    if written != [(output.application_id, output.recording_id)]:
        raise OSError(f"the written file holds {written}, not ({output.application_id}, {output.recording_id})")
