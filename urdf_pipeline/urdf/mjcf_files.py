"""Every file an MJCF model names, checked against the config's read rule at every place MuJoCo could look for it
(the main file's folder, the including file's and each `<compiler>` asset folder), and the model's size counted, before
MuJoCo opens any of them (docs/urdf.md, MJCF).

The scan reads XML as MuJoCo's reader (TinyXML2) does, or refuses what the two would read differently: the bytes as
UTF-8 whatever the XML declaration says, no namespaces (`<mujoco xmlns="...">` is still a `<mujoco>`), no DOCTYPE at
all (TinyXML2 skips one to its first `>`, so an element inside its subset is MuJoCo's and no one else's), no literal
tab or line break in a file name (expat reads a space, TinyXML2 the character). It keeps no tree: one pass with
handlers, which also counts what MuJoCo would build (MjcfCounts), so a size bomb is refused from a few bytes before
MuJoCo compiles it.
"""

from __future__ import annotations

import codecs
import os
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers.expat import ExpatError, ParserCreate

from ..confine import Confinement
from ..errors import UserError, Where, quoted, shown
from .mjcf_counts import MjcfCounts
from .xml_text import doctype_line

MAX_XML_BYTES = 16 << 20  # all the XML files of one model together (meshes are read by MuJoCo in the bounded child)
MAX_FILES = 1000  # included files of one model
MAX_DEPTH = 64  # includes within includes
_FOLDERS = ("meshdir", "texturedir", "assetdir")
_CHUNK = 1 << 20
_PNG = b"\x89PNG\r\n\x1a\n"
_RAW_TAG = re.compile(rb"""<[^\s/>]+(?:\s+[^\s=/>]+\s*=\s*(?:"[^"]*"|'[^']*'))*\s*/?>""")
_RAW_ATTRIBUTE = re.compile(rb"""([^\s=/>]+)\s*=\s*("[^"]*"|'[^']*')""")


@dataclass
class MjcfFiles:
    """What the scan found: the XML files read (the main one first), the files named and the model's counts."""

    main: Path
    confinement: Confinement
    where: Where
    xml_files: list[Path] = field(default_factory=list)
    folders: list[tuple[str, str, str]] = field(default_factory=list)  # (name, folder as written, at FILE:LINE)
    named: list[tuple[Path, str, str, str]] = field(default_factory=list)  # (including file, tag, file as written, at)
    counts: MjcfCounts = field(default_factory=MjcfCounts)
    budget: list[int] = field(default_factory=lambda: [MAX_XML_BYTES])  # bytes left to read, shared with <model> files

    def check(self, path: Path, what: str) -> Path:
        return self.confinement.check_read(Path(os.path.abspath(path)), what, self.where)

    def candidates(self, folders: Iterable[Path], tag: str, name: str, at: str) -> list[Path]:
        """The file `name` (named by a `<tag>` at FILE:LINE `at`) in each of `folders`, each checked."""
        return [self.check(folder / name, f"MJCF <{shown(tag)}> file {quoted(name)} in {at}:") for folder in dict.fromkeys(folders)]

    def at(self, path: Path, line: int) -> str:
        """`FILE:LINE` for a message, the file relative to the main file's folder when inside it."""
        name = os.path.relpath(path, self.main.parent) if path.is_relative_to(self.main.parent) else str(path)
        return f"{shown(name)}:{line}"


