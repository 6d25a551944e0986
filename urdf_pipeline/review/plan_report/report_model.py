"""The plan report as one typed model: what `plan` shows, whatever the format, and its one plain-data form.

`report.build_report` makes it from a Plan; `as_data` turns it into nested dicts, lists and scalars (what `plan
--format json` prints and `diff` compares), field by field from the dataclasses below: a class's `DATA` says where a field's
data name differs, where a field is not data (None: the text form's planned paths), or what items it gives (a callable:
`when_set`, left out unless set). The text, markdown and html renderers read the model and compute nothing of their own
from the plan. Numbers are held as the plan holds them; the data rounds them (`rounded`, 9 decimals), and every
format shows a limit with `number`, so they agree.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, fields, is_dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar, Literal

from ...plan import FixedChain, IndexPlan

if TYPE_CHECKING:
    from ..check.check_joints import JointReport

REPORT_VERSION = 1
JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "floating", "planar")

RowKind = Literal["mapped", "held", "mimic"]
OriginKind = Literal[
    "urdf_moving_joint", "urdf_fixed_joint", "calibration_inline", "calibration_file", "fixed_chain", "assumed_identity", "temporal"
]
SettingValue = str | int | bool | None | IndexPlan
SERIES_TEXT = "joint values also as time series (each driven joint, URDF units), plotted beside the 3D view"


def rounded(value: float) -> float:
    """Rounded to 9 decimals, -0.0 as 0.0: equal across machines whose last bits of sin/cos differ."""
    return round(float(value), 9) + 0.0


def number(value: float) -> str:
    """A number as every format shows a limit, a slack or a table cell: 6 significant digits of its rounded value."""
    return f"{rounded(value):.6g}"


DataSpec = Mapping[str, "str | None | Callable[[Any], Mapping[str, Any]]"]


def when_set(name: str) -> Callable[[Any], Mapping[str, Any]]:
    """A field left out of the data unless set: the golden reports stay as they were before it existed."""
    return lambda entry: {name: value} if (value := getattr(entry, name)) else {}


def as_data(value: Any) -> Any:
    """The model as plain data: dataclasses as dicts (by their fields' data names), tuples as lists, floats rounded,
    a shown path as its relative form; every other value as it is."""
    if isinstance(value, ShownPath):
        return value.relative
    if is_dataclass(value) and not isinstance(value, type):
        spec: DataSpec = getattr(value, "DATA", {})  # per field: None (not data), its data name, or its data items
        items: dict[str, Any] = {}
        for item in fields(value):
            name = spec.get(item.name, item.name)
            if callable(name):
                items.update({key: as_data(entry) for key, entry in name(value).items()})
            elif name is not None:
                items[name] = as_data(getattr(value, item.name))
        return items
    if isinstance(value, Mapping):
        return {key: as_data(item) for key, item in value.items()}
    if isinstance(value, tuple | list):
        return [as_data(item) for item in value]
    return rounded(value) if isinstance(value, float) else value


@dataclass(frozen=True)
class ShownPath:
    """A plan path two ways: as the plan holds it (text, for the terminal that ran the command) and relative to the
    config's folder, posix (markdown and json: the same bytes on every machine)."""

    planned: Path
    relative: str


@dataclass(frozen=True)
class SourceEntry:
    DATA: ClassVar[DataSpec] = {"file_key": None, "file": lambda s: {s.file_key: s.file}, "settings": lambda s: s.settings}
    name: str
    kind: str  # "parquet", "lerobot", ...
    file_key: str  # "path", or "root" for a LeRobot dataset
    file: ShownPath
    names: tuple[str, ...]
    settings: Mapping[str, SettingValue]  # the kind's other fields, by name (column, index, episode, ...)


@dataclass(frozen=True)
class Wrap:
    period: float  # source units
    center: float


@dataclass(frozen=True)
class Slack:
    value: float
    unit: str  # as the config wrote it for this joint's kind


@dataclass(frozen=True)
class Mimic:
    driver: str
    multiplier: float
    offset: float


@dataclass(frozen=True)
class Observed:
    """What `--sample` saw of one mapped value (check's JointReport, in the report's terms)."""

    rows: int
    min: float | None
    max: float | None
    fits: bool
    verdict: str
    slack_rows: int


@dataclass(frozen=True)
class JointRow:
    """One URDF joint the pipeline drives: mapped from a source value, held at a value, or a <mimic> joint."""

    DATA: ClassVar[DataSpec] = {"factor": None}

    kind: RowKind
    joint: str
    type: str  # the URDF joint type
    unit: str | None  # the source unit (mapped without source_range), the URDF unit (held, mimic), None (source_range)
    limits_urdf: tuple[float, float] | None
    source_name: str | None = None
    source_index: int | None = None
    factor: float | None = None  # the unit factor (mapped without source_range)
    sign: float | None = None
    offset: float | None = None  # URDF units
    scale: float | None = None
    wrap: Wrap | None = None
    source_range: tuple[float, float] | None = None
    target_range: tuple[float, float] | None = None  # URDF units
    limits_source_units: tuple[float, float] | None = None  # JointChannel.limits_in_source_unit
    slack_source_units: float | None = None  # the slack as a span of raw source values (JointChannel.slack_in_source_unit)
    slack: Slack | None = None  # limits.slack as the config wrote it for this joint's kind: 2 deg
    mimic: Mimic | None = None
    hold: float | None = None  # URDF units
    observed: Observed | None = None

    @property
    def limits_unit(self) -> str:
        """The unit of limits_source_units: the source's, or "source units" when source_range maps the values."""
        return self.unit if self.unit is not None and self.source_range is None else "source units"

    @property
    def slack_text(self) -> str:
        """The slack with its own unit, as every format shows it: "2 deg"; "0" for none (a zero's unit says nothing)."""
        value, unit = (self.slack.value, self.slack.unit) if self.slack else (0.0, "")
        return f"{number(value)} {unit}" if rounded(value) and unit else "0"


@dataclass(frozen=True)
class UrdfEntry:
    origin: str
    sha256: str


@dataclass(frozen=True)
class Appearance:
    color: tuple[float, float, float]  # RGB 0..1
    opacity: float


@dataclass(frozen=True)
class Compare:
    robot: str  # the measured robot
    threshold: str  # as written


@dataclass(frozen=True)
class RobotEntry:
    DATA: ClassVar[DataSpec] = {"urdf_path": None, "appearance": when_set("appearance"), "compare": when_set("compare")}
    key: str
    robot_name: str
    urdf_path: Path  # the file the URDF text came from, as the plan holds it
    urdf: UrdfEntry
    entity_path_prefix: str
    frame_prefix: str
    root_frame: str
    collision_geometries: Literal["keep", "drop"]
    source: str | None  # None: a scene, no joint source
    nan_policy: str | None
    on_violation: str | None
    joint_counts: Mapping[str, int]  # per URDF joint type (JOINT_TYPES), and "mimic"
    joints: tuple[JointRow, ...]  # mapped (config order), held, mimic
    ignored_source_values: tuple[str, ...]
    appearance: Appearance | None = None  # appearance:, None: the URDF's materials
    compare: Compare | None = None  # a commanded copy's (compare:)

    @property
    def copy_text(self) -> str:
        """The appearance and comparison in one line ("" without either); made of numbers, a key and a checked threshold."""
        parts = []
        if self.appearance is not None:
            rgb, alpha = self.appearance.color, self.appearance.opacity
            parts.append(f"drawn in colour [{', '.join(f'{c:g}' for c in rgb)}] at opacity {alpha:g}")
        if self.compare is not None:
            parts.append(f"a copy compared with robot '{self.compare.robot}', threshold {self.compare.threshold}")
        return "; ".join(parts)


@dataclass(frozen=True)
class EdgeOrigin:
    DATA: ClassVar[DataSpec] = {"fixed_chain": lambda o: {"fixed_chain": o.fixed_chain.joints if o.fixed_chain else None}}
    kind: OriginKind
    description: str
    robot: str | None = None
    joint: str | None = None
    joint_type: str | None = None
    file: str | None = None  # relative to the config's folder
    line: int | None = None
    label: str | None = None  # "edges[2]", "calib/extrinsics.yaml[0]", ...
    source: str | None = None  # a temporal edge's source
    fixed_chain: FixedChain | None = None  # in the data, its joints


@dataclass(frozen=True)
class TemporalValues:
    """A temporal edge's pose: named values of a source, per row."""

    DATA: ClassVar[DataSpec] = {"quaternion_names": "quaternion_xyzw_names", "quaternion_indices": "quaternion_xyzw_indices"}

    source: str
    entity: str
    translation_names: tuple[str, ...]
    translation_indices: tuple[int, ...]
    quaternion_names: tuple[str, ...]  # x, y, z, w
    quaternion_indices: tuple[int, ...]
    tf_topic: str | None = None  # a bag's /tf edge: the child's transforms on this topic, not named values


@dataclass(frozen=True)
class EdgeEntry:
    """One edge of the frame graph. URDF moving joints are at their origin (joint value 0)."""

    DATA: ClassVar[DataSpec] = {"translation": "translation_m", "quaternion_xyzw": None}

    parent: str
    child: str
    origin: EdgeOrigin
    translation: tuple[float, ...] | None  # metres; None for a temporal edge
    rotation_rpy_deg: tuple[float, ...] | None  # rounded, -180 as 180; None for a temporal edge
    quaternion_xyzw: tuple[float, ...] | None = None  # a configured edge's, as the plan holds it
    temporal: TemporalValues | None = None


@dataclass(frozen=True)
class SegmentEntry:
    id: str
    episode: int | None
    stem: str | None
    frames: int | None
    output: ShownPath


@dataclass(frozen=True)
class TrailEntry:
    """A trail every segment's recording draws: a link's path in a frame."""

    robot: str
    link: str
    frame: str
    style: str  # line | points
    window: str  # "2 s", "200 rows", "the whole recording"


@dataclass(frozen=True)
class OutputEntry:
    DATA: ClassVar[DataSpec] = {"recording_id": None, "path": None, "joint_series": when_set("joint_series"), "trails": when_set("trails")}
    application_id: str
    layout: str
    recording_id: str  # the first segment's
    path: ShownPath  # the first segment's output
    segment_count: int
    segments: tuple[SegmentEntry, ...]
    model: ShownPath | None
    manifest: ShownPath
    joint_series: bool = False  # output.joint_series: every format shows it only when set
    trails: tuple[TrailEntry, ...] = ()  # `trails:`: every format shows them only when there are some

    @property
    def single(self) -> bool:
        """One recording, no model: text prints it on one line."""
        return self.segment_count == 1 and self.layout == "single"


@dataclass(frozen=True)
class QaEntry:
    """The config's `qa:` thresholds as written (each with its unit), shown only when they differ from the defaults."""

    static_velocity: str
    spike_factor: float
    spike_jerk: str | None
    gap: str  # "50 ms" or "2.5 steps"
    length_outlier: float
    bias: str
    fail_on: tuple[str, ...]


@dataclass(frozen=True)
class WarningEntry:
    file: str | None  # relative to the config's folder
    line: int  # 0: unknown
    column: int
    path: str
    message: str


@dataclass(frozen=True)
class SampleEntry:
    """What `plan --sample` read: the first `rows` rows (at most) of each robot source of the first segment."""

    DATA: ClassVar[DataSpec] = {"reports": None}

    rows: int
    read: Mapping[str, int]  # rows read per source name, by name
    reports: tuple[JointReport, ...]  # check's verdict per mapped value (check renders them)


@dataclass(frozen=True)
class PictureEntry:
    """A picture `--render` drew: what it shows, and its path as the command line gave the folder."""

    label: str
    path: str


@dataclass(frozen=True)
class FrameTree:
    root: str
    mermaid: str  # the frame tree as a mermaid `graph TD`


@dataclass(frozen=True)
class PlanReport:
    """What a run of the config would do, read from its plan (and, with --sample, the first rows of its sources)."""

    DATA: ClassVar[DataSpec] = {
        "sources": lambda r: {"sources": r.sources_by_name},
        "configured_edges": None,
        "pictures": when_set("pictures"),
        "qa": when_set("qa"),
    }

    config: ShownPath
    root_frame: str
    sources: tuple[SourceEntry, ...]  # config order (the data's: by name)
    robots: tuple[RobotEntry, ...]
    edges: tuple[EdgeEntry, ...]  # every edge, top down from the root (children by name)
    configured_edges: tuple[EdgeEntry, ...]  # the config's own edges in config order: static, then temporal
    frame_tree: FrameTree
    output: OutputEntry
    warnings: tuple[WarningEntry, ...]  # sorted, each once
    sample: SampleEntry | None
    pictures: tuple[PictureEntry, ...] = ()  # with --render only
    qa: QaEntry | None = None  # `qa:`, when it changes a default
    report_version: int = REPORT_VERSION

    @property
    def sources_by_name(self) -> tuple[SourceEntry, ...]:
        """The data's order, and the tables'."""
        return tuple(sorted(self.sources, key=lambda s: s.name))
