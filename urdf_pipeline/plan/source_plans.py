"""The sources of a plan: where each one's values are, what they are named, and the remote objects they come from."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal, Protocol

from ..errors import Where

OnViolation = Literal["error", "clamp", "ignore"]
NanPolicy = Literal["error", "drop_row", "hold_last"]
TimelineKind = Literal["sequence", "timestamp", "duration"]


@dataclass(frozen=True)
class IndexPlan:
    """The column a source's rows are ordered by, and the Rerun timeline it becomes (sequence, timestamp or duration)."""

    column: str
    kind: TimelineKind
    unit: str | None  # "s" | "ms" | "us" | "ns" for time kinds


@dataclass(frozen=True)
class RemoteObject:
    """A remote file a source reads (`s3://BUCKET/KEY`, a Hub dataset's file) as compiled: `version` (the ETag; the Hub
    commit) is what its bytes are, so a run downloads exactly those or refuses. A plan holding one has as `path` where
    this machine's download cache keeps it; a Ray worker fetches into its own."""

    url: str
    version: str
    size: int  # bytes; 0 for a Hub data file (its commit pins it; its size is known once downloaded)


@dataclass(frozen=True)
class ParquetSourcePlan:
    """A parquet file: one list<number> `column` per row, or (column None) a wide table, one column per name."""

    name: str
    path: Path
    column: str | None  # None: a wide table, one numeric column per name
    index: IndexPlan
    names: tuple[str, ...]
    where: Where
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteObject | None = None  # `parquet: s3://...`: the object `path` is downloaded from (see `remote_of`)


@dataclass(frozen=True)
class RemoteDataset:
    """A LeRobot dataset on S3 or the Hub as compiled, each file pinned: `meta` (read at compile), `data` (run only)."""

    url: str  # the dataset's folder: s3://BUCKET/PREFIX/DATASET, or hf://datasets/ORG/NAME@COMMIT (the resolved sha)
    meta: tuple[RemoteObject, ...]
    data: tuple[RemoteObject, ...] = ()

    def relative(self, remote: RemoteObject) -> str:
        """Where `remote` lies inside the dataset's folder (`meta/info.json`)."""
        return remote.url[len(self.url) + 1 :]


@dataclass(frozen=True)
class LeRobotSourcePlan:
    """One feature (a joint vector) of a LeRobot dataset: one episode, or (per_segment) each segment's own."""

    name: str
    root: Path  # a remote dataset: the folder this machine keeps its files in (the Hub's snapshot, the download cache)
    feature: str
    episode: int
    names: tuple[str, ...]
    where: Where
    per_segment: bool = False  # no `episode` in the config: each segment reads its own episode
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteDataset | None = None  # `lerobot: s3://...` or `hf://...`: `run` reads a local view of its files
    fps: float | None = None  # meta/info.json's frames per second (checked: above 0, bounded); None when it says none
    timed: bool = False  # meta/info.json declares the `timestamp` feature: rows get the `time` timeline too


@dataclass(frozen=True)
class McapSourcePlan:
    """ROS 2 sensor_msgs/msg/JointState messages of one topic; every message names its values (mapped by name per row)."""

    name: str
    path: Path
    topic: str
    timeline: str  # the one timeline kept: "ros2_timestamp" (header stamp), "message_log_time" or "message_publish_time"
    names: tuple[str, ...]  # the names the messages may carry, from the config or the first message
    where: Where
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteObject | None = None  # `mcap: s3://...`: the object `path` is downloaded from


@dataclass(frozen=True)
class Hdf5SourcePlan:
    """A 2-D HDF5 dataset [rows, values] (e.g. ALOHA's /observations/qpos)."""

    name: str
    path: Path
    dataset: str  # absolute path inside the file, "/observations/qpos"
    index: IndexPlan | None  # a 1-D dataset path as column; None: Rerun's generated `row_index` sequence
    rows: int
    names: tuple[str, ...]
    where: Where
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteObject | None = None  # `hdf5: s3://...`: the object `path` is downloaded from


@dataclass(frozen=True)
class RrdSourcePlan:
    """Joint values already in a Rerun recording: one component of one entity."""

    name: str
    path: Path
    entity: str
    component: str
    named_rows: bool  # each row carries its own SeriesLines:names: values are mapped by name per row
    names: tuple[str, ...]
    where: Where
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteObject | None = None  # `rrd: s3://...`: the object `path` is downloaded from


@dataclass(frozen=True)
class CsvSourcePlan:
    """A CSV file with a header, read as a wide table: one numeric column per name and an index column."""

    name: str
    path: Path
    index: IndexPlan
    names: tuple[str, ...]  # the columns holding the values: the config's `names`, else every column but the index
    where: Where
    duplicates: str = "error"  # two rows at one index value: "error" or "keep_last" (the later row wins)
    remote: RemoteObject | None = None  # `csv: s3://...`: the object `path` is downloaded from


class NamedSource(Protocol):
    """What reading a source's rows needs of it (`raw_matrix`, a robot's `JointValueMapper`, a temporal edge's values):
    a `SourcePlan`, or the source of a live view."""

    @property
    def name(self) -> str: ...
    @property
    def names(self) -> tuple[str, ...]: ...
    @property
    def where(self) -> Where: ...


SourcePlan = ParquetSourcePlan | LeRobotSourcePlan | McapSourcePlan | Hdf5SourcePlan | RrdSourcePlan | CsvSourcePlan
FileSourcePlan = ParquetSourcePlan | McapSourcePlan | Hdf5SourcePlan | RrdSourcePlan | CsvSourcePlan  # one file at `path`


def remote_of(source: SourcePlan) -> RemoteObject | None:
    """The remote file a file source reads (`KIND: s3://BUCKET/KEY`); None for a local file or a LeRobot dataset."""
    remote = getattr(source, "remote", None)
    return remote if isinstance(remote, RemoteObject) else None


def with_local_path(source: FileSourcePlan, path: Path) -> FileSourcePlan:
    """The same source read from `path`: a remote file's plan once `run` has downloaded it there."""
    return replace(source, path=path)
