"""Exceptions raised inside Rerun lens callbacks come back wrapped in a RuntimeError; keep the original."""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

T = TypeVar("T")


class CallbackErrors:
    """Remembers the first exception raised by any wrapped callback so it can be re-raised unwrapped."""

    def __init__(self) -> None:
        self.first: BaseException | None = None
        self._lock = threading.Lock()

    def wrap(self, function: Callable[..., T]) -> Callable[..., T]:
        def guarded(*args: Any) -> T:
            try:
                return function(*args)
            except BaseException as exc:
                with self._lock:
                    if self.first is None:
                        self.first = exc
                raise

        return guarded

    def reraise_original(self, wrapper: BaseException) -> None:
        """Raise the callback's own exception if there was one; otherwise let the caller re-raise `wrapper`."""
        if self.first is not None:
            raise self.first from None
