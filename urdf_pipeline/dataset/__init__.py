"""Whole datasets: segments run on executors (local processes, Ray), manifest, fingerprints, catalog, summary,
signals. May import: everything below it (base, config, urdf, sources, compile, execute).

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .base_check import check_base
    from .interrupts import exit_status, handle_sigterm, keep_sigterm_handler, restore_sigterm_handler, signal_name, signal_number
    from .run import DatasetRun, RunOptions, register_outputs, run_dataset
    from .summary import summary_table, totals_line, write_report

__all__ = [
    "DatasetRun",
    "RunOptions",
    "check_base",
    "exit_status",
    "handle_sigterm",
    "keep_sigterm_handler",
    "register_outputs",
    "restore_sigterm_handler",
    "run_dataset",
    "signal_name",
    "signal_number",
    "summary_table",
    "totals_line",
    "write_report",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "DatasetRun": "run",
        "RunOptions": "run",
        "check_base": "base_check",
        "exit_status": "interrupts",
        "handle_sigterm": "interrupts",
        "keep_sigterm_handler": "interrupts",
        "register_outputs": "run",
        "restore_sigterm_handler": "interrupts",
        "run_dataset": "run",
        "signal_name": "interrupts",
        "signal_number": "interrupts",
        "summary_table": "summary",
        "totals_line": "summary",
        "write_report": "summary",
    },
)
