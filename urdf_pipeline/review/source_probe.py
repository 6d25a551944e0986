"""init's view of a source (SOURCE_SPEC -> the config entry and the names), from metadata only, as validate reads it."""

from __future__ import annotations

import glob
import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

from ..config.document import Document
from ..errors import UserError, listing
from .yaml_writer import Block

KINDS = ("lerobot", "parquet", "mcap", "hdf5", "rrd")
GLOB = re.compile(r"[*?\[]")


STUB_SOURCE_DIR = "TODO"  # the stub parquet path starts here: it does not exist, so validate fails on it alone


@dataclass
class SourceInfo:
    kind: str
    entry: Block  # the config's source entry (names added later for positional sources)
    names: list[str] | None  # names from the metadata; None: the source has none (matched by position)
    width: int | None  # values per row when known (positional sources)
    segment: str  # output.segment template
    notes: list[str] = field(default_factory=list)


def parse_source_spec(text: str) -> tuple[str, str, str | None]:
    """`KIND:PATH[#PART]` -> (kind, path, part); KIND inferred from PATH when left out."""
    kind, sep, rest = text.partition(":")
    if not sep or kind not in KINDS:
        kind, rest = "", text
    path, hash_, part = rest.partition("#")
    if not path:
        raise UserError(f"--source '{text}': no path; the form is KIND:PATH[#PART], KIND one of {', '.join(KINDS)}")
    if not kind:
        suffix = Path(path).suffix.lower()
        by_suffix = {".parquet": "parquet", ".mcap": "mcap", ".h5": "hdf5", ".hdf5": "hdf5", ".rrd": "rrd"}
        if suffix in by_suffix:
            kind = by_suffix[suffix]
        elif (Path(path) / "meta" / "info.json").is_file():
            kind = "lerobot"
        else:
            raise UserError(
                f"--source '{text}': say which kind of source it is: lerobot:DIR[#FEATURE], parquet:FILE[#COLUMN], "
                "mcap:FILE[#TOPIC], hdf5:FILE#/DATASET or rrd:FILE#ENTITY"
            )
    return kind, path, (part or None) if hash_ else None


def _relative(target: str | Path, base: Path) -> str:
    """`target` for a config in folder `base`: relative (as the pipeline resolves it, `(base / rel).resolve()`) when
    the two share a top folder, else absolute; with `/`."""
    real_base = os.path.realpath(base)
    real_target = os.path.realpath(target)
    absolute = os.path.abspath(target)
    options = []
    for path in (absolute, real_target):  # as given (keeping its symlinks), and resolved
        relative = os.path.relpath(path, real_base)
        shares_a_folder = os.path.commonpath([real_base, path]) != os.path.abspath(os.sep)
        if shares_a_folder and os.path.realpath(os.path.join(real_base, relative)) == real_target:
            options.append(relative)
    if not options:
        return Path(absolute).as_posix()
    return Path(min(options, key=len)).as_posix()  # the shorter; equal length: the one as given


def _relative_pattern(pattern: str, base: Path) -> str:
    folder, name = os.path.split(pattern)
    split = [i for i, part in enumerate(Path(pattern).parts) if GLOB.search(part)]
    if split and split[0] < len(Path(pattern).parts) - 1:  # a glob in a folder name: keep it as given, made absolute
        return Path(os.path.abspath(pattern)).as_posix()
    return f"{_relative(folder or '.', base)}/{name}".removeprefix("./")


def _document(out_file: Path) -> Document:
    return Document(out_file, {}, {})


def _reraise(text: str, exc: UserError) -> UserError:
    return UserError(f"--source {text}: {exc.message}")


def _first_file(text: str, path: str) -> Path:
    if GLOB.search(path):
        found = sorted(p for p in glob.glob(path, recursive=True) if Path(p).is_file())
        if not found:
            raise UserError(f"--source {text}: '{path}' matches no file")
        return Path(found[0]).resolve()
    resolved = Path(path).resolve()
    if not resolved.is_file():
        raise UserError(f"--source {text}: file not found: {resolved}")
    return resolved


def read_source(text: str, key: str, out_file: Path) -> SourceInfo:
    kind, path, part = parse_source_spec(text)
    base = out_file.parent
    globbed = kind != "lerobot" and bool(GLOB.search(path))
    config_path = _relative_pattern(path, base) if globbed else _relative(path, base)
    segment = "{stem}" if globbed else re.sub(r"[^A-Za-z0-9_.-]", "_", Path(path).name.split(".", 1)[0]) or "segment"
    entry = Block()
    entry.add(kind, config_path)
    if kind == "lerobot":
        return _lerobot(text, key, path, part, entry, out_file)
    file = _first_file(text, path)
    if kind == "parquet":
        return _parquet(text, file, part, entry, segment)
    if kind == "mcap":
        return _mcap(text, key, file, part, entry, segment, out_file)
    if kind == "hdf5":
        return _hdf5(text, key, file, part, entry, segment, out_file)
    return _rrd(text, key, file, part, entry, segment, out_file)


def _lerobot(text: str, key: str, path: str, part: str | None, entry: Block, out_file: Path) -> SourceInfo:
    from ..sources import lerobot

    feature = part or "observation.state"
    entry.add("feature", feature)
    root = Path(path).resolve()
    spec = {"lerobot": str(root), "feature": feature}
    info = SourceInfo("lerobot", entry, None, None, "episode_{episode:06d}")
    info.notes.append("no episode: one segment per episode of the dataset (episode: N pins one)")
    try:
        plan = lerobot.compile_source(key, spec, _document(out_file), root)
    except UserError as exc:
        width = _lerobot_unnamed_width(root, feature)
        if width is None:
            raise _reraise(text, exc) from None
        info.width = width  # a feature without names: matched by position, names given in the config
        return info
    info.names = list(plan.names)
    return info


