"""The review commands, one subpackage each: `validate/`, `check/`, `plan_report/` (`plan`), `diff/`; what two of them
share stays here (`markdown_text.py`, `picture_entries.py`). Each builds one typed report model that text, markdown and
json render. May import: everything below it.

The names below are the package's public surface; other packages import them from here, never from its modules.
check's sample and candidates are on it for `scaffold/` (init chooses each joint's unit as check judges it).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .check.check_candidates import ANGLES, LENGTHS, fits, fitting, reaches, unit_only
    from .check.check_joints import check_config, check_exit_code, check_plan, read_sample, render_check
    from .diff.diff_inputs import diff_files, diff_git
    from .diff.diff_render import render_diff
    from .plan_report.report import plan_command
    from .validate.annotations import render_annotations, render_text_errors, render_text_progress, validate_config

__all__ = [
    "ANGLES",
    "LENGTHS",
    "check_config",
    "check_exit_code",
    "check_plan",
    "diff_files",
    "diff_git",
    "fits",
    "fitting",
    "plan_command",
    "reaches",
    "read_sample",
    "render_annotations",
    "render_check",
    "render_diff",
    "render_text_errors",
    "render_text_progress",
    "unit_only",
    "validate_config",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "ANGLES": "check.check_candidates",
        "LENGTHS": "check.check_candidates",
        "check_config": "check.check_joints",
        "check_exit_code": "check.check_joints",
        "check_plan": "check.check_joints",
        "diff_files": "diff.diff_inputs",
        "diff_git": "diff.diff_inputs",
        "fits": "check.check_candidates",
        "fitting": "check.check_candidates",
        "plan_command": "plan_report.report",
        "reaches": "check.check_candidates",
        "read_sample": "check.check_joints",
        "render_annotations": "validate.annotations",
        "render_check": "check.check_joints",
        "render_diff": "diff.diff_render",
        "render_text_errors": "validate.annotations",
        "render_text_progress": "validate.annotations",
        "unit_only": "check.check_candidates",
        "validate_config": "validate.annotations",
    },
)
