"""The frozen, typed plan: everything decided before any joint value is read.

Two levels: `Plan` is the whole config (what `compile_config` and `urdf_pipeline.load` return, what `plan`, `diff`
and `run` read); `RecordingPlan` is one recording of it (a segment, or the split layout's model: what `execute`
writes), made by `Plan.for_segment` / `for_model`. Only the latter has sources and an output."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Literal

from .errors import UserError, Where, did_you_mean, listing

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


SourcePlan = ParquetSourcePlan | LeRobotSourcePlan | McapSourcePlan | Hdf5SourcePlan | RrdSourcePlan | CsvSourcePlan
FileSourcePlan = ParquetSourcePlan | McapSourcePlan | Hdf5SourcePlan | RrdSourcePlan | CsvSourcePlan  # one file at `path`


def remote_of(source: SourcePlan) -> RemoteObject | None:
    """The remote file a file source reads (`KIND: s3://BUCKET/KEY`); None for a local file or a LeRobot dataset."""
    remote = getattr(source, "remote", None)
    return remote if isinstance(remote, RemoteObject) else None


def with_local_path(source: FileSourcePlan, path: Path) -> FileSourcePlan:
    """The same source read from `path`: a remote file's plan once `run` has downloaded it there."""
    return replace(source, path=path)


@dataclass(frozen=True)
class JointChannel:
    """One source value driving one URDF joint. Corrections, in this order: wrap (source units) -> linear map ->
    limits. The linear map is (value * unit factor * scale) * sign + offset, or, with source_range, the source range
    mapped linearly onto the joint's range; both reduce to urdf = value * gain + bias."""

    joint: str
    source_name: str
    source_index: int
    source_unit: str
    factor: float
    sign: float
    offset: float
    lower: float | None  # URDF units; None when the joint has no limits
    upper: float | None
    slack: float  # URDF units: limits.slack for this joint's kind (compile/units.py)
    where: Where
    scale: float = 1.0
    wrap: float | None = None  # period in source units, e.g. 360 for a servo reporting 0..360 deg
    wrap_center: float = 0.0  # wrapped values land in [center - wrap/2, center + wrap/2), source units
    source_range: tuple[float, float] | None = None
    target_range: tuple[float, float] | None = None  # URDF units; the joint's limits unless joint_range is given
    slack_written: tuple[float, str] = (0.0, "")  # limits.slack as the config wrote it for this joint's kind: (2.0, "deg")

    @property
    def gain(self) -> float:
        if self.source_range is not None and self.target_range is not None:
            (s0, s1), (t0, t1) = self.source_range, self.target_range
            return (t1 - t0) / (s1 - s0)
        return self.factor * self.scale * self.sign

    @property
    def bias(self) -> float:
        if self.source_range is not None and self.target_range is not None:
            return self.target_range[0] - self.source_range[0] * self.gain
        return self.offset

    def to_source_unit(self, urdf_value: float) -> float:
        return (urdf_value - self.bias) / self.gain

    @property
    def limits_in_source_unit(self) -> tuple[float, float] | None:
        """The one meaning of "limits in source units" (plan, check, run, diff): the source values that the linear map
        (unit, scale, sign, offset, or source_range onto target_range) sends onto the URDF limits, low <= high. A raw
        value v is within the limits exactly when low <= v <= high (after wrap). None when the joint has no limits."""
        if self.lower is None or self.upper is None:
            return None
        low, high = sorted((self.to_source_unit(self.lower), self.to_source_unit(self.upper)))
        return (low, high)

    @property
    def slack_in_source_unit(self) -> float | None:
        """The slack as a span of raw source values (what check and the limits report compare raw values with)."""
        return self.slack / abs(self.gain) if self.gain else None

    @property
    def slack_text(self) -> str:
        """The slack for people: "2 deg", "0" (units.number_text's form; the unit of a zero slack says nothing)."""
        value, unit = self.slack_written
        if not unit:  # a channel built by hand, not compiled: its slack in URDF units
            value, unit = self.slack, "rad" if self.source_unit in ("rad", "deg") else "m"
        return f"{value:g} {unit}" if value else "0"


