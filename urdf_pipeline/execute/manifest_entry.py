"""The record of a segment a dataset browser lists, and its JSON form in the run's manifest (ranges_and_preview.py
gathers it during the run's pass): time ranges, robots, notes and a uint8 preview of the driven joints, about 1.5 KB
per segment, so a 10,000-segment manifest stays a few MB.

`from_json` reads it back tolerating any hand edit: whatever has the wrong type or size is dropped, never raised, and
names are shown bounded (`errors.shown`).
"""

from __future__ import annotations

import base64
import datetime
import math
from dataclasses import dataclass, fields
from typing import Any, Literal, TypeVar

from ..errors import shown

BUCKETS = 32  # buckets of the stored preview (fewer when the segment has fewer rows)
PREVIEW_JOINTS = 8  # joints per robot in the preview
NOTES = 16  # notes kept per segment; the rest are counted
NOTE_LIMIT = 300  # characters of one note (as `errors.shown` shortens it)
NAME_LIMIT = 200  # characters of a robot, joint or timeline name read back
EMPTY = (255, 0)  # a bucket without a finite value: min above max
INT64_MAX = 2**63 - 1  # a timeline's values lie within ±INT64_MAX (i64::MIN is Rerun's static time)
T = TypeVar("T")
TimelineKind = Literal["sequence", "timestamp", "duration"]
_KINDS: tuple[TimelineKind, ...] = ("sequence", "timestamp", "duration")
_EPOCH = datetime.datetime(1970, 1, 1, tzinfo=datetime.UTC)


@dataclass(frozen=True)
class TimeRange:
    """A timeline's first and last index value in the segment: nanoseconds for time kinds, steps for a sequence."""

    timeline: str
    kind: TimelineKind
    first: int
    last: int

    @property
    def seconds(self) -> float | None:
        """The duration the range spans; None for a sequence (its steps have no unit)."""
        return None if self.kind == "sequence" else (self.last - self.first) / 1e9

    @property
    def first_iso(self) -> str | None:
        return iso_time(self.first) if self.kind == "timestamp" else None

    @property
    def last_iso(self) -> str | None:
        return iso_time(self.last) if self.kind == "timestamp" else None


def iso_time(nanoseconds: int) -> str:
    """A timestamp timeline's value as an ISO 8601 UTC date with nanoseconds: `2024-05-01T12:00:00.000000001Z`."""
    seconds, rest = divmod(nanoseconds, 1_000_000_000)
    when = _EPOCH + datetime.timedelta(seconds=seconds)
    return f"{when:%Y-%m-%dT%H:%M:%S}.{rest:09d}Z"


@dataclass(frozen=True)
class JointPreview:
    """One robot's preview: per joint, `buckets` (min, max) codes; code c stands for low + c / 255 * (high - low)."""

    robot: str
    rows: int
    buckets: int
    joints: tuple[str, ...]
    low: tuple[float, ...]  # the value of code 0, per joint: its lower limit, or the lowest value seen
    high: tuple[float, ...]  # the value of code 255
    limited: tuple[bool, ...]  # low and high are the joint's limits (else the range seen)
    codes: bytes  # per joint: its buckets' min codes, then their max codes; an empty bucket is (255, 0)

    def codes_of(self, joint: int) -> tuple[bytes, bytes]:
        """The (min codes, max codes) of the joint at position `joint`."""
        start = joint * 2 * self.buckets
        return self.codes[start : start + self.buckets], self.codes[start + self.buckets : start + 2 * self.buckets]


