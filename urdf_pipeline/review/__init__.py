"""The review commands: validate (annotations), check, plan (report), diff, init (scaffold). Each builds one typed
report model that text, markdown and json render. May import: everything below it.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .annotations import render_annotations, render_text_errors, render_text_progress, validate_config
    from .check import check_config, check_exit_code, render_check
    from .diff_inputs import diff_files, diff_git
    from .diff_render import render_diff
    from .init_urdf import urdf_argument
    from .report import plan_command
    from .scaffold import init_config, schema_reference, write_schema

__all__ = [
    "check_config",
    "check_exit_code",
    "diff_files",
    "diff_git",
    "init_config",
    "plan_command",
    "render_annotations",
    "render_check",
    "render_diff",
    "render_text_errors",
    "render_text_progress",
    "schema_reference",
    "urdf_argument",
    "validate_config",
    "write_schema",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "check_config": "check",
        "check_exit_code": "check",
        "diff_files": "diff_inputs",
        "diff_git": "diff_inputs",
        "init_config": "scaffold",
        "plan_command": "report",
        "render_annotations": "annotations",
        "render_check": "check",
        "render_diff": "diff_render",
        "render_text_errors": "annotations",
        "render_text_progress": "annotations",
        "schema_reference": "scaffold",
        "urdf_argument": "init_urdf",
        "validate_config": "annotations",
        "write_schema": "scaffold",
    },
)
