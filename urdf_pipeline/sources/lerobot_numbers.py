"""Every number a LeRobot dataset's metadata declares, checked where it is read, before anything computes with it
(the rules: security.md#templates-and-numbers): `chunks_size: 0` makes Rerun's v2 reader divide by zero, and
`total_episodes: 1e30` would make a loop of 10^30 episodes. The episodes' table is bounded before it is built
(EPISODES_JSONL_BYTES, MAX_EPISODE_ROWS: a parquet footer of 800 KB can declare 30 million rows of zeros) and checked
over whole columns, naming the file, the column and the first row at fault.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pyarrow as pa

from ..errors import UserError, Where, shown

INT64_MAX = 2**63 - 1  # an index a timeline or a parquet column holds
MAX_FPS = 1_000_000  # frames per second: far beyond any camera or control loop, far below where a float stops counting
MAX_LISTED_EPISODES = 1_000_000  # episodes taken from total_episodes alone, when the dataset has no episodes table
EPISODES_JSONL_BYTES = 32 * 2**20  # v2's episodes.jsonl: ~100 bytes an episode, so some 300,000 episodes
MAX_EPISODE_ROWS = 1_000_000  # rows of the episodes' table, all files together: 10 times the largest public datasets
# info.json's counts and the least each may be; Rerun's reader reads each as an unsigned integer
INFO_COUNTS = {
    "total_episodes": 0,
    "total_frames": 0,
    "total_tasks": 0,
    "total_videos": 0,
    "total_chunks": 0,
    "chunks_size": 1,  # episodes per chunk folder: v2 divides episode indices by it
    "data_files_size_in_mb": 0,
    "video_files_size_in_mb": 0,
}
# the episodes' table: whole-number columns (and the suffix of a per-video column, videos/KEY/chunk_index)
INDEX_COLUMNS = ("episode_index", "length", "data/chunk_index", "data/file_index", "dataset_from_index", "dataset_to_index")
INDEX_SUFFIXES = ("/chunk_index", "/file_index")
TIME_SUFFIXES = ("/from_timestamp", "/to_timestamp")  # seconds into a video file
RANGES = (("dataset_from_index", "dataset_to_index"),)  # (first, end) of the rows of an episode, end not before first


class MetadataError(ValueError):
    """A number the episodes' table declares that nothing may use; `lerobot_meta.metadata` makes it a user error."""


def _value(value: object) -> str:
    return shown(json.dumps(value) if not isinstance(value, str) else repr(value), 60)


def count(value: object, key: str, named: str, where: Where | None, least: int = 0) -> int:
    """`value` as a whole number from `least` to INT64_MAX (not a bool, a float or a string), or a user error."""
    if isinstance(value, bool) or not isinstance(value, int) or not least <= value <= INT64_MAX:
        raise UserError(
            f"{key} in {named} is {_value(value)}: it must be a whole number from {least} to {INT64_MAX:,}; fix the dataset's metadata",
            where,
        )
    return value


def check_info_numbers(info: dict[str, Any], named: str, where: Where | None) -> None:
    """info.json's counts, fps and features' shapes, each when present."""
    for key, least in INFO_COUNTS.items():
        if key in info:
            count(info[key], key, named, where, least)
    if "fps" in info:
        fps = info["fps"]
        if isinstance(fps, bool) or not isinstance(fps, int | float) or not (math.isfinite(fps) and 0 < fps <= MAX_FPS):
            raise UserError(f"fps in {named} is {_value(fps)}: it must be a number above 0 and at most {MAX_FPS:,}", where)
    features = info.get("features")
    for name, feature in features.items() if isinstance(features, dict) else ():  # one iteration per feature
        shape = feature.get("shape") if isinstance(feature, dict) else None
        if shape is None:
            continue
        if not isinstance(shape, list):
            raise UserError(f"features.{shown(name)}.shape in {named} is {_value(shape)}: it must be a list of sizes", where)
        for size in shape:  # one iteration per dimension
            count(size, f"features.{shown(name)}.shape", named, where)


def listed_episodes(info: dict[str, Any], named: str, where: Where | None) -> range:
    """The episodes of a dataset without an episodes table: 0..total_episodes, bounded (no table says otherwise)."""
    total = count(info.get("total_episodes", 0), "total_episodes", named, where)
    if total > MAX_LISTED_EPISODES:
        raise UserError(
            f"total_episodes in {named} is {total:,} but the dataset has no episodes table (meta/episodes.jsonl or "
            f"meta/episodes/): at most {MAX_LISTED_EPISODES:,} episodes are taken from total_episodes alone",
            where,
        )
    return range(total)


def check_v2_listing(info: dict[str, Any], last: int | None, named: str, where: Where | None) -> None:
    """v2: Rerun's reader reads episode E only below total_episodes and in a chunk (E // chunks_size) below
    total_chunks; an episode the table lists beyond them would fail its segment inside the reader."""
    total, chunks, size = info.get("total_episodes"), info.get("total_chunks"), info.get("chunks_size", 1000)
    if last is None:
        return
    if total is not None and last >= total:
        raise UserError(f"meta/episodes lists episode {last:,} but total_episodes in {named} is {total:,}: the two must agree", where)
    if chunks is not None and last // size >= chunks:
        raise UserError(
            f"episode {last:,} is in chunk {last // size:,} ({size:,} episodes a chunk) but total_chunks in {named} is {chunks:,}: "
            "the two must agree",
            where,
        )


