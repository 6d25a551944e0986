"""The run's JSON manifest: every output with its content hash, so a re-run skips what is up to date.

It is rewritten atomically as segments finish, so after a crash or Ctrl-C it lists exactly the complete files. A
written segment's entry also holds its `summary` (execute/manifest_entry.py), which `segment_summaries` reads back for
a dataset browser without opening any recording; an entry without one stays valid (a new FORMAT would throw every
existing manifest away). Entries of segments not selected by this run (another `--episodes` range) are kept while
their files exist.
"""

from __future__ import annotations

import json
import os
import stat
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from ..confine import Confinement, confinement_for, file_state, os_cause, resolved_or_written
from ..errors import UserError, Where, shown
from ..execute import SegmentSummary, foreign_reason, require_ours, write_file_atomically
from ..package import __version__

if TYPE_CHECKING:
    from ..plan import Plan

FORMAT = 1
MANIFEST_BYTES = 24 << 20  # what a reader of a manifest (browse) takes: an entry is ~300 bytes + 80 a joint (16,000 arms, 9,000 humanoids)
MANIFEST_SEGMENTS = 20_000  # entries a reader takes: each is checked against the read rule
MANIFEST_VALUES = 1_500_000  # JSON values a reader parses (a segment with its summary holds about 52)
OutputKind = Literal["recording", "blueprint"]  # what a reader of a run's outputs publishes


@dataclass
class Manifest:
    path: Path
    application_id: str
    layout: str
    config: Path
    model: dict[str, Any] | None = None
    blueprint: dict[str, Any] | None = None
    files: dict[str, Any] = field(default_factory=dict)  # input path -> [size, mtime_ns, sha256] (fingerprint.py)
    segments: dict[str, dict[str, Any]] = field(default_factory=dict)
    _next_write: float = 0.0  # time.monotonic() from which a throttled write is due
    _lines: dict[str, tuple[dict[str, Any], str]] = field(default_factory=dict)  # segment id -> (entry, its JSON line)
    places: dict[str, int] = field(default_factory=dict)  # segment id -> its index in the file's `segments` (for messages)

    @classmethod
    def load(cls, path: Path, application_id: str, layout: str, config: Path, where: Where | None = None) -> Manifest:
        """The manifest at `path` (empty when there is none); a UserError when a file there is not a manifest of ours."""
        manifest = cls(path, application_id, layout, config)
        require_ours(path, "manifest", where)
        if not path.is_file():
            return manifest
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            return manifest  # unreadable: start afresh, every output is checked again
        if data.get("format") != FORMAT or data.get("application_id") != application_id or data.get("layout") != layout:
            return manifest
        # Entries of the wrong shape (a hand edit, a pull request) are not trusted: their outputs are checked again.
        manifest.model = data.get("model") if _is_entry(data.get("model")) else None
        manifest.blueprint = data.get("blueprint") if _is_entry(data.get("blueprint")) else None
        files = data.get("files")
        manifest.files = {path: entry for path, entry in files.items() if _is_file_hash(entry)} if isinstance(files, dict) else {}
        segments = data.get("segments")
        entries = segments if isinstance(segments, list) else []
        manifest.segments = {e["segment"]: e for e in entries if _is_entry(e) and isinstance(e.get("segment"), str)}
        manifest.places = {e["segment"]: i for i, e in enumerate(entries) if _is_entry(e) and isinstance(e.get("segment"), str)}
        return manifest

    def where(self, label: str, key: str = "path") -> Where:
        """The place of a segment's entry in the file, for a message naming it (`segments[3].path`)."""
        return Where(self.path, 0, f"segments[{self.places.get(label, '?')}].{key}")

    def entry(self, label: str) -> dict[str, Any] | None:
        return self.model if label == "model" else self.segments.get(label)

    def up_to_date(self, label: str, output: Path, content_hash: str) -> bool:
        """The manifest says this file was written from the same content, and the file is still that size."""
        entry = self.entry(label)
        if entry is None or entry.get("content_sha256") != content_hash:
            return False
        return self.resolve(entry["path"]) == output and _size(output) == entry.get("bytes")

    def record(self, label: str, output: Path, content_hash: str, frames: int, extra: dict[str, Any], size: int | None = None) -> None:
        """`extra` may hold an uploaded output's `url` and `etag` (its staged file is gone: `size` says its bytes)."""
        entry = {
            "path": os.path.relpath(output, self.path.parent),
            "content_sha256": content_hash,
            "bytes": output.stat().st_size if size is None else size,
            "frames": frames,
            **extra,
        }
        if label == "model":
            self.model = entry
        else:
            self.segments[label] = {"segment": label, **entry}

    def blueprint_up_to_date(self, path: Path, key: str) -> bool:
        """The blueprint at `path` is the one this manifest recorded for `key`, untouched since (size and mtime): it
        is neither checked nor written again, so an up-to-date run needs no Rerun."""
        entry = self.blueprint
        if entry is None or entry.get("content_sha256") != key or self.resolve(entry["path"]) != self.resolve(str(path)):
            return False
        try:
            status = path.stat()
        except (OSError, ValueError):
            return False
        return [status.st_size, status.st_mtime_ns] == [entry.get("bytes"), entry.get("mtime_ns")]

    def record_blueprint(self, path: Path, key: str) -> None:
        status = path.stat()
        relative = os.path.relpath(path, self.path.parent)
        self.blueprint = {"path": relative, "content_sha256": key, "bytes": status.st_size, "mtime_ns": status.st_mtime_ns}

    def resolve(self, relative: str) -> Path:
        """An entry's path, resolved; as written when the OS cannot follow it (a loop, a name too long: the manifest may
        come from a pull request), which then matches no output and names no file."""
        return resolved_or_written(self.path.parent / relative)

    def outputs(self) -> list[tuple[str, Path]]:
        """(segment id, layer or recording path) of every segment the manifest lists whose file exists."""
        return [(s, self.resolve(e["path"])) for s, e in sorted(self.segments.items()) if _exists(self, e)]

    def _line(self, label: str, entry: dict[str, Any]) -> str:
        """A segment's entry as one line of JSON, made once per entry: a large manifest is rewritten every second."""
        cached = self._lines.get(label)
        if cached is None or cached[0] is not entry:
            cached = self._lines[label] = (entry, json.dumps(entry, sort_keys=True))
        return cached[1]

    def write(self, every_seconds: float = 0.0) -> None:
        """Atomically; `every_seconds` throttles the rewrites of a long run (the last one is always forced), and so does
        the time a write takes (10 times its last duration): rewriting a large manifest takes at most a tenth of the driver."""
        if self.model is None and not self.segments and not self.path.exists():
            return  # nothing written, nothing to list: a failed first run leaves no file behind
        started = time.monotonic()
        if every_seconds and started < self._next_write:
            return
        # each entry's file, as the OS finds it (one stat, not `resolve`'s lstat of every folder on the way)
        listed = [(label, e) for label, e in sorted(self.segments.items()) if _exists(self, e)]
        data = {
            "format": FORMAT,
            "urdf_pipeline": __version__,
            "config": str(self.config),
            "application_id": self.application_id,
            "layout": self.layout,
            "model": self.model,
            "blueprint": self.blueprint,
            "files": self.files,
        }
        head = json.dumps(data, indent=1, sort_keys=True)
        segments = ",\n".join(f"  {self._line(label, entry)}" for label, entry in listed)
        text = f'{head[:-2]},\n "segments": [\n{segments}\n ]\n}}\n' if segments else f'{head[:-2]},\n "segments": []\n}}\n'
        write_file_atomically(self.path, lambda partial: partial.write_text(text, encoding="utf-8"), None)  # ours: see load
        finished = time.monotonic()
        self._next_write = finished + max(every_seconds, 10 * (finished - started))


