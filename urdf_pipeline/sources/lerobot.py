"""One episode of a LeRobot dataset (v2.x or v3), read with Rerun's LeRobotReader, video skipped."""

from __future__ import annotations

import functools
import json
import os
import string
from collections.abc import Callable, Mapping
from pathlib import Path
from types import MappingProxyType
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
import pyarrow as pa

from ..config import Document
from ..confine import file_state
from ..errors import UserError, Where
from ..plan import IndexPlan, LeRobotSourcePlan
from .base import EntryField, SourceDescription, no_remote_files, resolve_input
from .integrity import check_parquet_pages
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream

if TYPE_CHECKING:
    from rerun.chunk import Chunk
    from rerun.experimental import LeRobotReader

T = TypeVar("T")
check_download = no_remote_files
PLAN_TYPE = LeRobotSourcePlan
SPEC_FORM = "lerobot:DIR[#FEATURE]"
SUFFIXES: tuple[str, ...] = ()  # a folder: `is_dataset` says it
VECTOR_COMPONENT = "urdf_pipeline:joint_values"
FRAME_INDEX = IndexPlan("frame_index", "sequence", None)  # the timeline of every LeRobot source


def feature_names(feature: dict[str, Any]) -> list[str] | None:
    """LeRobot writes names as a list, a list holding one list, or {"motors": [...]}; accept all three."""
    names = feature.get("names")
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and len(names) == 1 and isinstance(names[0], list):
        names = names[0]
    if isinstance(names, list) and all(isinstance(n, str) for n in names):
        return names
    return None


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> LeRobotSourcePlan:
    here = ("sources", name)
    root = resolve_input(document, config_dir, spec["lerobot"], *here, "lerobot", directory=True)
    info_path = root / "meta" / "info.json"
    info = _info(root, document.where(*here, "lerobot"))
    version = str(info.get("codebase_version", ""))
    if not (version.startswith("v2") or version.startswith("v3")):
        raise UserError(f"LeRobot codebase_version '{version}' is not supported (v2.x or v3 only)", document.where(*here, "lerobot"))
    feature_key = spec.get("feature", "observation.state")
    features = info.get("features", {})
    if not isinstance(features, dict) or not all(isinstance(f, dict) for f in features.values()):
        raise UserError(f"'features' in {info_path} is not a mapping of feature names to mappings", document.where(*here, "lerobot"))
    _data_path_template(info, info_path, document.where(*here, "lerobot"))
    if feature_key not in features:
        numeric = [k for k, f in features.items() if f.get("dtype") in ("float32", "float64")]
        raise UserError(
            f"feature '{feature_key}' not in {info_path}; numeric features: {', '.join(numeric)}", document.where(*here, "feature")
        )
    feature = features[feature_key]
    shape = feature.get("shape") or [None]
    width = shape[0] if len(shape) == 1 else None
    names = tuple(spec["names"]) if "names" in spec else tuple(feature_names(feature) or ())
    if not names:
        raise UserError(f"feature '{feature_key}' has no names in {info_path}; give them with names: [...]", document.where(*here))
    if width is not None and width != len(names):
        raise UserError(
            f"feature '{feature_key}' holds {width} values per row but {len(names)} names are given",
            document.where(*here, "names" if "names" in spec else "feature"),
        )
    if "episode" not in spec:  # one segment per episode; segments.py picks them and fills in `episode`
        return with_duplicates(LeRobotSourcePlan(name, root, feature_key, -1, names, document.where(*here), per_segment=True), spec)
    episode = int(spec["episode"])
    total = info.get("total_episodes")
    if isinstance(total, int) and episode >= total:
        raise UserError(
            f"episode {episode} does not exist: the dataset has {total} episodes (0..{total - 1})", document.where(*here, "episode")
        )
    plan = with_duplicates(LeRobotSourcePlan(name, root, feature_key, episode, names, document.where(*here)), spec)
    check_episode_data(plan, document.where(*here, "episode"))
    return plan


