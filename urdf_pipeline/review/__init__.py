"""The review commands: validate (annotations), check, plan (report), diff, init (scaffold). Each builds one typed
report model that text, markdown and json render. May import: everything below it.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .annotations import render_annotations, render_text_errors, render_text_progress, validate_config
    from .check import check_config, check_exit_code, render_check
    from .diff_inputs import diff_files, diff_git
    from .diff_render import render_diff
    from .init_urdf import urdf_argument
    from .report import plan_command
    from .scaffold import init_config, schema_reference, write_schema

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