@dataclass(frozen=True)
class MimicJoint:
    """A <mimic> joint: value = driver * multiplier + offset, computed by the pipeline (Rerun's FK does not)."""

    joint: str
    driver: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class HeldJoint:
    """A joint no source drives, held at one value (`hold:`), so the FK has a value for every joint."""

    joint: str
    value: float  # URDF units


@dataclass(frozen=True)
class RobotPlan:
    """One robot of the config: its URDF text and where it hangs in the scene, and how one source's values drive its
    joints (channels, holds, mimics) and what is done with values out of limits or NaN."""

    key: str
    urdf_path: Path  # the URDF (or xacro) file the text came from
    urdf_text: str  # URDF text with every resolved mesh URI replaced by an absolute path
    urdf_origin: str  # "file robots/panda.urdf", "xacro ... args", "robot_descriptions NAME @ COMMIT: path"
    urdf_sha256: str  # of the URDF text before mesh paths were made absolute: equal across machines
    robot_name: str
    root_link: str
    links: tuple[str, ...]
    joint_links: tuple[tuple[str, str, str], ...]  # (joint, parent link, child link), unprefixed
    entity_path_prefix: str  # "/arm"
    frame_prefix: str
    keep_collisions: bool
    source: str | None  # None for a scene URDF without moving joints
    channels: tuple[JointChannel, ...]
    holds: tuple[HeldJoint, ...]
    mimics: tuple[MimicJoint, ...]  # ordered so a driver is computed before its mimic
    on_violation: OnViolation
    where: Where
    nan_policy: NanPolicy = "error"

    @property
    def fk_entity(self) -> str:
        return f"{self.entity_path_prefix}/joint_transforms"

    @property
    def static_transform_entity(self) -> str:
        return f"{self.entity_path_prefix}/tf_static"

    @property
    def collision_filter(self) -> str:
        return f"{self.entity_path_prefix}/{self.robot_name}/collision_geometries/**"

    @property
    def slack_text(self) -> str:
        """limits.slack in the config's own form: "0", "2 deg", "{angle: 2 deg, length: 2 mm}" (the kinds its channels have)."""
        by_kind: dict[bool, str] = {}
        for channel in self.channels:
            by_kind.setdefault(channel.slack_written[1] in ("rad", "deg"), channel.slack_text)
        given = {angular: text for angular, text in by_kind.items() if text != "0"}
        if len(given) == 2:
            return f"{{angle: {given[True]}, length: {given[False]}}}"
        return next(iter(given.values()), "0")


EdgeKind = Literal["static", "fixed_chain", "assume_identity"]


@dataclass(frozen=True)
class FixedChain:
    """Where a fixed_chain edge's transform comes from: the URDF's fixed joints from `start` down to `end`."""

    robot: str  # key of the robot whose URDF holds both frames
    start: str  # prefixed frame names, as written in the config
    end: str
    joints: tuple[str, ...]  # the fixed joints composed, top down


@dataclass(frozen=True)
class EdgePlan:
    """A static edge logged on /calibration: a calibration, a fixed chain copied from a URDF, or an assumed identity."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]
    where: Where
    kind: EdgeKind = "static"
    label: str = ""  # "edges[2]", "calib/extrinsics.yaml[0]", "frames.assume_identity[0]"
    fixed_chain: FixedChain | None = None


@dataclass(frozen=True)
class TemporalEdgePlan:
    """An edge read from a source row by row: named values give the translation and the quaternion."""

    parent: str
    child: str
    source: str
    translation_names: tuple[str, str, str]
    quaternion_names: tuple[str, str, str, str]  # x, y, z, w
    translation_indices: tuple[int, int, int]  # positions in the source's value vector
    quaternion_indices: tuple[int, int, int, int]
    entity: str  # "/calibration/temporal/<child>"
    label: str
    where: Where


Layout = Literal["single", "split"]


@dataclass(frozen=True)
class OutputPlan:
    """Where one recording goes: a single-layout segment, a split layout's layer, or its model."""

    path: Path
    application_id: str
    recording_id: str
    where: Where
    joint_series: bool = False  # output.joint_series: the driven joints' values also as time series


@dataclass(frozen=True)
class Segment:
    """One recording of a run: a LeRobot episode, a globbed input file, or the run's only input."""

    id: str  # the recording_id
    episode: int | None
    stem: str | None
    sources: tuple[SourcePlan, ...]  # this segment's own inputs (episode, file)
    output: Path
    frames: int | None  # rows expected, when the dataset's metadata says (LeRobot episode lengths)
    inputs: tuple[Path, ...]  # the files whose bytes this segment reads: part of its content hash


