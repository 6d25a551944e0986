"""What `diff` compares: two config files, or a config and its text at a git revision, each compiled quietly.

`diff CONFIG --git REV` compiles the config's text at REV (`git show REV:./NAME`, run in the config's folder) from a
hidden temporary file beside the config, so relative paths resolve as for the working tree's config. Everything
else the old config refers to (URDF, data, sidecar edge files) is read from the working tree.
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import UserError, UserErrors, Where, collect_warnings
from ..plan import Plan
from .diff import diff_plans
from .diff_base import DiffReport
from .pictures import diff_pictures

if TYPE_CHECKING:
    from ..render import Size


def compile_quietly(config: Path) -> Plan:
    """compile_config without printing warnings: the diff is about what differs, not what each config does."""
    from ..compile import compile_config

    with collect_warnings():
        return compile_config(config)


def diff_files(old: str, new: str, render: Path | None = None, size: Size | None = None) -> DiffReport:
    """OLD and NEW as the user named them. With `render`, the viewer draws both into that folder (see _report)."""
    return _report(old, new, compile_quietly(Path(old)), compile_quietly(Path(new)), render, size)


def diff_git(config: str, revision: str, render: Path | None = None, size: Size | None = None) -> DiffReport:
    """The config at `revision` vs the working tree's. Files the old config refers to are read from the working tree."""
    path = Path(config)
    new_plan = compile_quietly(path)
    with git_revision_copy(path, revision) as old_copy:
        old_plan = _renamed_errors(old_copy, Path(f"{path}@{revision}"))
        old_plan = _as_if_named(old_plan, old_copy, path)
    return _report(f"{config}@{revision}", config, old_plan, new_plan, render, size)


def _report(old: str, new: str, old_plan: Plan, new_plan: Plan, render: Path | None, size: Size | None) -> DiffReport:
    """The changes; with `render`, the pictures of both plans at the same joint values (named after NEW's file),
    drawn even when nothing differs: the reviewer sees the robot either way."""
    pictures = diff_pictures(old_plan, new_plan, render, Path(new).stem, size) if render is not None else ()
    return DiffReport(old, new, diff_plans(old_plan, new_plan), pictures)


def _renamed_errors(copy: Path, shown: Path) -> Plan:
    """Compile the temporary copy; its errors name `CONFIG@REV`, not the hidden file that is about to be removed."""
    try:
        return compile_quietly(copy)
    except UserError as exc:
        errors = exc.errors if isinstance(exc, UserErrors) else [exc]
        renamed = [
            UserError(e.message, replace(e.where, file=shown) if e.where is not None and e.where.file == copy else e.where) for e in errors
        ]
        raise (renamed[0] if len(renamed) == 1 else UserErrors(renamed)) from None


def _as_if_named(plan: Plan, copy: Path, config: Path) -> Plan:
    """The default manifest is named after the config's file: name it after the real config, not the copy."""
    plan = replace(plan, config_path=config)
    if plan.dataset.manifest.name == f"{copy.stem}.manifest.json":
        manifest = plan.dataset.manifest.with_name(f"{config.stem}.manifest.json")
        plan = replace(plan, dataset=replace(plan.dataset, manifest=manifest))
    return plan


def git_show(config: Path, revision: str) -> str:
    """The text of `config` at `revision` (`git show REV:./NAME` in the config's folder)."""
    folder = config.absolute().parent  # as compile_config sees it: relative paths start from here
    spec = f"{revision}:./{config.name}"
    try:
        result = subprocess.run(["git", "show", spec], cwd=folder, capture_output=True, text=True, check=False)
    except FileNotFoundError:
        raise UserError("git is not installed (needed by --git)", Where(config, 0)) from None
    except OSError as exc:
        raise UserError(f"cannot run git in {folder}: {exc}", Where(config, 0)) from None
    if result.returncode != 0:
        reason = (result.stderr.strip().splitlines() or ["git failed"])[-1].removeprefix("fatal: ")
        raise UserError(f"cannot read {config.name} at git revision '{revision}': {reason}", Where(config, 0))
    return result.stdout


@contextmanager
def git_revision_copy(config: Path, revision: str) -> Iterator[Path]:
    """The config's text at `revision` in a hidden file beside the config (so relative paths resolve alike), removed afterwards."""
    text = git_show(config, revision)
    folder = config.absolute().parent  # as compile_config sees it: relative paths start from here
    handle, name = tempfile.mkstemp(prefix=f".{config.stem}.git-", suffix=config.suffix or ".yaml", dir=folder)
    copy = Path(name)
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            stream.write(text)
        yield copy
    finally:
        copy.unlink(missing_ok=True)