@dataclass(frozen=True)
class SegmentEntry:
    """One written segment as the manifest lists it, for a dataset browser: every value checked for its type (a hand-
    edited manifest gives None, never an exception). `path` passed the read rule and is a recording the tool wrote
    (`segment_summaries`); `segment` is as the manifest says: show it through `errors.shown`; the summary's names are
    already shown, bounded."""

    segment: str
    path: Path  # resolved against the manifest's folder
    frames: int | None
    episode: int | None
    summary: SegmentSummary | None  # None for an entry written before summaries, or adopted from its file
    url: str | None = None  # an output in S3: its URL and the ETag the run recorded (`path` is then its staged path)
    etag: str | None = None
    where: Where | None = None  # the entry in the manifest, for a message naming it


def segment_summaries(plan: Plan) -> list[SegmentEntry]:
    """The segments the config's manifest lists whose files exist, in the manifest's order (by segment id); empty when
    there is no manifest yet. A UserError when the file at the manifest's path is not a manifest of ours, and (a
    manifest is data from whoever wrote the folder: a pull request) when an entry names a file the read rule refuses or
    a file that is not a recording the tool wrote (`run_output`). Outputs in S3 keep their URL and ETag; their key is
    checked where they are fetched (`remote_outputs.local_outputs`). Bounded before it is parsed: at most MANIFEST_BYTES
    and MANIFEST_VALUES (counted as read) and MANIFEST_SEGMENTS entries, no two naming the same file."""
    _require_bounded(plan.dataset.manifest, Where(plan.dataset.manifest, 0))
    manifest = Manifest.load(plan.dataset.manifest, plan.application_id, plan.dataset.layout, plan.config_path, plan.output_where)
    if len(manifest.segments) > MANIFEST_SEGMENTS:
        raise UserError(
            f"lists {len(manifest.segments):,} segments; a browser takes at most {MANIFEST_SEGMENTS:,}: browse a config that "
            "selects fewer episodes (output.episodes)",
            Where(manifest.path, 0, "segments"),
        )
    confinement = confinement_for(plan.config_path)
    found: list[SegmentEntry] = []
    named: dict[Path, str] = {}  # each file once: a manifest naming one recording 20,000 times is no dataset
    for label, entry in sorted(manifest.segments.items()):
        where = manifest.where(label, "path" if plan.dataset.remote is None else "url")
        if plan.dataset.remote is not None:  # the staged path is never read: the object is, by its URL
            if isinstance(entry.get("etag"), str):
                found.append(_segment_entry(label, manifest.resolve(entry["path"]), entry, where))
            continue
        path = run_output(manifest.path.parent / _home_expanded(entry["path"]), "recording", "the recording", where, confinement)
        if path is None:
            continue
        if path in named:
            raise UserError(f"names the file {named[path]} names ({shown(str(path))}): each segment has a recording of its own", where)
        named[path] = where.path
        found.append(_segment_entry(label, path, entry, where))
    return found