def _read(files: MjcfFiles, path: Path) -> bytes:
    """The file's bytes, as MuJoCo reads them: within the model's budget, UTF-8, no DOCTYPE."""
    try:
        with path.open("rb") as file:
            data = file.read(files.budget[0] + 1)
    except OSError as exc:
        raise UserError(f"cannot read MJCF file {shown(path)}: {exc.strerror or exc}", files.where) from None
    if len(data) > files.budget[0]:
        raise UserError(
            f"MJCF model {shown(files.main.name)}: its XML files hold more than {MAX_XML_BYTES >> 20} MB together (at {shown(path)})",
            files.where,
        )
    files.budget[0] -= len(data)
    line = doctype_line(data)
    if line is not None:
        raise UserError(
            f"MJCF file {files.at(path, line)}: <!DOCTYPE> is refused: MuJoCo's XML reader (TinyXML2) skips a DOCTYPE to "
            "its first '>' and expands no entity, while other readers expand it, so the two would read different models; "
            "remove the DOCTYPE (and write any entity's text in place)",
            files.where,
        )
    decoder = codecs.getincrementaldecoder("utf-8")()
    for start in range(0, len(data), _CHUNK):  # checked, not kept: expat reads the bytes themselves
        try:
            decoder.decode(data[start : start + _CHUNK], start + _CHUNK >= len(data))
        except UnicodeDecodeError as exc:
            line = data.count(b"\n", 0, start + exc.start) + 1
            raise UserError(
                f"MJCF file {files.at(path, line)} is not UTF-8 text (byte {start + exc.start}): MuJoCo reads its files as "
                "UTF-8 whatever the XML declaration says; save it as UTF-8",
                files.where,
            ) from None
    return data


class _FileScan:
    """One XML file read with expat's handlers (no tree kept): its compiler folders, the files it names, its counts,
    and its includes, read where they stand (MuJoCo inlines them), inside the replicates around them."""

    def __init__(self, files: MjcfFiles, path: Path, depth: int, nesting: int, multiplier: int) -> None:
        """`nesting`: the level of the element the file's root stands for (1 for a model's own file, an include's for
        an included one); `multiplier`: the copies the replicates around it make."""
        self.files, self.path, self.depth = files, path, depth
        self.raw = _read(files, path)
        self.parser = ParserCreate(encoding="utf-8")  # whatever the XML declaration says; namespace-unaware, like TinyXML2
        self.stack: list[int] = [multiplier]  # the multiplier inside each open element
        self.nesting = nesting - 1  # an element's level is self.nesting + len(self.stack)

    def run(self) -> None:
        self.parser.StartElementHandler = self.start
        self.parser.EndElementHandler = self.end
        try:
            self.parser.Parse(self.raw, True)
        except ExpatError as exc:
            raise UserError(f"MJCF file {self.files.at(self.path, exc.lineno)} is not valid XML: {exc}", self.files.where) from None

    def start(self, tag: str, attributes: dict[str, str]) -> None:
        line = self.parser.CurrentLineNumber
        at = self.files.at(self.path, line)
        outer = self.stack[-1]
        inner = self.files.counts.element(tag, attributes, outer, self.nesting + len(self.stack), at, self.files.where)
        self.stack.append(inner)
        paths = [name for name in attributes if name.startswith("file") or (tag == "compiler" and name in _FOLDERS)]
        if paths:
            self._same_for_mujoco(tag, paths, at)
        if tag == "compiler":
            self.files.folders.extend((name, attributes[name], at) for name in _FOLDERS if name in attributes)
        for name in paths:
            if name.startswith("file") and attributes[name]:
                self.files.named.append((self.path, tag, attributes[name], at))
        if tag == "include" and attributes.get("file"):
            included = _include(self.files, self.path, attributes["file"], at)
            _scan(self.files, included, self.depth + 1, self.nesting + len(self.stack) - 1, outer)

    def end(self, tag: str) -> None:
        self.stack.pop()

    def _same_for_mujoco(self, tag: str, names: list[str], at: str) -> None:
        """A file name with a literal tab or line break is read as a space by expat and as itself by TinyXML2."""
        raw = _RAW_TAG.match(self.raw, self.parser.CurrentByteIndex)
        values = {m.group(1).decode("utf-8"): m.group(2) for m in _RAW_ATTRIBUTE.finditer(raw.group(0))} if raw else {}
        for name in names:
            if name not in values or re.search(rb"[\t\n\r]", values[name]):
                raise UserError(
                    f"MJCF file {at}: <{shown(tag)} {shown(name)}={quoted(values.get(name, b'..')[1:-1].decode('utf-8', 'replace'))}> "
                    "holds a tab or line break: XML readers disagree on it (expat reads a space, MuJoCo the character "
                    "itself), so the file checked would not be the file MuJoCo opens; write the name on one line",
                    self.files.where,
                )


