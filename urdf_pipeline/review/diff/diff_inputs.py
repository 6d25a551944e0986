"""What `diff` compares: two config files, or a config and its text at a git revision, each compiled quietly. The
text at REV is compiled from a hidden copy beside the config, so its relative paths resolve as the working tree's
config's; REV reaches git only once verified as a commit (`verified_revision`), never as an option."""

from __future__ import annotations

import os
import subprocess
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from ...config import MAX_BYTES
from ...errors import UserError, UserErrors, Where, collect_warnings, quoted, shown
from ...plan import Plan
from ..picture_entries import diff_pictures
from .diff_base import DiffReport
from .diff_plans import diff_plans

if TYPE_CHECKING:
    from ...render import Size
    from ...web import SiteWriter


def compile_quietly(config: Path) -> Plan:
    """compile_config without printing warnings: the diff is about what differs, not what each config does."""
    from ...compile import compile_config

    with collect_warnings():
        return compile_config(config)


def diff_files(old: str, new: str, render: Path | None = None, size: Size | None = None, site: SiteWriter | None = None) -> DiffReport:
    """OLD and NEW as the user named them. With `render`, the viewer draws both into that folder; with `site`
    (`--html`), the report goes into it as HTML with both plans in the web viewer (see _report)."""
    return _report(old, new, compile_quietly(Path(old)), compile_quietly(Path(new)), render, size, site)


def diff_git(
    config: str, revision: str, render: Path | None = None, size: Size | None = None, site: SiteWriter | None = None
) -> DiffReport:
    """The config at `revision` vs the working tree's. Files the old config refers to are read from the working tree."""
    path = Path(config)
    if not _is_file(path):
        compile_quietly(path)  # the config's own error (not found, not a file, a name too long) before any git call
    with git_revision_copy(path, revision) as old_copy:  # REV verified first: a bad one is refused before any work
        new_plan = compile_quietly(path)
        old_plan = _renamed_errors(old_copy, Path(f"{path}@{revision}"))
        old_plan = _as_if_named(old_plan, old_copy, path)
    return _report(f"{config}@{revision}", config, old_plan, new_plan, render, size, site)


def _is_file(path: Path) -> bool:
    try:
        return path.is_file()
    except OSError:  # a name too long, a permission refused: compile_config words it
        return False


def _report(
    old: str, new: str, old_plan: Plan, new_plan: Plan, render: Path | None, size: Size | None, site: SiteWriter | None = None
) -> DiffReport:
    """The changes; with `render`, the pictures of both plans at the same joint values (named after NEW's file; the
    overlay's caption lists the changes), drawn even when nothing differs: the reviewer sees the robot either way.
    With `site`, the site's pages too."""
    changes = diff_plans(old_plan, new_plan)
    pictures = diff_pictures(old_plan, new_plan, render, Path(new).stem, size, (old, new), changes) if render is not None else ()
    report = DiffReport(old, new, changes, pictures)
    if site is not None:
        from ..review_site import write_diff_site

        write_diff_site(site, old_plan, new_plan, report)
    return report


def _renamed_errors(copy: Path, named: Path) -> Plan:
    """Compile the temporary copy; its errors name `CONFIG@REV`, not the hidden file that is about to be removed."""
    try:
        return compile_quietly(copy)
    except UserError as exc:
        errors = exc.errors if isinstance(exc, UserErrors) else [exc]
        renamed = [
            UserError(e.message, replace(e.where, file=named) if e.where is not None and e.where.file == copy else e.where) for e in errors
        ]
        raise (renamed[0] if len(renamed) == 1 else UserErrors(renamed)) from None


def _as_if_named(plan: Plan, copy: Path, config: Path) -> Plan:
    """The default manifest is named after the config's file: name it after the real config, not the copy."""
    plan = replace(plan, config_path=config)
    if plan.dataset.manifest.name == f"{copy.stem}.manifest.json":
        manifest = plan.dataset.manifest.with_name(f"{config.stem}.manifest.json")
        plan = replace(plan, dataset=replace(plan.dataset, manifest=manifest))
    return plan


