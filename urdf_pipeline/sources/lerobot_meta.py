"""A LeRobot dataset's metadata (v2.x or v3), read from a folder holding its `meta/`: the dataset on disk, or a local
view of a remote dataset's metadata files (lerobot_remote.py). Everything `compile` learns of a dataset comes from
here, checked the same way wherever the dataset lives; `shown` is how messages name the dataset (its folder, or its
URL)."""

from __future__ import annotations

import functools
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import pyarrow as pa

from ..config import MAX_BYTES, Document, Placeholder, Template, checked_template
from ..confine import file_state
from ..errors import UserError, Where, quoted
from ..plan import LeRobotSourcePlan
from .lerobot_numbers import check_episode_columns, check_info_numbers, check_v2_listing, episode_file_columns, jsonl_table, listed_episodes
from .ordering import with_duplicates

T = TypeVar("T")
# What a hostile or broken dataset's metadata raises while it is read: each becomes one user error at the source.
METADATA_ERRORS = (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError, RecursionError, pa.ArrowException)
V3_COLUMNS = ("data/chunk_index", "data/file_index")  # v3: which data file holds an episode's rows


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


def read_info(root: Path, where: Where | None = None, shown: str | None = None) -> dict[str, Any]:
    """meta/info.json as a mapping, its numbers checked (lerobot_numbers.py); a user error when it is missing, no
    regular file (a FIFO would block), larger than MAX_BYTES or not a JSON object."""
    path = root / "meta" / "info.json"
    named = f"{shown}/meta/info.json" if shown else str(path)
    if file_state(path, "LeRobot metadata file", where) != "file":
        raise UserError(f"{shown or root} is not a LeRobot dataset: {named} is missing", where)
    try:
        with path.open("rb") as stream:
            raw = stream.read(MAX_BYTES + 1)
        if len(raw) > MAX_BYTES:
            raise ValueError(f"it is larger than {MAX_BYTES // 2**20} MB, the most read as metadata")
        info = json.loads(raw.decode("utf-8"))
    except (OSError, ValueError, RecursionError) as exc:
        raise UserError(f"cannot read {named}: {'nested too deeply' if isinstance(exc, RecursionError) else exc}", where) from None
    if not isinstance(info, dict):
        raise UserError(f"{named} holds {type(info).__name__}, not a JSON object", where)
    check_info_numbers(info, named, where)
    return info


# The placeholders of info.json's path templates, written exactly as LeRobot writes them: Rerun's reader replaces
# these texts and nothing else, so any other spelling would make the file we check differ from the file it reads.
V2_PLACEHOLDERS = {"episode_chunk": Placeholder(int, "03d"), "episode_index": Placeholder(int, "06d")}
V3_PLACEHOLDERS = {"chunk_index": Placeholder(int, "03d"), "file_index": Placeholder(int, "03d")}
VIDEO_KEY = {"video_key": Placeholder(str, "")}


def is_v3(info: dict[str, Any]) -> bool:
    return str(info.get("codebase_version", "")).startswith("v3")


def data_path_template(info: dict[str, Any], info_path: Path | str, where: Where | None) -> Template:
    """info.json's data_path (and video_path, which the reader also takes): relative, inside the dataset (no `..`),
    with only the placeholders of the dataset's layout as LeRobot writes them (config/templates.py refuses the rest:
    `{episode_index.__class__}`, `{episode_index:999999999d}`...)."""
    placeholders = V3_PLACEHOLDERS if is_v3(info) else V2_PLACEHOLDERS
    video = info.get("video_path")
    if video is not None:
        _path_template(video, "video_path", {**placeholders, **VIDEO_KEY}, info_path, where)
    return _path_template(info.get("data_path"), "data_path", placeholders, info_path, where)


def _path_template(text: object, key: str, placeholders: dict[str, Placeholder], info_path: Path | str, where: Where | None) -> Template:
    if not isinstance(text, str):
        kind = "missing" if text is None else f"a JSON {type(text).__name__}"
        raise UserError(f"{key} in {info_path} is {kind}, not a path template such as {_LEROBOT_DEFAULT}", where)
    if Path(text).is_absolute() or ".." in Path(text).parts:
        raise UserError(f"{key} {quoted(text)} in {info_path} must stay inside the dataset (a relative path without '..')", where)
    return checked_template(text, placeholders, f"{key} in {info_path}:", where)


_LEROBOT_DEFAULT = "'data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet'"


def metadata(shown: str, where: Where | None, read: Callable[[], T]) -> T:
    """`read()` of the dataset's metadata; whatever a broken file raises is a user error at the source."""
    try:
        return read()
    except METADATA_ERRORS as exc:
        raise UserError(f"cannot read the episode metadata of LeRobot dataset {shown}: {exc}", where) from None