def _png_size(path: Path) -> tuple[int, int]:
    """The width and height a PNG's header states (what MuJoCo's decoder allocates, whatever the compressed bytes),
    (0, 0) for another format: MuJoCo's own texture and height field formats hold every value they state."""
    try:
        with path.open("rb") as file:
            head = file.read(24)
    except OSError:
        return (0, 0)  # MuJoCo says why it cannot read it
    if len(head) < 24 or not head.startswith(_PNG) or head[12:16] != b"IHDR":
        return (0, 0)
    return (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big"))


def _scan(files: MjcfFiles, path: Path, depth: int, nesting: int = 1, multiplier: int = 1) -> None:
    """One XML file and its includes, depth first, as MuJoCo inlines them."""
    if depth > MAX_DEPTH:
        raise UserError(
            f"MJCF model {shown(files.main.name)} nests includes (or <model> files) more than {MAX_DEPTH} deep (at {shown(path.name)})",
            files.where,
        )
    if len(files.xml_files) >= MAX_FILES:
        raise UserError(f"MJCF model {shown(files.main.name)} includes more than {MAX_FILES} files", files.where)
    if path in files.xml_files:
        raise UserError(f"MJCF file {shown(path.name)} includes itself (an <include> cycle)", files.where)
    files.xml_files.append(path)
    _FileScan(files, path, depth, nesting, multiplier).run()


def _include(files: MjcfFiles, includer: Path, name: str, at: str) -> Path:
    """The included file, checked at both places MuJoCo may read it from; the one that exists (the main folder's first)."""
    candidates = files.candidates((files.main.parent, includer.parent), "include", name, at)
    found = next((candidate for candidate in candidates if candidate.is_file()), None)
    if found is None:
        raise UserError(f"MJCF <include> file {quoted(name)} in {at} not found (relative to {files.main.parent})", files.where)
    return found


def scan_mjcf(
    main: Path, confinement: Confinement, where: Where, seen: list[Path] | None = None, depth: int = 0, budget: list[int] | None = None
) -> MjcfFiles:
    """Every file `main` (resolved, allowed) names, checked, and the model's size within MjcfCounts' bounds: a UserError
    at `where` for the first refused. A `<model file>` asset (a model MuJoCo attaches) is scanned as a model of its own,
    its folders relative to its own file, and its counts added at each `<attach>` of it."""
    files = MjcfFiles(main, confinement, where, seen if seen is not None else [])
    if budget is not None:
        files.budget = budget
    _scan(files, main, depth)
    base = main.parent
    folders = [base, *(base / written for _, written, _ in files.folders)]  # every one given: which MuJoCo keeps matters not
    for name, written, at in files.folders:
        files.check(base / written, f"MJCF <compiler {name}> folder in {at}:")
    for includer, tag, name, at in files.named:
        if tag == "include":
            continue
        candidates = files.candidates((*folders, includer.parent), tag, name, at)
        if tag == "model":
            for candidate in dict.fromkeys(c for c in candidates if c.is_file() and c not in files.xml_files):
                model = scan_mjcf(candidate, confinement, where, files.xml_files, depth + 1, files.budget)
                files.counts.models.append(model.counts)
        elif tag in ("texture", "hfield"):
            found = [_png_size(candidate) for candidate in dict.fromkeys(candidates) if candidate.is_file()]
            files.counts.image(tag, name, max(found, default=(0, 0)), at, where)
    files.counts.attach_models(where)
    return files