@dataclass(frozen=True)
class JointDifferences:
    """`compare:`: a commanded copy against its measured robot over the segment's rows (URDF units: rad, m)."""

    copy: str
    measured: str
    threshold: str  # as the config wrote it: "{angle: 2 deg, length: 5 mm}"
    rows: int  # rows compared (both robots had values)
    rows_beyond: int  # rows where any joint differs beyond its threshold
    unmatched: int  # rows one side had beyond the other's (0 when the sources' rows match)
    joints: tuple[str, ...]
    largest: tuple[float, ...]  # per joint: the largest absolute difference
    beyond: tuple[int, ...]  # per joint: rows beyond its threshold
    units: tuple[str, ...] = ()  # per joint: its threshold's unit as written ("deg", "mm"); () shows URDF units
    # calibration bias, per joint over the rows where both robots were still (qa.static_velocity); () in older manifests
    bias_rows: tuple[int, ...] = ()  # the still rows (0: no bias measured, mean and std 0)
    bias_mean: tuple[float, ...] = ()  # mean of (copy - measured), URDF units
    bias_std: tuple[float, ...] = ()  # its standard deviation (population, ddof 0)
    biased: tuple[bool, ...] = ()  # |mean| beyond qa.bias: `calibration_bias`

    @property
    def joints_biased(self) -> tuple[str, ...]:
        return tuple(joint for joint, flagged in zip(self.joints, self.biased, strict=False) if flagged)

    def unit_text(self, joint: int, value: float) -> str:
        """A value of the joint in its threshold's unit: "3.5 deg" (URDF units, bare, for an entry without)."""
        from ..compile import FACTORS

        unit = self.units[joint] if len(self.units) == len(self.joints) else ""
        return f"{value / FACTORS[unit]:.3g} {unit}" if unit in FACTORS else f"{value:.4g}"

    @property
    def joints_beyond(self) -> tuple[str, ...]:
        return tuple(joint for joint, rows in zip(self.joints, self.beyond, strict=True) if rows)

    def largest_text(self, joint: int) -> str:
        """A joint's largest difference in its threshold's unit: "3.5 deg" (URDF units, bare, for an entry without)."""
        return self.unit_text(joint, self.largest[joint])

    def as_json(self) -> dict[str, Any]:
        return _plain(self)

    @classmethod
    def from_json(cls, data: Any) -> JointDifferences | None:
        """Read back tolerating hand edits: any part of the wrong type or size drops the whole entry."""
        if not isinstance(data, dict) or not all(isinstance(data.get(k), str) for k in ("copy", "measured", "threshold")):
            return None
        counts = [_int_in(data.get(k), 0, INT64_MAX) for k in ("rows", "rows_beyond", "unmatched")]
        joints = data.get("joints")
        if None in counts or not isinstance(joints, list) or not 0 < len(joints) <= 4 * PREVIEW_JOINTS:
            return None
        names, largest, beyond = (
            _items(joints, str, len(joints)),
            _finite(data.get("largest"), len(joints)),
            _items(data.get("beyond"), int, len(joints)),
        )
        if names is None or largest is None or beyond is None or any(b < 0 for b in beyond):
            return None
        rows, rows_beyond, unmatched = (c or 0 for c in counts)
        return cls(
            shown(data["copy"], NAME_LIMIT),
            shown(data["measured"], NAME_LIMIT),
            shown(data["threshold"], NAME_LIMIT),
            rows,
            rows_beyond,
            unmatched,
            tuple(shown(n, NAME_LIMIT) for n in names),
            tuple(largest),
            tuple(beyond),
            tuple(_items(data.get("units"), str, len(joints)) or ()),  # a unit not in FACTORS is shown as no unit
            *_bias(data, len(joints)),
        )


def _bias(data: dict[str, Any], count: int) -> tuple[tuple[int, ...], tuple[float, ...], tuple[float, ...], tuple[bool, ...]]:
    """The bias fields read back: all four of the right form, else none (an older manifest, or a hand edit)."""
    rows, mean, std, biased = (
        _items(data.get("bias_rows"), int, count),
        _finite(data.get("bias_mean"), count),
        _finite(data.get("bias_std"), count),
        _items(data.get("biased"), bool, count),
    )
    if rows is None or mean is None or std is None or biased is None or any(r < 0 for r in rows):
        return (), (), (), ()
    return tuple(rows), tuple(mean), tuple(std), tuple(biased)


@dataclass(frozen=True)
class SegmentSummary:
    """What a browser lists of one segment (see the module)."""

    robots: tuple[str, ...]
    timelines: tuple[TimeRange, ...]
    notes: tuple[str, ...]
    notes_left_out: int
    previews: tuple[JointPreview, ...]
    differences: tuple[JointDifferences, ...] = ()  # one per compared pair (compare:)

    def as_json(self) -> dict[str, Any]:
        """The manifest's form: plain JSON values, the codes as base64."""
        return {
            "robots": list(self.robots),
            "timelines": [_time_json(t) for t in self.timelines],
            "notes": list(self.notes),
            "notes_left_out": self.notes_left_out,
            "preview": [{**_plain(p), "codes": base64.b64encode(p.codes).decode("ascii")} for p in self.previews],
            **({"differences": [d.as_json() for d in self.differences]} if self.differences else {}),
        }

    @classmethod
    def from_json(cls, data: Any) -> SegmentSummary | None:
        """`as_json`'s form read back from a manifest anyone may have edited: a part of the wrong type or size is
        dropped (a timeline, a preview, a note), a summary that is not a mapping is None; names are shown bounded."""
        if not isinstance(data, dict):
            return None
        timelines = tuple(t for t in map(_time_from_json, _list(data.get("timelines"))[:16]) if t is not None)
        previews = tuple(p for p in map(_preview_from_json, _list(data.get("preview"))[:64]) if p is not None)
        left_out = data.get("notes_left_out")
        return cls(
            robots=_strings(data.get("robots"), 64, NAME_LIMIT),
            timelines=timelines,
            notes=_strings(data.get("notes"), NOTES, NOTE_LIMIT),
            notes_left_out=_int_in(left_out, 0, INT64_MAX) or 0,
            previews=previews,
            differences=tuple(d for d in map(JointDifferences.from_json, _list(data.get("differences"))[:64]) if d is not None),
        )


