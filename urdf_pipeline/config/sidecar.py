"""`edges: - file: calib/extrinsics.yaml`: a sidecar list of edges (docs/config-reference.md), spliced in at the
entry's position, each error at the sidecar's own file and line. A sidecar includes no other, so nothing recurses."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..confine import confinement_for, file_state
from ..errors import Problems, UserError, Where
from .document import MAX_DEPTH, Document, PathKey, load_document, parse_document, read_text
from .schema import validate_document


@dataclass(frozen=True)
class EdgeSpec:
    """One edge as written, in the config or in a sidecar, with the document that locates its errors."""

    spec: dict[str, Any]
    document: Document
    path: PathKey  # the edge's YAML path inside `document`: ("edges", 2) or (0,)
    label: str  # "edges[2]" or "calib/extrinsics.yaml[0]"

    def where(self, *sub: str | int) -> Where:
        return self.document.where(*self.path, *sub)


def expand_edge_specs(specs: list[dict[str, Any]], document: Document, problems: Problems) -> list[EdgeSpec]:
    """Inline edges and the edges of every sidecar, in order. Broken sidecars are reported and contribute nothing."""
    result: list[EdgeSpec] = []
    for index, spec in enumerate(specs):
        if "file" in spec:
            result += _sidecar_specs(spec["file"], document, ("edges", index, "file"), problems)
        else:
            result.append(EdgeSpec(spec, document, ("edges", index), f"edges[{index}]"))
    return result


def _sidecar_specs(name: str, document: Document, here: PathKey, problems: Problems) -> list[EdgeSpec]:
    path = document.file.parent / name
    try:  # before existence: no probing; a path the OS cannot follow (a loop, a name too long) is refused here
        real = confinement_for(document.file).check_read(path, "edges file", document.where(*here))
        state = file_state(real, "edges file", document.where(*here))
    except UserError as exc:
        problems.extend(exc)
        return []
    if state != "file":
        shown = f"edges file {real} is a folder" if state == "folder" else f"edges file not found: {real}"
        problems.add(f"{shown} (paths are relative to the config file)", document.where(*here))
        return []
    try:
        sidecar = _load_json(path) if path.suffix == ".json" else load_document(path, "edges file")
    except UserError as exc:  # syntax errors, duplicate keys, beyond the bounds: at the sidecar's line
        problems.extend(exc)
        return []
    if sidecar.data is None:
        problems.add(f"edges file {name} is empty; it must hold a list of edges", Where(sidecar.file, 1))
        return []
    if isinstance(sidecar.data, list):
        nested = [index for index, item in enumerate(sidecar.data) if isinstance(item, dict) and "file" in item]
        for index in nested:
            problems.add(
                f"edges file {name} includes another edges file ({sidecar.data[index]['file']}); a sidecar holds edges only: "
                "list the other file in the config's edges instead",
                sidecar.where(index, "file"),
            )
        if nested:
            return []
    try:
        validate_document(sidecar, "edges_file")
    except UserError as exc:
        problems.extend(exc)
        return []
    return [EdgeSpec(item, sidecar, (index,), f"{name}[{index}]") for index, item in enumerate(sidecar.data)]


def _load_json(path: Path) -> Document:
    """JSON read as JSON (YAML 1.1 would read 1e-05 as a string and refuse tab indentation), lines taken from the
    same text parsed as YAML: the structure is identical, and raw tabs can only be whitespace in valid JSON. The text
    is read within the same bounds as YAML (size, UTF-8), and the YAML parse applies the same nesting and size bounds."""
    text = read_text(path, "edges file")
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UserError(f"JSON syntax error: {exc.msg} (column {exc.colno})", Where(path, exc.lineno)) from None
    except RecursionError:  # nested beyond Python's limit: the YAML parse below names the line where it gets too deep
        parse_document(text.replace("\t", " "), path)
        raise UserError(f"nested too deeply (more than {MAX_DEPTH} levels)", Where(path, 1)) from None
    try:
        lines = parse_document(text.replace("\t", " "), path).lines
    except UserError as exc:
        if not exc.message.startswith("YAML syntax error"):
            raise  # a duplicate key, or beyond the bounds (nesting, nodes)
        lines = {}  # valid JSON that PyYAML cannot follow: errors then point at line 1
    return Document(path, data, lines)