def jsonl_lines(path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of each non-blank line of episodes.jsonl, read within EPISODES_JSONL_BYTES."""
    read = 0
    with path.open("rb") as stream:
        for number, raw in enumerate(stream, 1):  # one iteration per line, each at most the bound
            read += len(raw)
            if read > EPISODES_JSONL_BYTES or number > MAX_EPISODE_ROWS:
                raise MetadataError(
                    f"meta/episodes.jsonl is larger than {EPISODES_JSONL_BYTES // 2**20} MB or {MAX_EPISODE_ROWS:,} lines, "
                    "the most read as metadata"
                )
            text = raw.decode("utf-8").strip()
            if text:
                yield number, text


def jsonl_episode(number: int, text: str) -> tuple[int, dict[str, Any]]:
    """A line of episodes.jsonl: its episode_index, checked, and the record."""
    record = json.loads(text)
    if not isinstance(record, dict):
        raise MetadataError(f"meta/episodes.jsonl line {number} is no JSON object")
    index = record.get("episode_index")
    if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index <= INT64_MAX:
        raise MetadataError(f"episode_index in meta/episodes.jsonl line {number} is {_value(index)}: it must be a whole number from 0")
    length = record.get("length")
    if length is not None and (isinstance(length, bool) or not isinstance(length, int) or not 0 <= length <= INT64_MAX):
        raise MetadataError(f"length in meta/episodes.jsonl line {number} is {_value(length)}: it must be a whole number from 0")
    return index, record


def jsonl_table(path: Path) -> pa.Table:
    """v2's episodes.jsonl as episode_index and length columns, every line checked."""
    indices: list[int] = []
    lengths: list[int | None] = []
    for number, text in jsonl_lines(path):  # one iteration per episode
        index, record = jsonl_episode(number, text)
        indices.append(index)
        lengths.append(record.get("length"))
    return pa.table({"episode_index": pa.array(indices, pa.int64()), "length": pa.array(lengths, pa.int64())})


def wanted_columns(names: list[str]) -> list[str]:
    """The columns of a v3 episodes file that are read, each checked: indices, row ranges, video time ranges."""
    return [name for name in names if name in INDEX_COLUMNS or name.endswith(INDEX_SUFFIXES + TIME_SUFFIXES)]


def episode_file_columns(metadata: Any, rows_before: int, relative: str) -> list[str]:
    """The columns of a v3 episodes file to read, from its footer (`pq.read_metadata`), before any is read: the table's
    rows with this file's stay within MAX_EPISODE_ROWS, and every column read holds plain numbers."""
    if rows_before + metadata.num_rows > MAX_EPISODE_ROWS:
        raise MetadataError(
            f"{relative} declares {metadata.num_rows:,} rows, which bring the episodes' table beyond {MAX_EPISODE_ROWS:,} rows"
        )
    schema = metadata.schema.to_arrow_schema()
    columns = wanted_columns(schema.names)
    if "episode_index" not in columns:
        raise MetadataError(f"{relative} has no episode_index column")
    for name in columns:  # one iteration per column to read
        kind = schema.field(name).type
        if not (pa.types.is_integer(kind) or (name.endswith(TIME_SUFFIXES) and pa.types.is_floating(kind))):
            raise MetadataError(f"{name} in {relative} holds {kind}, not {'seconds' if name.endswith(TIME_SUFFIXES) else 'whole numbers'}")
    return columns


def check_episode_columns(table: pa.Table, relative: str) -> None:
    """A v3 episodes file's columns, over whole columns: indices whole numbers from 0 (episode_index never missing),
    video times finite and from 0, each range's end not before its start."""
    import pyarrow.compute as pc

    for name in table.column_names:  # one iteration per column read
        column = table.column(name)
        if name.endswith(TIME_SUFFIXES):
            if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)):
                raise MetadataError(f"{name} in {relative} holds {column.type}, not seconds")
            bad = pc.invert(pc.and_(pc.is_finite(pc.cast(column, pa.float64())), pc.greater_equal(column, 0)))
            _refuse_rows(bad, column, name, relative, "a finite number of seconds from 0")
            continue
        if not pa.types.is_integer(column.type):
            raise MetadataError(f"{name} in {relative} holds {column.type}, not whole numbers")
        if pa.types.is_signed_integer(column.type):
            bad = pc.less(column, 0)
        else:  # unsigned: beyond what an int64 (a timeline, pyarrow's filters) holds
            bad = pc.greater(pc.cast(column, pa.uint64()), pa.scalar(INT64_MAX, pa.uint64()))
        if name == "episode_index":
            bad = pc.or_kleene(bad, pc.is_null(column))
        _refuse_rows(bad, column, name, relative, f"a whole number from 0 to {INT64_MAX:,}")
    pairs = [*RANGES, *((n, n[: -len("/from_timestamp")] + "/to_timestamp") for n in table.column_names if n.endswith(TIME_SUFFIXES[0]))]
    for first, end in pairs:  # one iteration per range the file holds
        if first in table.column_names and end in table.column_names:
            bad = pc.less(table.column(end), table.column(first))
            _refuse_rows(bad, table.column(end), end, relative, f"not before {first}")


def _refuse_rows(bad: Any, column: Any, name: str, relative: str, rule: str) -> None:
    import pyarrow.compute as pc

    bad = pc.fill_null(bad, False)
    if pc.any(bad).as_py():
        row = pc.index(bad, True).as_py()
        raise MetadataError(f"{name} in {relative} is {_value(column[row].as_py())} at row {row}: it must be {rule}")