def checked_plan(name: str, spec: dict[str, Any], document: Document, root: Path, shown: str) -> LeRobotSourcePlan:
    """The source's plan from meta/info.json alone (the codebase version, the feature and its names, data_path, fps and
    whether rows carry a `timestamp`), the episode pinned by `episode:` checked against total_episodes; its data is
    checked by the caller."""
    here = ("sources", name)
    where = document.where(*here, "lerobot")
    info_path = f"{shown}/meta/info.json"
    info = read_info(root, where, shown)
    version = str(info.get("codebase_version", ""))
    if not (version.startswith("v2") or version.startswith("v3")):
        raise UserError(f"LeRobot codebase_version '{version}' is not supported (v2.x or v3 only)", where)
    feature_key = spec.get("feature", "observation.state")
    features = info.get("features", {})
    if not isinstance(features, dict) or not all(isinstance(f, dict) for f in features.values()):
        raise UserError(f"'features' in {info_path} is not a mapping of feature names to mappings", where)
    data_path_template(info, info_path, where)
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
    fps, timed = (float(info["fps"]) if "fps" in info else None), "timestamp" in features  # fps: checked by read_info
    if "episode" not in spec:  # one segment per episode; segments.py picks them and fills in `episode`
        return with_duplicates(
            LeRobotSourcePlan(name, root, feature_key, -1, names, document.where(*here), per_segment=True, fps=fps, timed=timed), spec
        )
    episode = int(spec["episode"])
    total = info.get("total_episodes")
    if isinstance(total, int) and episode >= total:
        raise UserError(
            f"episode {episode} does not exist: the dataset has {total} episodes (0..{total - 1})", document.where(*here, "episode")
        )
    return with_duplicates(LeRobotSourcePlan(name, root, feature_key, episode, names, document.where(*here), fps=fps, timed=timed), spec)


# A metadata file as last seen: (path, size, mtime_ns). What is read of it is kept per process while it is unchanged:
# every segment of a run asks for it, and reading it each time made a run quadratic in the episodes.
FileStamp = tuple[Path, int, int]


def stamped(path: Path) -> FileStamp:
    status = os.stat(path)
    return (path, status.st_size, status.st_mtime_ns)


def episode_files(root: Path) -> tuple[FileStamp, ...]:
    """The dataset's per-episode metadata files: v2's meta/episodes.jsonl or v3's meta/episodes/**/*.parquet."""
    jsonl = root / "meta" / "episodes.jsonl"
    if file_state(jsonl, "LeRobot metadata file", None) == "file":
        return (stamped(jsonl),)
    files = sorted((root / "meta" / "episodes").glob("**/*.parquet"))
    return tuple(stamped(f) for f in files if file_state(f, "LeRobot metadata file", None) == "file")


def episode_table(root: Path) -> pa.Table | None:
    """The dataset's per-episode metadata: v2's meta/episodes.jsonl or v3's meta/episodes/**/*.parquet (None without
    any); kept while the files are unchanged."""
    files = episode_files(root)
    return _read_episode_table(files) if files else None


@functools.lru_cache(maxsize=4)
def _read_episode_table(files: tuple[FileStamp, ...]) -> pa.Table:
    """The episodes' table, every number in it checked (lerobot_numbers.py) as it is read."""
    import pyarrow.parquet as pq

    if files[0][0].name == "episodes.jsonl":
        return jsonl_table(files[0][0])
    tables: list[pa.Table] = []
    for file, _, _ in files:  # one iteration per episodes file (a v3 dataset has one per 1000 episodes or so)
        relative = "/".join(file.parts[len(file.parts) - 1 - file.parts[::-1].index("meta") :])
        columns = episode_file_columns(pq.read_metadata(file), sum(t.num_rows for t in tables), relative)
        tables.append(pq.read_table(file, columns=columns))
        check_episode_columns(tables[-1], relative)
    return pa.concat_tables(tables, promote_options="default")


def episode_lengths(root: Path, table: pa.Table | None, where: Where | None, shown: str) -> dict[int, int | None]:
    """Episode index -> its length in frames (None when the metadata does not say)."""
    info, named = read_info(root, where, shown), f"{shown}/meta/info.json"
    if table is None:
        return dict.fromkeys(listed_episodes(info, named, where))
    lengths = table.column("length").to_pylist() if "length" in table.column_names else [None] * table.num_rows
    found = dict(zip(table.column("episode_index").to_pylist(), lengths, strict=True))
    if not is_v3(info):
        check_v2_listing(info, max(found, default=None), named, where)
    return found


def v2_data_file(info: dict[str, Any], template: Template, episode: int) -> str | None:
    """v2: the one data file of `episode` (data_path holds {episode_index}), relative to the dataset; None for v3."""
    if "episode_index" not in template.fields:
        return None
    return template.format(episode_chunk=episode // int(info.get("chunks_size", 1000)), episode_index=episode)


def v3_data_files(table: pa.Table | None, template: Template, episode: int | None = None) -> dict[int, tuple[str, ...]] | None:
    """v3: episode -> the data file(s) its rows are in (episodes share files), relative to the dataset, from the
    episode table's data/chunk_index and data/file_index (only `episode`'s, when given); None when the table does
    not say."""
    if table is None or not set(V3_COLUMNS) <= set(table.column_names):
        return None
    if episode is not None:
        import pyarrow.compute as pc  # here: 50 ms of every command otherwise, and only v3 datasets need it

        table = table.filter(pc.equal(table.column("episode_index"), episode))
    found: dict[int, set[str]] = {}
    columns = zip(*(table.column(c).to_pylist() for c in ("episode_index", *V3_COLUMNS)), strict=True)
    for index, chunk, file in columns:  # one iteration per episode row of the metadata
        found.setdefault(int(index), set()).add(template.format(chunk_index=chunk, file_index=file))
    return {index: tuple(sorted(files)) for index, files in found.items()}
