"""The review commands, one subpackage each: `validate/`, `check/`, `plan_report/` (`plan`), `diff/`. check's sample
and candidates are on the surface for `scaffold/` (init chooses each joint's unit as check judges it)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .check.check_candidates import fitting
    from .check.check_joints import check_config, check_exit_code, check_plan, plan_sample, render_check
    from .diff.diff_inputs import diff_files, diff_git
    from .diff.diff_render import render_diff
    from .plan_report.report import plan_command
    from .qa_report.qa_render import QaFormat, fail_on_flags, failure, render_qa
    from .validate.annotations import render_annotations, render_text_errors, render_text_progress, validate_config

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
