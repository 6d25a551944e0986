"""Whole datasets: segments run on executors (local processes, Ray), manifest, fingerprints, catalog, summary.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .base_check import BaseRecording, base_files, check_base
    from .cpus import usable_cpus
    from .manifest import SegmentEntry, run_output, segment_summaries
    from .remote_outputs import bucket_state, fetch_manifest, local_outputs
    from .run import DatasetRun, RunOptions, register_outputs, run_dataset
    from .run_report import differences_lines, report_target, stopped_line, summary_table, totals_line, write_report

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
