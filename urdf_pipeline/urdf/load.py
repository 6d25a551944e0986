"""Where a robot's URDF text comes from: a plain file, xacro with arguments, a `robot_descriptions` package, or a MuJoCo
model (MJCF, turned into URDF text by mjcf.py).

Every form yields the same thing: the URDF text, the folder relative mesh paths start from, extra package
roots for `package://` URIs, and an origin string; the text's sha256 goes into the recording so runs compare.
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import importlib
import os
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..confine import Confinement, refuse_url
from ..errors import UserError, Where
from .mjcf import load_mjcf
from .xacro_guard import XacroBudget, XacroRequest, expand_xacro
from .xml_text import MAX_URDF_BYTES


@dataclass(frozen=True)
class LoadedUrdf:
    text: str
    path: Path  # the file the text came from (its folder anchors relative mesh paths)
    origin: str  # human-readable, machine-independent where possible
    package_paths: dict[str, Path] = field(default_factory=dict)  # extra package:// roots the form knows

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()


def load_urdf_source(
    spec: Any,
    package_paths: Mapping[str, Path],
    config_dir: Path,
    confinement: Confinement,
    where: Where,
    budget: XacroBudget | None = None,
) -> LoadedUrdf:
    """`spec` is a robot's `urdf` entry; its paths are relative to `config_dir` (the config file's folder, as named) and
    read only where `confinement` allows. Errors point at `where`: this module knows files, not configs. A xacro takes
    its time from `budget`, the config's (one of its own when None)."""
    if isinstance(spec, str):
        return _plain(spec, config_dir, confinement, where)
    if "xacro" in spec:
        return _xacro(spec, package_paths, config_dir, confinement, where, budget)
    if "mjcf" in spec:
        written = str(spec["mjcf"])
        refuse_url(written, "MJCF file", where)
        path = _config_file(written, "MJCF file", config_dir, confinement, where)
        return LoadedUrdf(load_mjcf(path, written, confinement, where), path, f"mjcf {written}")
    return _robot_descriptions(spec["robot_descriptions"], where)


def _read(path: Path, where: Where) -> str:
    """The URDF text of a file, at most MAX_URDF_BYTES of it read."""
    try:
        with path.open("rb") as file:
            data = file.read(MAX_URDF_BYTES + 1)
        if len(data) > MAX_URDF_BYTES:
            raise UserError(f"{path} is larger than {MAX_URDF_BYTES >> 20} MB: no robot's URDF is so large", where)
        return data.decode("utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {path}: {exc}", where) from None


def _config_file(written: str, what: str, config_dir: Path, confinement: Confinement, where: Where) -> Path:
    """The file a config names (relative to its folder), allowed by the read rule before its existence is checked:
    no probing outside the roots."""
    path = confinement.check_read(Path(os.path.abspath(config_dir / written)), what, where)
    if not path.is_file():
        raise UserError(f"{what} not found: {path} (paths are relative to the config file)", where)
    return path


def _plain(urdf: str, config_dir: Path, confinement: Confinement, where: Where) -> LoadedUrdf:
    refuse_url(urdf, "URDF", where)
    if Path(urdf).name.endswith(".xacro"):
        raise UserError(f"'{urdf}' is a xacro file, not a URDF; use the xacro form: urdf: {{xacro: {urdf}, args: {{...}}}}", where)
    path = _config_file(urdf, "URDF file", config_dir, confinement, where)
    return LoadedUrdf(_read(path, where), path, f"file {urdf}")


def _xacro(
    spec: dict[str, Any],
    package_paths: Mapping[str, Path],
    config_dir: Path,
    confinement: Confinement,
    where: Where,
    budget: XacroBudget | None,
) -> LoadedUrdf:
    """Expanded in a bounded child process that refuses code, the environment and files outside the config's roots."""
    refuse_url(str(spec["xacro"]), "xacro file", where)
    path = _config_file(str(spec["xacro"]), "xacro file", config_dir, confinement, where)
    args = {name: str(value).lower() if isinstance(value, bool) else str(value) for name, value in spec.get("args", {}).items()}
    text = expand_xacro(XacroRequest(path, str(spec["xacro"]), args, package_paths, confinement), where, budget)
    shown = " ".join(f"{k}:={v}" for k, v in sorted(args.items()))
    return LoadedUrdf(text, path, f"xacro {spec['xacro']}" + (f" {shown}" if shown else ""))


def _robot_descriptions(name: str, where: Where) -> LoadedUrdf:
    try:
        from robot_descriptions._descriptions import DESCRIPTIONS
    except ImportError:
        raise UserError("the robot_descriptions package is not installed: pip install robot_descriptions", where) from None
    if name not in DESCRIPTIONS:
        close = difflib.get_close_matches(name, list(DESCRIPTIONS), n=3)
        raise UserError(f"robot_descriptions has no '{name}'" + (f" (did you mean {', '.join(close)}?)" if close else ""), where)
    cache = os.environ.get("ROBOT_DESCRIPTIONS_CACHE", "~/.cache/robot_descriptions")
    sys.modules.pop(f"robot_descriptions.{name}", None)  # it fetches at import; import afresh for the current cache
    try:
        with contextlib.redirect_stdout(sys.stderr):
            module = importlib.import_module(f"robot_descriptions.{name}")
    except Exception as exc:  # git errors when offline, among others
        raise UserError(
            f"robot_descriptions could not provide '{name}' (no cached copy in ROBOT_DESCRIPTIONS_CACHE={cache} and the download failed: "
            f"{type(exc).__name__}: {str(exc).strip().splitlines()[0] if str(exc).strip() else ''}); connect once, or point "
            "ROBOT_DESCRIPTIONS_CACHE at a cache that holds it",
            where,
        ) from None
    urdf_path = getattr(module, "URDF_PATH", None)
    if urdf_path is None:
        raise UserError(f"robot_descriptions '{name}' has no URDF_PATH (it may be MJCF-only or xacro-only)", where)
    path = Path(urdf_path)
    package_path = Path(getattr(module, "PACKAGE_PATH", path.parent))
    repository = Path(getattr(module, "REPOSITORY_PATH", package_path))
    try:
        from robot_descriptions._cache import get_head_sha

        commit = get_head_sha(str(repository)) or "unknown commit"
    except ImportError:
        commit = "unknown commit"
    relative = path.relative_to(repository) if path.is_relative_to(repository) else path.name
    roots = {package_path.name: package_path, repository.name: repository}
    return LoadedUrdf(_read(path, where), path, f"robot_descriptions {name} @ {commit}: {relative}", roots)
