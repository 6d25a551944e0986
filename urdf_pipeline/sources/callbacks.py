"""Exceptions raised inside Rerun lens callbacks and Python-fed streams come back as a RuntimeError; keep the original."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from rerun.chunk import Chunk, LazyChunkStream

T = TypeVar("T")


class Cancelled(Exception):
    """Raised inside the pipeline after `CallbackErrors.cancel`."""


class CallbackErrors:
    """Remembers the first exception raised by any wrapped callback so it can be re-raised unwrapped."""

    def __init__(self) -> None:
        self.first: BaseException | None = None
        self._lock = threading.Lock()
        self._cancelled = threading.Event()

    def cancel(self) -> None:
        """Make every wrapped callback and stream raise from now on: Rerun's pipeline then stops within one chunk
        (how Ctrl-C stops a write that runs on Rerun's threads)."""
        self._cancelled.set()

    def _check(self) -> None:
        if self._cancelled.is_set():
            raise Cancelled("cancelled")

    def wrap(self, function: Callable[..., T]) -> Callable[..., T]:
        def guarded(*args: Any) -> T:
            with self._remembering():
                self._check()
                return function(*args)

        return guarded

    def wrap_stream(self, stream: LazyChunkStream) -> LazyChunkStream:
        """`stream` passed through Python, so that an error raised while reading it (a source's own checks, which run
        in Python) is remembered: Rerun's writer reports it only as text."""
        from rerun.chunk import LazyChunkStream

        def chunks() -> Iterator[Chunk]:
            with self._remembering():
                for chunk in stream:
                    self._check()
                    yield chunk

        return LazyChunkStream.from_iter(chunks())

    @contextmanager
    def _remembering(self) -> Iterator[None]:
        try:
            yield
        except BaseException as exc:
            with self._lock:
                if self.first is None:
                    self.first = exc
            raise

    def reraise_original(self, wrapper: BaseException) -> None:
        """Raise the callback's own exception if there was one; otherwise let the caller re-raise `wrapper`."""
        if self.first is not None:
            raise self.first from None