# What a hostile or broken dataset's metadata raises while it is read: each becomes one user error at the source.
METADATA_ERRORS = (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError, pa.ArrowException)
TEMPLATE_FIELDS = frozenset({"episode_chunk", "episode_index", "chunk_index", "file_index"})


def _info(root: Path, where: Where | None = None) -> dict[str, Any]:
    """meta/info.json as a mapping; a user error when it is missing, no regular file (a FIFO would block), or not a
    JSON object."""
    path = root / "meta" / "info.json"
    if file_state(path, "LeRobot metadata file", where) != "file":
        raise UserError(f"{root} is not a LeRobot dataset: {path} is missing", where)
    try:
        info = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise UserError(f"cannot read {path}: {exc}", where) from None
    if not isinstance(info, dict):
        raise UserError(f"{path} holds {type(info).__name__}, not a JSON object", where)
    return info


def _data_path_template(info: dict[str, Any], info_path: Path, where: Where | None) -> str:
    """info.json's data_path: relative, inside the dataset (no `..`), with only LeRobot's own fields and no attribute
    or item access (`{episode_index.__class__}` would reach into Python objects)."""
    template = str(info.get("data_path", ""))
    try:
        fields = {name for _, name, _, _ in string.Formatter().parse(template) if name is not None}
    except ValueError as exc:
        raise UserError(f"data_path '{template}' in {info_path} is not a path template: {exc}", where) from None
    if not fields <= TEMPLATE_FIELDS or Path(template).is_absolute() or ".." in Path(template).parts:
        raise UserError(
            f"data_path '{template}' in {info_path} must stay inside the dataset and use only "
            f"{', '.join('{' + f + '}' for f in sorted(TEMPLATE_FIELDS))}",
            where,
        )
    return template


def _metadata(plan: LeRobotSourcePlan, read: Callable[[], T]) -> T:
    """`read()` of the dataset's metadata; whatever a broken file raises is a user error at the source."""
    try:
        return read()
    except METADATA_ERRORS as exc:
        raise UserError(f"cannot read the episode metadata of LeRobot dataset {plan.root}: {exc}", plan.where) from None


def is_dataset(path: Path) -> bool:
    """A folder holding meta/info.json: what `init` takes for a LeRobot dataset when `lerobot:` is left out."""
    try:
        return (path / "meta" / "info.json").is_file()
    except (OSError, ValueError):  # a name too long, no permission: not a dataset, `init` says what it cannot read
        return False


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the feature's (PART, default `observation.state`) names from meta/info.json, as `validate` reads
    them; a feature without names is described by its width (its values are then matched by position)."""
    feature = part or "observation.state"
    root = Path(path).resolve()
    fields = (EntryField("feature", feature),)
    segment = "episode_{episode:06d}"
    notes = ("no episode: one segment per episode of the dataset (episode: N pins one)",)
    try:
        plan = compile_source(name, {"lerobot": str(root), "feature": feature}, document, root)
    except UserError:
        width = _unnamed_width(root, feature)
        if width is None:
            raise
        unnamed = "the feature has no names in meta/info.json"
        return SourceDescription("lerobot", fields, None, width, segment, unnamed=unnamed, notes=notes)
    return SourceDescription("lerobot", fields, plan.names, None, segment, notes=notes)


def _unnamed_width(root: Path, feature: str) -> int | None:
    """The width of a 1-D feature without names; None when the feature is missing, named or not 1-D."""
    try:
        features = _info(root).get("features", {})
    except UserError:
        return None
    spec = features.get(feature) if isinstance(features, dict) else None
    if not isinstance(spec, dict) or feature_names(spec) is not None:
        return None
    shape = spec.get("shape") or []
    return int(shape[0]) if len(shape) == 1 and isinstance(shape[0], int) else None


# A metadata file as last seen: (path, size, mtime_ns), the rule of the run's file hashes (dataset/fingerprint.py).
# What is read from the dataset's metadata is kept per process while its files are unchanged: every segment of a run
# asks for it, and reading it again each time made a run quadratic in the episodes (10,000 episodes: 57 ms a segment
# parsing episodes.jsonl, 9 ms opening Rerun's reader).
FileStamp = tuple[Path, int, int]


def _stamped(path: Path) -> FileStamp:
    status = os.stat(path)
    return (path, status.st_size, status.st_mtime_ns)


def _episode_files(root: Path) -> tuple[FileStamp, ...]:
    """The dataset's per-episode metadata files: v2's meta/episodes.jsonl or v3's meta/episodes/**/*.parquet."""
    jsonl = root / "meta" / "episodes.jsonl"
    if file_state(jsonl, "LeRobot metadata file", None) == "file":
        return (_stamped(jsonl),)
    files = sorted((root / "meta" / "episodes").glob("**/*.parquet"))
    return tuple(_stamped(f) for f in files if file_state(f, "LeRobot metadata file", None) == "file")