def _plain(record: Any) -> dict[str, Any]:
    """A record's fields as JSON values, in their order (tuples as lists)."""
    return {f.name: list(v) if isinstance(v := getattr(record, f.name), tuple) else v for f in fields(record)}


def _time_json(time: TimeRange) -> dict[str, Any]:
    entry = _plain(time)
    if time.kind != "sequence":
        entry["seconds"] = time.seconds
    if time.kind == "timestamp":
        entry["first_iso"], entry["last_iso"] = time.first_iso, time.last_iso
    return entry


def _list(value: Any) -> list[Any]:
    return value if isinstance(value, list) else []


def _int_in(value: Any, low: int, high: int) -> int | None:
    """An int (not a bool) within [low, high], else None."""
    return value if isinstance(value, int) and not isinstance(value, bool) and low <= value <= high else None


def _items(value: Any, kind: type[T], count: int) -> list[T] | None:
    """A JSON list of exactly `count` values of `kind` (bool is no number here), else None."""
    if (
        not isinstance(value, list)
        or len(value) != count
        or not all(isinstance(v, kind) and (kind is bool or not isinstance(v, bool)) for v in value)
    ):
        return None
    return value


def _finite(value: Any, count: int) -> list[float] | None:
    """A JSON list of `count` finite numbers, as floats, else None."""
    if not isinstance(value, list) or len(value) != count:
        return None
    try:
        numbers = [float(v) for v in value if isinstance(v, int | float) and not isinstance(v, bool)]
    except OverflowError:  # an int beyond any float
        return None
    return numbers if len(numbers) == count and all(map(math.isfinite, numbers)) else None


def _codes(value: Any, size: int) -> bytes | None:
    """base64 text of exactly `size` bytes, else None."""
    if not isinstance(value, str) or len(value) > 2 * size + 8:
        return None
    try:
        raw = base64.b64decode(value, validate=True)
    except ValueError:
        return None
    return raw if len(raw) == size else None


def _strings(value: Any, count: int, limit: int) -> tuple[str, ...]:
    """The strings of a JSON list (others dropped), at most `count`, each as `errors.shown` shows it."""
    return tuple(shown(item, limit) for item in _list(value) if isinstance(item, str))[:count]


def _time_from_json(data: Any) -> TimeRange | None:
    """A timeline's range; the derived values (seconds, ISO) are computed again, never read."""
    if not isinstance(data, dict) or not isinstance(data.get("timeline"), str) or data.get("kind") not in _KINDS:
        return None
    first, last = _int_in(data.get("first"), -INT64_MAX, INT64_MAX), _int_in(data.get("last"), -INT64_MAX, INT64_MAX)
    if first is None or last is None or first > last:
        return None
    return TimeRange(shown(data["timeline"], NAME_LIMIT), data["kind"], first, last)


def _preview_from_json(data: Any) -> JointPreview | None:
    """A robot's preview whose every list has one entry per joint and whose codes fill joints x 2 x buckets bytes."""
    if not isinstance(data, dict) or not isinstance(data.get("robot"), str) or not isinstance(data.get("joints"), list):
        return None
    rows, buckets, count = _int_in(data.get("rows"), 0, INT64_MAX), _int_in(data.get("buckets"), 1, 4 * BUCKETS), len(data["joints"])
    if rows is None or buckets is None or not 0 < count <= 4 * PREVIEW_JOINTS:
        return None
    joints, limited = _items(data["joints"], str, count), _items(data.get("limited"), bool, count)
    low, high = _finite(data.get("low"), count), _finite(data.get("high"), count)
    codes = _codes(data.get("codes"), count * 2 * buckets)
    if joints is None or limited is None or low is None or high is None or codes is None:
        return None
    names = tuple(shown(j, NAME_LIMIT) for j in joints)
    return JointPreview(shown(data["robot"], NAME_LIMIT), rows, buckets, names, tuple(low), tuple(high), tuple(limited), codes)
