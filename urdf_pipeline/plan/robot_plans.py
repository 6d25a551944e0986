"""The robots of a plan and the edges between their frames: joint channels with their corrections, holds, mimic
joints, static, fixed-chain and temporal edges."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from ..errors import Where
from .source_plans import NanPolicy, OnViolation


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
class Comparison:
    """`compare:` a commanded copy of a measured robot (same URDF text, same driven joints): rows of the two whose
    joint values differ beyond the threshold (URDF units, by joint kind) are counted per segment."""

    robot: str  # key of the measured robot
    angle: float  # rad: the threshold of revolute and continuous joints
    length: float  # m: the threshold of prismatic joints
    written: str  # the threshold as the config wrote it, for messages: "{angle: 2 deg, length: 5 mm}"
    thresholds: tuple[float, ...] = ()  # per channel of the copy, in its order: angle or length by the joint's kind
    units: tuple[str, ...] = ()  # per channel: the unit its threshold was written in ("deg", "mm"), for messages


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
    appearance: tuple[float, float, float, float] | None = None  # RGBA in 0..1 replacing every visual's colour
    compare: Comparison | None = None

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
    """An edge read from a source row by row: named values give the translation and the quaternion, or (`tf_topic`) the
    child's transforms on a tf2_msgs/msg/TFMessage topic of the source's bag."""

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
    tf_topic: str | None = None  # a bag's /tf: the child's transforms on this topic of the source's MCAP file, no named values