def _episode_table(root: Path) -> pa.Table | None:
    """The dataset's per-episode metadata (None without any)."""
    files = _episode_files(root)
    return _read_episode_table(files) if files else None


@functools.lru_cache(maxsize=4)
def _read_episode_table(files: tuple[FileStamp, ...]) -> pa.Table:
    import pyarrow.parquet as pq

    if files[0][0].name == "episodes.jsonl":
        rows = [json.loads(line) for line in files[0][0].read_text(encoding="utf-8").splitlines() if line.strip()]
        return pa.table({"episode_index": [int(r["episode_index"]) for r in rows], "length": [r.get("length") for r in rows]})
    wanted = ["episode_index", "length", "data/chunk_index", "data/file_index"]
    tables = [pq.read_table(f, columns=[c for c in wanted if c in pq.read_schema(f).names]) for f, _, _ in files]
    return pa.concat_tables(tables, promote_options="default")


def episodes(plan: LeRobotSourcePlan) -> dict[int, int | None]:
    """Episode index -> its length in frames (None when the metadata does not say), from the dataset's metadata only."""
    return dict(_metadata(plan, lambda: _episodes(plan)))  # a copy: the one kept is shared


def _episodes(plan: LeRobotSourcePlan) -> Mapping[int, int | None]:
    files = _episode_files(plan.root)
    if not files:
        total = int(_info(plan.root, plan.where).get("total_episodes", 0))
        return dict.fromkeys(range(total))
    return _episode_lengths(files)


@functools.lru_cache(maxsize=4)
def _episode_lengths(files: tuple[FileStamp, ...]) -> Mapping[int, int | None]:
    table = _read_episode_table(files)
    lengths = table.column("length").to_pylist() if "length" in table.column_names else [None] * table.num_rows
    return MappingProxyType(dict(zip(table.column("episode_index").to_pylist(), lengths, strict=True)))


def episode_inputs(plan: LeRobotSourcePlan) -> tuple[Path, ...]:
    """The files one episode is read from (for its content hash): meta/info.json and the episode's data file(s), each a
    regular file (a FIFO would block pyarrow and Rerun's reader). compile/segments.py applies the read rule to them."""
    inputs = _metadata(plan, lambda: _episode_inputs(plan))
    for file in inputs[1:]:  # one iteration per data file
        what = f"episode {plan.episode}: LeRobot data file"
        if file_state(file, what, plan.where) != "file":
            raise UserError(f"{what} {file} does not exist", plan.where)
    return inputs


