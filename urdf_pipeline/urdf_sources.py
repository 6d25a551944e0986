"""Where a robot's URDF text comes from: a plain file, xacro with arguments, or a `robot_descriptions` package.

Every form yields the same thing: the URDF text, the folder relative mesh paths start from, extra package
roots for `package://` URIs, and an origin string; the text's sha256 goes into the recording so runs compare.
"""

from __future__ import annotations

import contextlib
import difflib
import hashlib
import importlib
import os
import re
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .document import Document
from .errors import UserError, Where
from .meshes import package_roots


@dataclass(frozen=True)
class LoadedUrdf:
    text: str
    path: Path  # the file the text came from (its folder anchors relative mesh paths)
    origin: str  # human-readable, machine-independent where possible
    package_paths: dict[str, Path] = field(default_factory=dict)  # extra package:// roots the form knows

    @property
    def sha256(self) -> str:
        return hashlib.sha256(self.text.encode("utf-8")).hexdigest()


def load_urdf_source(key: str, spec: Any, package_paths: Mapping[str, Path], document: Document) -> LoadedUrdf:
    where = document.where("robots", key, "urdf")
    if isinstance(spec, str):
        return _plain(spec, document, where)
    if "xacro" in spec:
        return _xacro(spec, package_paths, document, where)
    return _robot_descriptions(spec["robot_descriptions"], where)


def _read(path: Path, where: Where) -> str:
    try:
        return path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise UserError(f"cannot read {path}: {exc}", where) from None


def _plain(urdf: str, document: Document, where: Where) -> LoadedUrdf:
    path = (document.file.parent / urdf).resolve()
    if path.name.endswith(".xacro"):
        raise UserError(f"'{urdf}' is a xacro file, not a URDF; use the xacro form: urdf: {{xacro: {urdf}, args: {{...}}}}", where)
    if not path.is_file():
        raise UserError(f"URDF file not found: {path} (paths are relative to the config file)", where)
    return LoadedUrdf(_read(path, where), path, f"file {urdf}")


class _UnknownPackage(Exception):
    pass


@contextlib.contextmanager
def _find_from(package_paths: Mapping[str, Path]) -> Iterator[None]:
    """Answer xacro's `$(find PKG)` from the robot's package_paths, then ROS_PACKAGE_PATH / AMENT_PREFIX_PATH.

    The xacro package asks ament_index for it, which needs a ROS installation no laptop has.
    """
    import xacro.substitution_args as substitution

    def find(package: str) -> str:
        roots = ([package_paths[package]] if package in package_paths else []) + package_roots(package)
        for root in roots:
            if root.is_dir():
                return str(root)
        raise _UnknownPackage(package)

    original = substitution._eval_find
    original_eval = substitution._eval_dict["find"]
    substitution._eval_find = find
    substitution._eval_dict["find"] = find
    try:
        yield
    finally:
        substitution._eval_find = original
        substitution._eval_dict["find"] = original_eval


def _xacro(spec: dict[str, Any], package_paths: Mapping[str, Path], document: Document, where: Where) -> LoadedUrdf:
    import xacro

    path = (document.file.parent / spec["xacro"]).resolve()
    if not path.is_file():
        raise UserError(f"xacro file not found: {path} (paths are relative to the config file)", where)
    args = {name: _xacro_value(value) for name, value in spec.get("args", {}).items()}
    try:
        with _find_from(package_paths), contextlib.redirect_stdout(sys.stderr):
            xacro.init_stacks(str(path))
            doc = xacro.parse(None, str(path))
            xacro.process_doc(doc, mappings=dict(args))
    except Exception as exc:  # xacro wraps the causes; find the one the user can act on
        cause = _root_cause(exc)
        if isinstance(cause, _UnknownPackage):
            package = cause.args[0]
            raise UserError(f"xacro needs $(find {package}): add it to this robot's package_paths ({package}: DIR)", where) from None
        undefined = re.search(r"Undefined substitution argument (\S+)", str(exc))
        if isinstance(cause, xacro.substitution_args.ArgException) or undefined:
            name = undefined.group(1) if undefined else cause.args[0]
            raise UserError(f"xacro argument '{name}' has no value and no default: add it to urdf.args", where) from None
        # Whatever else xacro raises is about the user's file, not a bug of ours.
        raise UserError(f"xacro failed on {path.name}: {type(exc).__name__}: {exc}", where) from None
    text = doc.toprettyxml(indent="  ")
    shown = " ".join(f"{k}:={v}" for k, v in sorted(args.items()))
    return LoadedUrdf(text, path, f"xacro {spec['xacro']}" + (f" {shown}" if shown else ""))


def _root_cause(exc: BaseException) -> BaseException:
    seen: set[int] = set()
    while id(exc) not in seen:
        seen.add(id(exc))
        inner = getattr(exc, "exc", None) or exc.__cause__ or exc.__context__
        if inner is None:
            break
        exc = inner
    return exc


def _xacro_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


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
