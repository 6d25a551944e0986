"""Write a recording while its streams are read: memory is bounded by the chunks in flight, never by the recording's
length (a collected store held every chunk until the end).

The merged streams go straight to Rerun's writer (or to a user's recording, `urdf_pipeline.log`), which runs the readers, lenses and writing on its own threads.
The chunks come out as large as the collected store's because the sources are read in blocks of `BLOCK_ROWS` rows
(`sources/ordering.py`): a robot's FK chunk holds one block's transforms.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

    from ..sources import CallbackErrors


POLL_SECONDS = 0.1


def drain_streams(streams: list[LazyChunkStream], sink: Callable[[LazyChunkStream], None], errors: CallbackErrors) -> None:
    """Every chunk of `streams`, merged, handed to `sink` (Rerun's file writer, or a recording's `send_chunks`), which
    pulls them as it goes. Rerun reports an exception raised in Python (a lens callback, a source's own checks) only
    as text: `errors` holds the original, raised here."""
    from rerun.chunk import LazyChunkStream

    merged = LazyChunkStream.merge(*streams)
    failed: list[BaseException] = []

    def write() -> None:
        try:
            sink(merged)
        except BaseException as exc:
            failed.append(exc)

    # On a thread of its own, so that the main thread takes Ctrl-C and SIGTERM at once (Python runs signal handlers
    # only there, between bytecodes); it then cancels the pipeline, which stops within one chunk.
    writer = threading.Thread(target=write, name="urdf-pipeline-writer", daemon=True)
    writer.start()
    try:
        while writer.is_alive():
            writer.join(POLL_SECONDS)
    except BaseException:
        errors.cancel()
        writer.join()
        raise
    if failed:
        exc = failed[0]
        if isinstance(exc, (RuntimeError, ValueError)):
            errors.reraise_original(exc)
        raise exc