def _episode_inputs(plan: LeRobotSourcePlan) -> tuple[Path, ...]:
    info = _info(plan.root, plan.where)
    meta = plan.root / "meta" / "info.json"
    template = _data_path_template(info, meta, plan.where)
    if "{episode_index" in template:  # v2: one file per episode
        chunk = plan.episode // int(info.get("chunks_size", 1000))
        path = plan.root / template.format(episode_chunk=chunk, episode_index=plan.episode)
        if file_state(path, "LeRobot data file", plan.where) == "file":
            return (meta, path)
    table = _episode_table(plan.root)
    if table is not None and {"data/chunk_index", "data/file_index"} <= set(table.column_names):  # v3: episodes share files
        import pyarrow.compute as pc  # here: 50 ms of every command otherwise, and only v3 datasets need it

        rows = table.filter(pc.equal(table.column("episode_index"), plan.episode)).to_pylist()
        paths = {plan.root / template.format(chunk_index=r["data/chunk_index"], file_index=r["data/file_index"]) for r in rows}
        if paths and all(file_state(p, "LeRobot data file", plan.where) == "file" for p in paths):
            return (meta, *sorted(paths))
    return (meta, *sorted((plan.root / "data").glob("**/*.parquet")))  # unknown layout: every data file, to be safe


def check_episode_data(plan: LeRobotSourcePlan, where: Where | None) -> None:
    """The episode has rows (by the dataset's metadata) and its data files decode (pyarrow, before Rerun's reader)."""
    import pyarrow.parquet as pq

    length = _metadata(plan, lambda: _episodes(plan)).get(plan.episode)
    files = episode_inputs(plan)[1:]
    if length == 0:
        raise UserError(
            f"episode {plan.episode} of LeRobot dataset {plan.root} has zero frames (meta says length 0); nothing would move", where
        )
    for file in files:  # one iteration per data file
        try:
            present = set(pq.read_schema(file).names)
        except (pa.ArrowException, OSError) as exc:
            raise UserError(f"episode {plan.episode}: cannot read parquet file {file}: {exc}", where) from None
        columns = [c for c in (plan.feature, "frame_index", "episode_index") if c in present]
        try:
            # the timeline Rerun's reader makes, frame_index, checked in the same pass: values beyond int64 would wrap
            check_parquet_pages(file, columns, where, FRAME_INDEX if "frame_index" in present else None, where)
        except UserError as exc:
            raise UserError(f"episode {plan.episode}: {exc.message}", where) from None


@functools.lru_cache(maxsize=4)
def _reader(root: Path, metadata: tuple[FileStamp, ...]) -> tuple[LeRobotReader, frozenset[int]]:
    """Rerun's reader of the dataset and its episodes, kept while `metadata` (info.json, the episode files) is
    unchanged: opening one reads the whole dataset's metadata."""
    from rerun.experimental import LeRobotReader

    reader = LeRobotReader(root)
    return reader, frozenset(reader.episodes())


def _one_vector_per_row(chunk: Chunk) -> list[Chunk]:
    """Scalars:scalars holds a row's values as instances; repack them as one list instance per row.

    Rerun's lenses hand a selector the row values flattened, so per-row FK needs one vector instance per row.
    """
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    index = batch.schema.get_field_index("Scalars:scalars")
    values = batch.column(index)
    wrapped = pa.ListArray.from_arrays(pa.array(np.arange(len(values) + 1, dtype=np.int32)), values)
    field = pa.field(VECTOR_COMPONENT, wrapped.type, metadata={b"rerun:kind": b"data", b"rerun:component": VECTOR_COMPONENT.encode()})
    return Chunk.from_record_batch(batch.set_column(index, field, wrapped))


def open_stream(plan: LeRobotSourcePlan) -> SourceStream:
    reader, known = _reader(plan.root, (_stamped(plan.root / "meta" / "info.json"), *_episode_files(plan.root)))
    if plan.episode not in known:
        raise UserError(f"episode {plan.episode} is not in {plan.root}", plan.where)
    if plan.per_segment:  # a pinned episode was checked when the config compiled
        check_episode_data(plan, plan.where)
    entity = f"/{plan.feature}"
    stream = (
        reader.stream(plan.episode, video_mode="skip")
        .filter(content=entity, is_static=False, components="Scalars:scalars")
        .flat_map(_one_vector_per_row)
    )
    stream = in_time_order(stream, "frame_index", plan, plan.root)
    return SourceStream(stream, entity, VECTOR_COMPONENT, len(plan.names))
