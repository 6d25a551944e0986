"""Which files a config may make the tool read or write: a config from a pull request must not reach beyond its folder.

The rule (documented in docs/ci.md, "What a config can reach"):
- A path a config names (URDF, xacro and what it includes, meshes, package_paths, sources, sidecar edge files) is
  read only if it resolves, symlinks followed, under an allowed root: the config's own folder (or, when the config
  is in a git work tree, that work tree: a repository keeps configs/ beside robots/ and data/, and everything in a
  checkout is the pull request's own content already), or a root the
  environment of whoever runs the tool declares (ROS_PACKAGE_PATH, AMENT_PREFIX_PATH, ROBOT_DESCRIPTIONS_CACHE, this
  Python's site-packages where description packages install, and URDF_PIPELINE_ALLOW_PATHS). A config cannot widen
  this: only the environment can.
- Outputs are written only under the config's folder or URDF_PIPELINE_ALLOW_PATHS.
- Nothing inside a `.git` folder is read or written (a CI checkout keeps its token in `.git/config`).
"""

from __future__ import annotations

import os
import site
import sysconfig
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from .errors import UserError, Where

ALLOW_ENV = "URDF_PIPELINE_ALLOW_PATHS"  # os.pathsep-separated folders a config may also read and write under


def _environment_roots() -> tuple[Path, ...]:
    """Roots declared by the environment: ROS package paths, the robot_descriptions cache, site-packages."""
    entries: list[str] = []
    entries += os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep)
    entries += os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep)
    entries.append(os.environ.get("ROBOT_DESCRIPTIONS_CACHE", "~/.cache/robot_descriptions"))
    entries += [sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"], *site.getsitepackages()]
    return tuple(_resolved(entry) for entry in entries if entry)


def _allowed_by_user() -> tuple[Path, ...]:
    return tuple(_resolved(entry) for entry in os.environ.get(ALLOW_ENV, "").split(os.pathsep) if entry)


def _resolved(entry: str | Path) -> Path:
    return Path(entry).expanduser().resolve()


def _inside_git(path: Path) -> bool:
    return ".git" in path.parts


def _work_tree(folder: Path) -> Path | None:
    """The top of the git work tree holding `folder` (the nearest ancestor with a `.git` entry), if any."""
    for candidate in (folder, *folder.parents):
        if (candidate / ".git").exists():
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
        resolved = _resolved(path)
        return not _inside_git(resolved) and any(resolved.is_relative_to(root) for root in self.read_roots)

    def may_write(self, path: Path) -> bool:
        resolved = _resolved(path)
        return not _inside_git(resolved) and any(resolved.is_relative_to(root) for root in self.write_roots)

    def check_read(self, path: Path, what: str, where: Where | None) -> Path:
        """`path` resolved, or a user error naming it: `what` says which file it is ("mesh", "URDF file", ...)."""
        if not self.may_read(path):
            raise UserError(f"{what} {path}{self._outside(path)}", where)
        return _resolved(path)

    def check_write(self, path: Path, what: str, where: Where | None) -> Path:
        if not self.may_write(path):
            raise UserError(f"{what} {path}{self._outside(path, writing=True)}", where)
        return _resolved(path)

    def _outside(self, path: Path, writing: bool = False) -> str:
        resolved = _resolved(path)
        shown = f" (resolves to {resolved})" if resolved != path else ""
        if _inside_git(resolved):
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
    return _confinement(_resolved(config_file).parent, _environment_roots(), _allowed_by_user())
