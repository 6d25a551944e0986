"""For every stage, what concerns the whole process: signals, child processes, the Rerun viewer (one module each).

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .children import (
        ANSI_ESCAPE,
        ChildOutcome,
        bound_from_environment,
        limit_this_process,
        passed_environment,
        run_bounded_child,
        sandboxed_python,
        stop_session,
    )
    from .rerun_viewer import log_reason, require_viewer, spawn_viewer, start_viewer, viewer_binary, viewer_url
    from .signals import Stopped, deferred_signals, held_off, ignore_stop_signals, signal_name, sigterm_kept, stop_signal

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