def _lerobot_unnamed_width(root: Path, feature: str) -> int | None:
    from ..sources.lerobot import feature_names

    try:
        features = json.loads((root / "meta" / "info.json").read_text(encoding="utf-8")).get("features", {})
    except (OSError, json.JSONDecodeError):
        return None
    spec = features.get(feature)
    if not isinstance(spec, dict) or feature_names(spec) is not None:
        return None
    shape = spec.get("shape") or []
    return int(shape[0]) if len(shape) == 1 and isinstance(shape[0], int) else None


_SEQUENCE_COLUMNS = ("frame_index", "index", "frame", "step", "seq", "sequence")
_TIME_COLUMNS = ("timestamp", "time", "t", "stamp")


def _parquet(text: str, file: Path, part: str | None, entry: Block, segment: str) -> SourceInfo:
    import pyarrow as pa
    import pyarrow.parquet as pq

    from ..sources.parquet import _numeric_list_width

    try:
        schema = pq.read_schema(file)
    except (pa.ArrowInvalid, OSError) as exc:
        raise UserError(f"--source {text}: cannot read the parquet schema of {file}: {exc}") from None
    lists = [name for name in schema.names if _numeric_list_width(schema.field(name).type) is not False]
    if part is not None:
        column = part
    elif "observation.state" in lists:
        column = "observation.state"
    elif len(lists) == 1:
        column = lists[0]
    else:
        raise UserError(
            f"--source {text}: name the column with parquet:FILE#COLUMN; list columns of {file.name}: {listing(lists, empty='none')}"
        )
    if column not in schema.names:
        raise UserError(f"--source {text}: column '{column}' not in {file.name}; it has: {', '.join(schema.names)}")
    width = _numeric_list_width(schema.field(column).type)
    if width is False:
        raise UserError(f"--source {text}: column '{column}' is {schema.field(column).type}, not a list of numbers")
    entry.add("column", column)
    integers = [n for n in schema.names if pa.types.is_integer(schema.field(n).type)]
    times = [
        n
        for n in schema.names
        if pa.types.is_timestamp(schema.field(n).type) or (pa.types.is_floating(schema.field(n).type) and n.lower() in _TIME_COLUMNS)
    ]
    sequence = next((n for n in _SEQUENCE_COLUMNS if n in integers), None)
    if sequence is not None:
        entry.add("index", sequence, "review: the timeline column (a sequence); or {timestamp: COL, unit: s}")
    elif times:
        entry.add(
            "index", {"timestamp": times[0], "unit": "s"}, "review: time since the epoch; {duration: COL, unit: s} if it counts from 0"
        )
    else:
        entry.add("index", "frame_index", f"TODO: {file.name} has no frame or time column this could guess; name its timeline column")
    return SourceInfo("parquet", entry, None, width if isinstance(width, int) else None, segment)


def _mcap(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from rerun.chunk import McapReader

    from ..sources import mcap

    topic = part
    if topic is None:
        try:
            channels = McapReader(file).info().channels
        except (ValueError, OSError, RuntimeError) as exc:
            raise UserError(f"--source {text}: cannot read MCAP file {file}: {exc}") from None
        topics = sorted({c.topic for c in channels if c.schema is not None and c.schema.name == mcap.JOINT_STATE})
        if len(topics) != 1:
            raise UserError(
                f"--source {text}: name the topic with mcap:FILE#TOPIC; its {mcap.JOINT_STATE} topics: {listing(topics, empty='none')}"
            )
        topic = topics[0]
    entry.add("topic", topic)
    try:
        plan = mcap.compile_source(key, {"mcap": str(file), "topic": topic}, _document(out_file), file.parent)
    except UserError as exc:
        raise _reraise(text, exc) from None
    info = SourceInfo("mcap", entry, list(plan.names), None, segment)
    info.notes.append("names: read from the topic's first message by validate (every name must be mapped or ignored)")
    return info


def _hdf5(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from ..sources import hdf5

    dataset = hdf5.dataset_path(part or "/")
    try:
        plan = hdf5.compile_source(key, {"hdf5": str(file), "dataset": dataset}, _document(out_file), file.parent)
    except UserError as exc:
        raise UserError(f"--source {text}: {exc.message}" + ("; name it with hdf5:FILE#/DATASET" if part is None else "")) from None
    entry.add("dataset", dataset)
    info = SourceInfo("hdf5", entry, None, len(plan.names), segment)
    info.notes.append("index: /DATASET  (optional: a 1-D dataset of times or frame numbers; default a row_index sequence)")
    return info


def _rrd(text: str, key: str, file: Path, part: str | None, entry: Block, segment: str, out_file: Path) -> SourceInfo:
    from ..sources import rrd

    if part is None:
        raise UserError(
            f"--source {text}: name the entity holding the values with rrd:FILE#ENTITY, e.g. rrd:{file.name}#/observation.state"
        )
    entry.add("entity", rrd.entity_path(part))
    try:
        plan = rrd.compile_source(key, {"rrd": str(file), "entity": part}, _document(out_file), file.parent)
    except UserError as exc:
        raise _reraise(text, exc) from None
    return SourceInfo("rrd", entry, list(plan.names), None, segment)


def stub_source(key: str, joints: list[str]) -> SourceInfo:
    entry = Block()
    entry.add("parquet", f"{STUB_SOURCE_DIR}/{key}.parquet", "TODO: your data: one row per frame (or another source kind)")
    entry.add("column", "observation.state", "TODO: the list<float> column holding one value per name")
    entry.add("index", "frame_index", "TODO: the timeline column (a sequence); or {timestamp: COL, unit: s}")
    info = SourceInfo("parquet", entry, None, len(joints), "episode_000")
    return info
