"""Content hashes: an output is up to date when the hash of everything it was made from is unchanged.

What goes in: the pipeline's version, the compiled plan for that output (joint mapping, corrections, edges, the
resolved URDF text: what the YAML means, not its comments or key order), and the bytes of the files it reads
(the segment's input files; for outputs holding the model, the mesh files). A remote input goes in as its URL and
its version (the S3 ETag), read by one HEAD when the config is compiled: an unchanged object is not downloaded.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import re
from collections.abc import Mapping, Sequence
from functools import cache
from pathlib import Path
from typing import Any

from ..package import __version__
from ..plan import Plan, TrailPlan

MESH_FILENAME = re.compile(r'filename\s*=\s*"([^"]+)"')


_KNOWN: dict[str, tuple[int, int, str]] = {}  # path -> (size, mtime_ns, sha256) recorded by an earlier run's manifest
_USED: dict[str, tuple[int, int, str]] = {}  # the same for every file hashed by this run, for its manifest


def remember_file_hashes(known: Mapping[str, Sequence[Any]]) -> None:  # [size, mtime_ns, sha256], as Manifest.load checked
    """Hashes an earlier run recorded: a file whose size and mtime are unchanged is not read again (an up-to-date
    re-run of a large dataset would otherwise read every input); `--force` still rewrites every output. Starts a run:
    what the previous run used is forgotten."""
    _USED.clear()
    for path, (size, mtime_ns, digest) in known.items():
        _KNOWN[path] = (size, mtime_ns, digest)


def file_hashes_used() -> dict[str, list[Any]]:
    return {path: list(entry) for path, entry in sorted(_USED.items())}


def file_sha256(path: Path) -> str:
    stat = path.stat()
    known = _KNOWN.get(str(path))
    if known is not None and known[:2] == (stat.st_size, stat.st_mtime_ns):
        digest = known[2]
    else:
        digest = _file_sha256(path, stat.st_size, stat.st_mtime_ns)
    _USED[str(path)] = (stat.st_size, stat.st_mtime_ns, digest)
    return digest


@cache
def _file_sha256(path: Path, size: int, mtime_ns: int) -> str:  # size and mtime: a changed file is hashed again
    digest = hashlib.sha256()
    with path.open("rb") as file:
        for block in iter(lambda: file.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _canonical(value: Any) -> Any:
    """JSON-able form of a plan part; `where` (config line numbers) is left out: moving a line changes no output."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        # a remote file (dataset) is its URL and version; its `path` (`root`) is where this machine's cache keeps it. A
        # local one's plan leaves `remote` (None) out: a source kind that learned to read URLs changes no local file's hash
        left_out = {"where", "path", "root"} if getattr(value, "remote", None) is not None else {"where", "remote"}
        return {
            "type": type(value).__name__,
            **{f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value) if f.name not in left_out},
        }
    if isinstance(value, tuple | list):
        return [_canonical(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in value.items()}
    if isinstance(value, Path):
        return str(value)
    if isinstance(value, float):
        return repr(value)
    return value


def _mesh_files(plan: Plan) -> list[Path]:
    paths = {Path(m) for robot in plan.robots for m in MESH_FILENAME.findall(robot.urdf_text)}
    return sorted(p for p in paths if p.is_file())


def _digest(parts: dict[str, Any]) -> str:
    return hashlib.sha256(json.dumps(parts, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def _drawn(trail: TrailPlan) -> TrailPlan:
    """What of a trail its recording holds: the window is the blueprint's (its own key), not the recording's."""
    return dataclasses.replace(trail, window=None, window_unit="s", timelines=())


def segment_hashes(plan: Plan, with_model: bool) -> dict[str, str]:
    """The content hash of each segment's recording (single layout: with_model) or layer (split layout), by segment id."""
    common = _digest(
        {
            "version": __version__,
            "what": "single" if with_model else "layer",
            "application_id": plan.application_id,
            "robots": _canonical(plan.robots),
            "edges": _canonical(plan.edges),
            "temporal_edges": _canonical(plan.temporal_edges),
            "root": plan.root_frame,
            "meshes": [file_sha256(p) for p in _mesh_files(plan)] if with_model else [],
            # only when set: the hashes of recordings without the series are what they were before the option
            **({"joint_series": True} if plan.dataset.joint_series else {}),
            **({"trails": _canonical([_drawn(t) for t in plan.trails])} if plan.trails else {}),  # the same rule for `trails:`
        }
    )
    return {
        segment.id: _digest(
            {
                "common": common,
                "segment": _canonical(dataclasses.replace(segment, output=Path(segment.output.name))),
                "inputs": [file_sha256(p) for p in segment.inputs],
            }
        )
        for segment in plan.segments
    }


def model_hash(plan: Plan) -> str:
    """The content hash of the split layout's model asset: the robots' URDFs, settings and meshes."""
    return _digest(
        {
            "version": __version__,
            "what": "model",
            "application_id": plan.application_id,
            "robots": [[r.key, r.urdf_text, r.entity_path_prefix, r.frame_prefix, r.keep_collisions] for r in plan.robots],
            "meshes": [file_sha256(p) for p in _mesh_files(plan)],
            # only when set: the models of robots drawn in their URDF's colours keep the hashes they had
            **(
                {"appearance": {r.key: list(r.appearance) for r in plan.robots if r.appearance}}
                if any(r.appearance for r in plan.robots)
                else {}
            ),
        }
    )
