"""Every file an MJCF model names, checked against the config's read rule before MuJoCo opens any of them.

MuJoCo reads `<include file>`, mesh, texture, height field, skin and model files, named relative to the main file's
folder or to `<compiler meshdir/texturedir/assetdir>` (themselves relative to the main file's folder, or absolute).
Here the XML is read first (each file bounded in size, includes bounded in number), and every `file*` attribute of any
element is checked at every place MuJoCo could look for it: the main file's folder, the including file's folder and
each of the asset folders. One place outside the config's roots refuses the model, naming the file and the element.
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

from ..confine import Confinement
from ..errors import UserError, Where

MAX_XML_BYTES = 64 << 20  # one MJCF file (the XML; meshes are read by MuJoCo in the bounded child)
MAX_FILES = 1000  # included files of one model
MAX_DEPTH = 64  # includes within includes
_FOLDERS = ("meshdir", "texturedir", "assetdir")


@dataclass
class MjcfFiles:
    """What the scan found: the XML files read (the main one first) and the asset files named."""

    main: Path
    confinement: Confinement
    where: Where
    xml_files: list[Path] = field(default_factory=list)
    folders: list[tuple[str, str]] = field(default_factory=list)  # every compiler meshdir/texturedir/assetdir, as written
    named: list[tuple[Path, str, str]] = field(default_factory=list)  # (including file, element tag, file as written)

    def check(self, path: Path, what: str) -> Path:
        return self.confinement.check_read(Path(os.path.abspath(path)), what, self.where)


def _parse(path: Path, shown: str, where: Where) -> ET.Element:
    try:
        with path.open("rb") as file:
            data = file.read(MAX_XML_BYTES + 1)
    except OSError as exc:
        raise UserError(f"cannot read MJCF file {shown}: {exc.strerror or exc}", where) from None
    if len(data) > MAX_XML_BYTES:
        raise UserError(f"MJCF file {shown} is larger than {MAX_XML_BYTES >> 20} MB", where)
    try:
        return ET.fromstring(data)
    except ET.ParseError as exc:
        raise UserError(f"MJCF file {shown} is not valid XML: {exc}", where) from None


def _scan(files: MjcfFiles, path: Path, depth: int = 0) -> None:
    """One XML file: its compiler folders, the files it names, and its includes, depth first (as MuJoCo inlines them)."""
    if depth > MAX_DEPTH:
        raise UserError(
            f"MJCF model {files.main.name} nests includes (or <model> files) more than {MAX_DEPTH} deep (at {path.name})", files.where
        )
    if len(files.xml_files) >= MAX_FILES:
        raise UserError(f"MJCF model {files.main.name} includes more than {MAX_FILES} files", files.where)
    if path in files.xml_files:
        raise UserError(f"MJCF file {path.name} includes itself (an <include> cycle)", files.where)
    files.xml_files.append(path)
    root = _parse(path, str(path), files.where)
    for element in root.iter():
        if element.tag == "compiler":
            files.folders.extend((name, element.attrib[name]) for name in _FOLDERS if name in element.attrib)
        for attribute, value in element.attrib.items():
            if attribute.startswith("file") and value:
                files.named.append((path, str(element.tag), value))
        if element.tag == "include" and element.get("file"):
            _scan(files, _include(files, path, element.attrib["file"]), depth + 1)


def _include(files: MjcfFiles, includer: Path, name: str) -> Path:
    """The included file, checked at both places MuJoCo may read it from; the one that exists (the main folder's first)."""
    candidates = [
        files.check(folder / name, f"MJCF <include> file {name!r} in {includer.name}:")
        for folder in dict.fromkeys((files.main.parent, includer.parent))
    ]
    found = next((candidate for candidate in candidates if candidate.is_file()), None)
    if found is None:
        raise UserError(f"MJCF <include> file {name!r} in {includer.name} not found (relative to {files.main.parent})", files.where)
    return found


def scan_mjcf(main: Path, confinement: Confinement, where: Where, seen: list[Path] | None = None, depth: int = 0) -> MjcfFiles:
    """Every file `main` (resolved, allowed) names, checked: a UserError at `where` for the first refused. A `<model
    file>` asset (a model MuJoCo attaches) is scanned as a model of its own, its folders relative to its own file."""
    files = MjcfFiles(main, confinement, where, seen if seen is not None else [])
    _scan(files, main, depth)
    base = main.parent
    folders = [base, *(base / written for _, written in files.folders)]  # every one given: which MuJoCo keeps matters not
    for name, written in files.folders:
        files.check(base / written, f"MJCF <compiler {name}> folder")
    for includer, tag, name in files.named:
        if tag == "include":
            continue
        candidates = [
            files.check(folder / name, f"MJCF <{tag}> file {name!r} in {includer.name}:")
            for folder in dict.fromkeys((*folders, includer.parent))
        ]
        if tag == "model":
            for candidate in dict.fromkeys(c for c in candidates if c.is_file() and c not in files.xml_files):
                scan_mjcf(candidate, confinement, where, files.xml_files, depth + 1)
    return files
