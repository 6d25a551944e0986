"""Which files a config may make the tool read or write: a config from a pull request must not reach beyond its folder.

The rule is docs/security.md's "What a config can reach"; only the environment can widen it, never a config. A path
the operating system cannot follow is the config's problem, never a crash: `check_read`, `check_write` and
`file_state` raise a `UserError` naming the file and the cause.
"""

from __future__ import annotations

import errno
import os
import re
import site
import stat
import sys
import sysconfig
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Literal

from .errors import UserError, Where, shown

ALLOW_ENV = "URDF_PIPELINE_ALLOW_PATHS"  # os.pathsep-separated folders a config may also read and write under
NAME_MAX = 255  # bytes in one file name on every file system a run writes to (ext4, xfs, btrfs, tmpfs, APFS)
PARTIAL_ROOM = len("..partial-") + 10  # execute/writer.py writes `.NAME.partial-PID` beside NAME first


URL = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*):(//|\\\\)")  # any SCHEME:// (`s3://`, `https://`, `file://`), or SCHEME:\\


def is_remote(text: str) -> bool:
    """True for anything written as a URL (`SCHEME://`): such a string is never read as a local path, whatever its
    scheme, so `s3://x` can never become the relative file `s3:/x`."""
    return bool(URL.match(text))


def refuse_url(text: str, what: str, where: Where | None) -> None:
    """A URL where only a local path is read (a URDF, a xacro file, a source kind not read remotely): said, not
    looked up as a relative file name."""
    if is_remote(text):
        raise UserError(
            f"{what} {shown(text)} is a URL; it is read from a local path (relative to the config file): download it first",
            where,
        )


class Unresolvable(Exception):
    """A path the operating system cannot follow; `cause` says why in words for a message."""

    def __init__(self, path: Path, cause: str) -> None:
        super().__init__(f"{path}: {cause}")
        self.path = path
        self.cause = cause


def os_cause(exc: BaseException, path: Path | str | None = None) -> str:
    """Why the operating system refused `path`, in words a config's author can act on."""
    if isinstance(exc, RuntimeError):  # Python 3.11's Path.resolve() on a symlink loop
        return "it is a symbolic link loop (the links lead back to each other); point the link at a real file"
    if isinstance(exc, ValueError):
        return "it holds a NUL character, which no file name may hold"
    code = getattr(exc, "errno", None)
    if code == errno.ELOOP:
        return "it is a symbolic link loop (the links lead back to each other); point the link at a real file"
    if code == errno.ENAMETOOLONG:
        return f"a name in it is too long for the file system (at most {NAME_MAX} bytes per name); shorten it"
    if code in (errno.EACCES, errno.EPERM):
        return "permission denied"
    if code in (errno.ENOTDIR, errno.EEXIST) and path is not None:  # EEXIST: mkdir over a file
        blocker = _file_in_the_way(Path(path))
        if blocker is not None:
            return f"{blocker} is a file, not a folder"
    strerror = getattr(exc, "strerror", None)
    return str(strerror or exc).lower() if strerror else str(exc)


def _file_in_the_way(path: Path) -> Path | None:
    """The first ancestor of `path` that exists and is not a folder, if any."""
    for ancestor in reversed(path.parents):
        try:
            if not stat.S_ISDIR(os.stat(ancestor).st_mode):
                return ancestor
        except OSError:
            return None
    return None


def resolved(entry: str | Path) -> Path:
    """`entry` made absolute, `~` expanded and symlinks followed; `Unresolvable` when the OS cannot follow it."""
    path = Path(entry).expanduser()
    try:
        return path.resolve()
    except (OSError, RuntimeError, ValueError) as exc:  # ValueError: a NUL character in the name
        raise Unresolvable(path, os_cause(exc, path)) from None


def _lexical(path: Path) -> Path:
    return Path(os.path.abspath(path.expanduser()))


def resolved_or_written(path: Path) -> Path:
    """`path` resolved; as written (absolute, `..` folded) when the OS cannot follow it: for a path that is only
    compared or named (an output, a manifest entry), whose checks then refuse it with the cause."""
    try:
        return resolved(path)
    except Unresolvable:
        return _lexical(path)


FileState = Literal["missing", "file", "folder"]


def file_state(path: Path, what: str, where: Where | None, verb: str = "read") -> FileState:
    """What is at `path` (symlinks followed): nothing, a regular file or a folder. Anything else the OS reports (a
    loop, a name too long, no permission, a file where a folder is expected) or a FIFO, socket or device (reading one
    would wait forever or never end) is a `UserError` naming `what`, the path and the cause."""
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        return "missing"
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the name
        raise UserError(f"{what} {path} cannot be {verb}: {os_cause(exc, path)}", where) from None
    if stat.S_ISREG(mode):
        return "file"
    if stat.S_ISDIR(mode):
        return "folder"
    kind = "a FIFO" if stat.S_ISFIFO(mode) else "a socket" if stat.S_ISSOCK(mode) else "a device"
    raise UserError(f"{what} {path} is {kind}, not a regular file or folder; name a file", where)


def _prefix_shares() -> list[str]:
    """`share` under this Python's prefix (data-files, ament and cmeel install robots and meshes there); under the base
    prefix too when this Python imports the base's packages (no venv, or a venv with system site-packages)."""
    site_packages = [Path(p) for p in (*site.getsitepackages(), sysconfig.get_paths()["purelib"])]
    prefixes = [sys.prefix, sysconfig.get_paths()["data"]]
    prefixes += [base for base in (sys.base_prefix, sys.base_exec_prefix) if any(p.is_relative_to(base) for p in site_packages)]
    return [str(Path(prefix) / "share") for prefix in dict.fromkeys(prefixes)]


def _environment_roots() -> tuple[Path, ...]:
    """Roots declared by the environment: ROS package paths, the robot_descriptions cache, site-packages, prefix/share."""
    entries: list[str] = []
    entries += os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)
    entries += os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
    entries.append(os.environ.get("ROBOT_DESCRIPTIONS_CACHE", "~/.cache/robot_descriptions"))
    entries += [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"], *site.getsitepackages()]
    entries += _prefix_shares()
    return _roots(entries)


def _roots(entries: list[str]) -> tuple[Path, ...]:
    """The entries resolved, in order, once each; an entry the OS cannot follow allows nothing."""
    roots: list[Path] = []
    for entry in entries:
        if entry:
            try:
                roots.append(resolved(entry))
            except Unresolvable:
                continue
    return tuple(dict.fromkeys(roots))


def _inside_git(path: Path) -> bool:
    return ".git" in path.parts


def _allows(real: Path, roots: tuple[Path, ...]) -> bool:
    """The rule on a path already resolved (or, when the OS cannot follow it, as written): under a root, not in .git."""
    return not _inside_git(real) and any(real.is_relative_to(root) for root in roots)


def _work_tree(folder: Path) -> Path | None:
    """The top of the git work tree holding `folder` (the nearest ancestor with a `.git` entry), if any."""
    for candidate in (folder, *folder.parents):
        if os.path.exists(candidate / ".git"):  # never raises: a loop or a name too long is no work tree
            return candidate
    return None


@dataclass(frozen=True)
class Confinement:
    """The allowed roots for one config file; see the module's docstring for the rule."""

    config_dir: Path  # resolved
    read_roots: tuple[Path, ...]
    write_roots: tuple[Path, ...]
    work_tree: Path | None = None  # the git work tree holding the config, read like the config's folder

    def may_read(self, path: Path) -> bool:
        """Whether the rule lets a config read `path` (False when the OS cannot follow it: `check_read` says why)."""
        return self._under(path, self.read_roots)

    def may_write(self, path: Path) -> bool:
        return self._under(path, self.write_roots)

    @staticmethod
    def _under(path: Path, roots: tuple[Path, ...]) -> bool:
        try:
            real = resolved(path)
        except Unresolvable:
            return False
        return _allows(real, roots)

    def check_read(self, path: Path, what: str, where: Where | None) -> Path:
        """`path` resolved, or a user error naming it: `what` says which file it is ("mesh", "URDF file", ...). What the
        OS says of the file (a loop, a name too long, a FIFO) is told only for a place the rule allows: a config learns
        nothing of files outside its roots. A missing file passes: the caller says "not found" in its own words."""
        real = self._followed(path, what, where, self.read_roots, writing=False)
        if not _allows(real, self.read_roots):
            raise UserError(f"{what} {path}{self._outside(path, real)}", where)
        file_state(real, what, where)
        return real

    def check_write(self, path: Path, what: str, where: Where | None) -> Path:
        """`path` resolved, or a user error: outside the write roots, a folder or a file in the way of its folder, a name
        too long for the file system (with room for the partial file written first), or a path the OS cannot follow."""
        real = self._followed(path, what, where, self.write_roots, writing=True)
        if not _allows(real, self.write_roots):
            raise UserError(f"{what} {path}{self._outside(path, real, writing=True)}", where)
        long = [part for part in real.parts if len(os.fsencode(part)) > NAME_MAX]
        if long or len(os.fsencode(real.name)) + PARTIAL_ROOM > NAME_MAX:
            name = long[0] if long else real.name
            raise UserError(
                f"{what} {path} cannot be written: the name '{name[:60]}...' has {len(os.fsencode(name))} bytes, more than the "
                f"{NAME_MAX - (0 if long else PARTIAL_ROOM)} a file name may have here; shorten it",
                where,
            )
        existing = real
        while not os.path.lexists(existing) and existing != existing.parent:
            existing = existing.parent
        if existing == real:  # worded as execute/writer.py words it at run time
            if file_state(real, what, where, "written") == "folder":
                raise UserError(
                    f"cannot write {real}: it exists and it is a folder; urdf-pipeline never overwrites a file it did not write "
                    "(not even with --force): delete or move it, or choose another output path",
                    where,
                )
        elif file_state(existing, f"{what} {path} cannot be written: its folder", where, "used") != "folder":
            raise UserError(f"cannot write to {real.parent}: {existing} is not a directory; choose another output path", where)
        return real

    def _followed(self, path: Path, what: str, where: Where | None, roots: tuple[Path, ...], writing: bool) -> Path:
        """`path` resolved; a user error when the OS cannot follow it: the cause inside the roots, the rule outside."""
        try:
            return resolved(path)
        except Unresolvable as exc:
            lexical = _lexical(path)
            if not _allows(lexical, roots):
                raise UserError(f"{what} {path}{self._outside(path, lexical, writing)}", where) from None
            raise UserError(f"{what} {path} cannot be {'written' if writing else 'read'}: {exc.cause}", where) from None

    def _outside(self, path: Path, real: Path, writing: bool = False) -> str:
        shown = f" (resolves to {real})" if real != path else ""
        if _inside_git(real):
            return f"{shown} is inside a .git folder, which a config may never {'write' if writing else 'read'}"
        home = self.config_dir if writing or self.work_tree is None else self.work_tree
        where = "the config's folder" if home == self.config_dir else "the config's git work tree"
        where += "" if writing else " or a declared package root"
        return (
            f"{shown} is outside {where} ({home}); a config may only "
            f"{'write' if writing else 'read'} there. To allow another folder, the person running the tool sets "
            f"{ALLOW_ENV}=/that/folder (a config cannot)"
        )


@lru_cache(maxsize=64)
def _confinement(config_dir: Path, environment: tuple[Path, ...], allowed: tuple[Path, ...]) -> Confinement:
    tree = _work_tree(config_dir)
    return Confinement(config_dir, (tree or config_dir, *environment, *allowed), (config_dir, *allowed), tree)


def confinement_for(config_file: Path) -> Confinement:
    """The roots of the config at `config_file` under the current environment."""
    folder = resolved_or_written(config_file).parent  # the config was read: as named only if a link changed meanwhile
    return _confinement(folder, _environment_roots(), _roots(os.environ.get(ALLOW_ENV, "").split(os.pathsep)))