def _git(arguments: list[str], config: Path, revision: str, **kwargs: Any) -> subprocess.Popen[bytes]:
    """git, started in the config's folder (as compile_config sees it: relative paths start from here). The caller puts
    `--end-of-options` before any argument that holds user data, so none can be read as an option."""
    folder = config.absolute().parent
    try:
        return subprocess.Popen(["git", *arguments], cwd=folder, stdin=subprocess.DEVNULL, stderr=subprocess.PIPE, **kwargs)
    except FileNotFoundError as exc:
        if exc.filename == "git":
            raise UserError("git is not installed (needed by --git)", Where(config, 0)) from None
        raise UserError(f"cannot run git in {shown(folder)}: no such folder", Where(config, 0)) from None
    except OSError as exc:
        raise UserError(
            f"cannot run git in {shown(folder)} for --git {quoted(revision)}: {shown(exc.strerror or exc)}", Where(config, 0)
        ) from None


def _last_line(stderr: bytes) -> str:
    lines = [line for line in stderr.decode("utf-8", "replace").splitlines() if line.strip()]
    return shown(lines[-1].removeprefix("fatal: ").removeprefix("error: ")) if lines else ""


def verified_revision(config: Path, revision: str) -> str:
    """The commit `revision` names (`git rev-parse --verify --end-of-options REV^{commit}`), as its full hash: what the
    user typed reaches git only as a revision, never as an option (`--output=FILE`, `-c core.pager=...`), and every
    later call names the hash."""
    child = _git(
        ["rev-parse", "--verify", "--quiet", "--end-of-options", f"{revision}^{{commit}}"], config, revision, stdout=subprocess.PIPE
    )
    out, err = child.communicate()
    commit = out.decode("ascii", "replace").strip()
    if child.returncode != 0 or not commit or not all(c in "0123456789abcdef" for c in commit):
        why = _last_line(err)
        raise UserError(
            f"--git {quoted(revision)} names no commit in {shown(config.absolute().parent)}"
            + (f": {why}" if why else "")
            + "; give a branch, tag or commit (`main`, `HEAD~1`, `v1.2`)",
            Where(config, 0),
        )
    return commit


@contextmanager
def git_revision_copy(config: Path, revision: str) -> Iterator[Path]:
    """The config's text at `revision` (`git cat-file blob COMMIT:./NAME` in the config's folder) in a hidden file
    beside the config (so relative paths resolve alike), removed afterwards. At most MAX_BYTES + 1 are copied: the
    YAML reader refuses a copy that large, as it refuses such a file in the working tree."""
    commit = verified_revision(config, revision)
    folder = config.absolute().parent  # as compile_config sees it: relative paths start from here
    handle, name = tempfile.mkstemp(prefix=f".{config.stem}.git-", suffix=config.suffix or ".yaml", dir=folder)
    copy = Path(name)
    try:
        with os.fdopen(handle, "wb") as stream:
            _copy_blob(config, revision, f"{commit}:./{config.name}", stream)
        yield copy
    finally:
        copy.unlink(missing_ok=True)


def _copy_blob(config: Path, revision: str, spec: str, stream: IO[bytes]) -> None:
    """The blob's bytes into `stream`, at most MAX_BYTES + 1; a user error naming REV when git cannot give it."""
    child = _git(["cat-file", "blob", "--end-of-options", spec], config, revision, stdout=subprocess.PIPE)
    assert child.stdout is not None and child.stderr is not None
    left = MAX_BYTES + 1  # one byte more than the YAML reader accepts: it refuses the copy as it refuses such a file
    while left > 0 and (chunk := child.stdout.read(min(left, 1 << 16))):
        stream.write(chunk)
        left -= len(chunk)
    if left <= 0:
        child.kill()
    child.stdout.close()
    err = child.stderr.read(1 << 16)
    child.stderr.close()
    if child.wait() != 0 and left > 0:
        why = _last_line(err) or "git failed"
        raise UserError(f"cannot read {shown(config.name)} at git revision {quoted(revision)}: {why}", Where(config, 0))
