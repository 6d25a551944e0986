"""Write a recording while its streams are read: memory is bounded by the chunks in flight, never by the recording's
length. The sources are read in blocks of `BLOCK_ROWS` rows (`sources/ordering.py`): a robot's FK chunk holds one
block's transforms.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import TYPE_CHECKING

from ..process import deferred_signals

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
    try:
        _start_and_wait(writer)
    except BaseException:
        _cancel(writer, errors)
        raise
    if failed:
        exc = failed[0]
        if isinstance(exc, (RuntimeError, ValueError)):
            errors.reraise_original(exc)
        raise exc


def _start_and_wait(writer: threading.Thread) -> None:
    """Start `writer` and wait until it has returned, or until a Ctrl-C or SIGTERM handler raises (within
    `POLL_SECONDS`). The signal is taken between the waits (`deferred_signals`), never inside `start` or `join`: an
    interrupted `join` lets every later one return while the thread runs on (Python 3.11, see process/signals.py)."""
    while True:
        with deferred_signals() as received:
            if writer.ident is None:
                writer.start()
            while writer.is_alive() and not received:
                writer.join(POLL_SECONDS)
        if not writer.is_alive():  # else a signal whose handler did not raise: wait on
            return


def _cancel(writer: threading.Thread, errors: CallbackErrors) -> None:
    """Cancel the pipeline and wait until the writer has returned, which it does within one chunk. Only then may the
    caller go on: Rerun's threads call into Python (sources, lenses) until then, and one that does so while the
    interpreter finalizes aborts the process ("panic in a function that cannot unwind"). A second Ctrl-C is delivered
    once the writer has returned."""
    with deferred_signals():
        errors.cancel()
        if writer.ident is not None:  # None: start() itself failed
            writer.join()