@dataclass(frozen=True)
class RemoteOutputs:
    """Outputs in one S3 bucket: each output path is under `staging` (this machine's mirror of it) until uploaded."""

    staging: Path
    url_root: str  # s3://BUCKET/

    def url_of(self, path: Path) -> str:
        return self.url_root + path.relative_to(self.staging).as_posix()


@dataclass(frozen=True)
class DatasetPlan:
    """The segments of a run and how they are written."""

    layout: Layout
    segments: tuple[Segment, ...]
    model: Path | None  # layout split: the static model asset
    manifest: Path
    where: Where  # output.segment, for errors about segments
    joint_series: bool = False  # output.joint_series: each segment also holds its driven joints' values as time series
    remote: RemoteOutputs | None = None  # outputs in S3: the staged paths above and their URLs


@dataclass(frozen=True)
class ScenePlan:
    """What every recording of a config shares, whatever it reads: the robots, the edges between their frames, the
    root frame. The base of the whole config's `Plan` and of one recording's `RecordingPlan`, which are otherwise
    apart so that no code reads one segment's sources or output from the dataset's plan."""

    config_path: Path
    robots: tuple[RobotPlan, ...]
    edges: tuple[EdgePlan, ...]
    root_frame: str
    temporal_edges: tuple[TemporalEdgePlan, ...]

    def robots_for(self, source: str) -> tuple[RobotPlan, ...]:
        return tuple(r for r in self.robots if r.source == source)


@dataclass(frozen=True)
class Plan(ScenePlan):
    """The whole config, compiled and frozen: the seam between checking and doing. Its segments each hold their own
    sources and output path; one recording's plan is `for_segment(segment)` (or `for_model()`): what a run executes."""

    dataset: DatasetPlan
    application_id: str  # every recording's (output.application_id)
    output_where: Where  # the config's `output`, for errors about what a run writes

    @property
    def segments(self) -> tuple[Segment, ...]:
        return self.dataset.segments

    def segment_named(self, wanted: str | None, option: str, first_by_default: bool) -> Segment:
        """The segment whose id is `wanted`; without one, the first (`first_by_default`) or the only one. `option` is
        how the user names it (`--segment`, `segment=`), for the error that lists the ids."""
        ids = [segment.id for segment in self.segments]
        if wanted is None:
            if first_by_default or len(ids) == 1:
                return self.segments[0]
            raise UserError(f"{len(ids)} segments; say which with {option} one of: {listing(ids)}", self.dataset.where)
        for segment in self.segments:
            if segment.id == wanted:
                return segment
        raise UserError(f"{option} {wanted}: no such segment (segments: {listing(ids)}){did_you_mean(wanted, ids)}", self.dataset.where)

    def for_segment(self, segment: Segment) -> RecordingPlan:
        """The plan of one segment's recording: its own sources and output."""
        return self._recording(segment.sources, segment.output, segment.id)

    def for_model(self) -> RecordingPlan:
        """The plan of the split layout's model asset: no source is read."""
        assert self.dataset.model is not None, "for_model needs the split layout"
        return self._recording((), self.dataset.model, MODEL_RECORDING_ID)

    def _recording(self, sources: tuple[SourcePlan, ...], path: Path, recording_id: str) -> RecordingPlan:
        series = self.dataset.joint_series and bool(sources)  # the split layout's model holds no values
        output = OutputPlan(path, self.application_id, recording_id, self.output_where, series)
        return RecordingPlan(self.config_path, self.robots, self.edges, self.root_frame, self.temporal_edges, sources, output)


@dataclass(frozen=True)
class RecordingPlan(ScenePlan):
    """The plan of ONE recording (a segment, or the split layout's model), made by `Plan.for_segment`/`for_model`:
    what execute writes and the API logs. It knows nothing of the other segments."""

    sources: tuple[SourcePlan, ...]  # this recording's own inputs (its episode, its file); none for the model
    output: OutputPlan

    def source(self, name: str) -> SourcePlan:
        return next(s for s in self.sources if s.name == name)


MODEL_RECORDING_ID = "urdf_model"  # the split layout's model asset is a recording of its own, not a segment