def _require_bounded(path: Path, where: Where) -> None:
    """The manifest at `path` holds at most MANIFEST_BYTES and MANIFEST_VALUES JSON values (counted on the bytes as
    they are read: each value but the first follows a `,`, `[` or `{`), before anything is parsed: a parse takes up to
    30 times its text in memory (a file of `{},{},...`), so both bound what a reader of a stranger's manifest takes. A
    FIFO or device there is refused, not read."""
    if file_state(path, "manifest", where) != "file":
        return  # none yet (or a folder: Manifest.load refuses it)
    read = values = 0
    try:
        with open(path, "rb") as file:
            while chunk := file.read(1 << 20):
                read += len(chunk)
                values += chunk.count(b",") + chunk.count(b"[") + chunk.count(b"{")
                if read > MANIFEST_BYTES or values > MANIFEST_VALUES:
                    raise UserError(
                        f"is over {MANIFEST_BYTES >> 20} MiB or {MANIFEST_VALUES:,} JSON values (a segment's entry is about 300 "
                        "bytes and 80 a joint: about 16,000 segments of an arm, 9,000 of a humanoid); a browser reads no "
                        "more: browse a config that selects fewer episodes (output.episodes)",
                        where,
                    )
    except OSError as exc:
        raise UserError(f"cannot be read: {os_cause(exc, path)}", where) from None


def run_output(
    path: Path, kind: OutputKind, what: str, where: Where | None, confinement: Confinement | None, named: str | None = None
) -> Path | None:
    """`path` resolved when it is a file a run of the tool wrote (a recording with our recording property, a blueprint),
    None when nothing is there; a UserError naming `where` when the read rule (`confinement`) refuses it (outside every
    root, a FIFO, a loop) or it is anything else (a symbolic link, a folder, a page, a script, another tool's
    recording): what a reader publishes must be the run's own output, never a file a manifest merely names. `named`:
    how the message names the file (default: `path`; an object's URL for its cached copy)."""
    real = confinement.check_read(path, what, where) if confinement is not None else resolved_or_written(path)
    if not os.path.lexists(path):
        return None
    reason = foreign_reason(path, kind)
    if reason is not None:
        raise UserError(
            f"{what} {shown(named or str(path))} is not one of the run's outputs: {reason}; only the files a run wrote are published "
            "(`urdf-pipeline run CONFIG --force` writes them again)",
            where,
        )
    return real


def _home_expanded(text: str) -> Path:
    """An entry's path with `~` expanded: `~/.aws/credentials` in a manifest means that file, and is refused as such
    (the run writes relative paths only); as written when no home is known for it."""
    try:
        return Path(text).expanduser()
    except RuntimeError:
        return Path(text)


def _segment_entry(label: str, path: Path, entry: dict[str, Any], where: Where) -> SegmentEntry:
    def number(key: str) -> int | None:
        value = entry.get(key)
        return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else None

    summary = SegmentSummary.from_json(entry.get("summary"))
    url, etag = entry.get("url"), entry.get("etag")
    url, etag = (url, etag) if isinstance(url, str) and isinstance(etag, str) else (None, None)
    return SegmentEntry(label, path, number("frames"), number("episode"), summary, url, etag, where)


def _exists(manifest: Manifest, entry: dict[str, Any]) -> bool:
    """The entry's output is there: its file, or (uploaded to S3, `etag`) its object as the run that wrote it saw it
    (`run` compares the bucket's listing before it trusts an entry)."""
    return isinstance(entry.get("etag"), str) or _size(manifest.path.parent / entry["path"]) is not None  # one stat


def _size(path: Path) -> int | None:
    """The size of the regular file at `path`; None when there is none or the OS cannot tell (never an exception)."""
    try:
        status = path.stat()
    except (OSError, ValueError):
        return None
    return status.st_size if stat.S_ISREG(status.st_mode) else None


def _is_entry(entry: Any) -> bool:
    """An output's entry: a mapping with its path."""
    return isinstance(entry, dict) and isinstance(entry.get("path"), str)


def _is_file_hash(entry: Any) -> bool:
    """An input's [size, mtime_ns, sha256]."""
    return (
        isinstance(entry, list)
        and len(entry) == 3
        and all(isinstance(n, int) and not isinstance(n, bool) for n in entry[:2])
        and isinstance(entry[2], str)
    )
