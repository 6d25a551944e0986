"""What `diff` reports (DiffReport, made of Changes), how paths are compared, and the tolerances that make two numbers,
rotations or translations the same."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ...errors import listing
from ...urdf import Quaternion, Vector, normalized_quaternion, quaternion_multiply
from ..plan_report.report_model import PictureEntry, rounded

TOLERANCE = 1e-9
Wording = Mapping[str, "str | Callable[[Any], Any] | Wording | None"]  # per data key: how diff says its change


@dataclass(frozen=True)
class Change:
    """One difference: `subject: detail` is its line (`robot arm: j2 -> panda_joint2: sign 1 -> -1`)."""

    group: str  # "robot", "edges", "sources" or "output"
    subject: str  # "robot arm", "edge world -> panda_link0", "source arm_state", "output"
    detail: str
    old: Any = None  # JSON-ready values, when the change is one field's
    new: Any = None

    @property
    def line(self) -> str:
        return f"{self.subject}: {self.detail}"


@dataclass(frozen=True)
class DiffReport:
    """What `diff` found: the two configs as the user named them, and every change in report order (diff.diff_plans).
    diff_render.py prints it as text or JSON."""

    old: str  # "OLD", or "CONFIG@REV" with --git
    new: str
    changes: tuple[Change, ...]
    pictures: tuple[PictureEntry, ...] = ()  # with --render only: old, new, side by side, overlay

    @property
    def equivalent(self) -> bool:
        return not self.changes


@dataclass(frozen=True, eq=False)
class PathValue:
    """A plan path seen from its config's folder: equal to another when either the relative or the absolute path is
    (not transitive, hence not hashable: PathValues are compared, never keyed)."""

    relative: str
    absolute: str

    def __eq__(self, other: object) -> bool:
        return isinstance(other, PathValue) and (self.relative == other.relative or self.absolute == other.absolute)

    def __str__(self) -> str:
        return self.relative


def same(a: Any, b: Any) -> bool:
    """Equal, floats within TOLERANCE (nested in tuples and lists too)."""
    if isinstance(a, bool) or isinstance(b, bool):
        return a is b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(a, b, rel_tol=TOLERANCE, abs_tol=TOLERANCE)
    if isinstance(a, tuple | list) and isinstance(b, tuple | list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b, strict=True))
    return bool(a == b)


def _number(value: float) -> str:
    return f"{value + 0.0:.12g}"  # + 0.0: no "-0"


def value_text(value: Any) -> str:
    """A value as the report shows it: `1`, `-0.5`, `[0, 0, 0.5]`, `none`, `""`."""
    if value is None:
        return "none"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int | float):
        return _number(float(value))
    if isinstance(value, tuple | list):
        return "[" + ", ".join(value_text(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{key}: {value_text(v)}" for key, v in value.items()) + "}"
    if isinstance(value, str):
        return value if value else '""'
    return str(value)


def added_removed(old: Sequence[Any], new: Sequence[Any], colon: str = "", limit: int = 12) -> str:
    """`added A, B; removed C` (each list bounded by `errors.listing`), "" when neither list holds an item the other lacks."""
    added = [str(item) for item in new if item not in old]
    removed = [str(item) for item in old if item not in new]
    return "; ".join(f"{word}{colon} {listing(items, limit)}" for word, items in (("added", added), ("removed", removed)) if items)


def rounded_text(values: Sequence[float]) -> str:
    """A pose's numbers to 9 decimals (report_model.rounded), as the report shows a translation or a quaternion."""
    return value_text([rounded(v) for v in values])


def _json(value: Any) -> Any:
    if value is None or isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, tuple | list):
        return [_json(v) for v in value]
    return str(value)


def _length(mm: float) -> str:
    return f"{mm:.1f}" if mm == 0 or mm >= 0.05 else f"{mm:.2g}"


def _degrees(deg: float) -> str:
    return f"{deg:.2f}" if deg == 0 or deg >= 0.005 else f"{deg:.2g}"


def _unit_quaternion(q: Sequence[float]) -> Quaternion:
    return normalized_quaternion(tuple(q)) or (0.0, 0.0, 0.0, 1.0)


def rotation_angle_deg(a: Sequence[float], b: Sequence[float]) -> float:
    """The angle of the rotation taking a to b (both quaternions x, y, z, w), in degrees, in [0, 180]."""
    ax, ay, az, aw = _unit_quaternion(a)
    x, y, z, w = quaternion_multiply((-ax, -ay, -az, aw), _unit_quaternion(b))
    return math.degrees(2 * math.atan2(math.sqrt(x * x + y * y + z * z), abs(w)))


def _same_rotation(a: Sequence[float], b: Sequence[float]) -> bool:
    qa, qb = _unit_quaternion(a), _unit_quaternion(b)
    return same(qa, qb) or same(qa, tuple(-v for v in qb))  # q and -q are the same rotation


def pose_change(t_old: Vector, q_old: Sequence[float], t_new: Vector, q_new: Sequence[float]) -> str | None:
    """`moved 5.0 mm, 0.00 deg (translation [..] -> [..])`, or None for the same pose."""
    translated, rotated = not same(t_old, t_new), not _same_rotation(q_old, q_new)
    if not translated and not rotated:
        return None
    mm = math.dist(t_old, t_new) * 1000 if translated else 0.0
    deg = rotation_angle_deg(q_old, q_new) if rotated else 0.0
    what = []
    if translated:
        what.append(f"translation {rounded_text(t_old)} -> {rounded_text(t_new)}")
    if rotated:
        what.append(f"quaternion_xyzw {rounded_text(q_old)} -> {rounded_text(q_new)}")
    return f"moved {_length(mm)} mm, {_degrees(deg)} deg ({'; '.join(what)})"


class Changes:
    """The changes found so far, and the two configs' folders their paths are relative to."""

    def __init__(self, old_base: Path, new_base: Path) -> None:
        self.old_base, self.new_base = old_base, new_base
        self.changes: list[Change] = []

    def add(self, group: str, subject: str, detail: str, old: Any = None, new: Any = None) -> None:
        self.changes.append(Change(group, subject, detail, _json(old), _json(new)))

    def field(self, group: str, subject: str, label: str, old: Any, new: Any) -> None:
        if not same(old, new):
            self.add(group, subject, f"{label} {value_text(old)} -> {value_text(new)}", old, new)

    def walk(self, group: str, subject: str, old: Mapping[str, Any], new: Mapping[str, Any], wording: Wording, prefix: str = "") -> None:
        """The keyed walk over two entries of the report's plain data (report_model.as_data): each key one field, its
        label its name, unless `wording` words it: another label, a callable that shows its value, the wording of its
        own keys, or None (a comparison of its own says it). A dict is walked key by key, each labelled after its own."""
        for key in [*old, *(key for key in new if key not in old)]:
            words = wording.get(key, key)
            before, after = old.get(key), new.get(key)
            if callable(words):
                self.field(group, subject, prefix + key, words(before), words(after))
            elif isinstance(words, Mapping):
                self.walk(group, subject, before or {}, after or {}, words, prefix)
            elif isinstance(before, dict) and isinstance(after, dict) and words is not None:
                self.walk(group, subject, before, after, {}, f"{prefix}{words} ")
            elif words is not None:
                self.field(group, subject, prefix + words, before, after)

    def old_path(self, path: Path) -> PathValue:
        return path_value(path, self.old_base)

    def new_path(self, path: Path) -> PathValue:
        return path_value(path, self.new_base)


def path_value(path: Path, base: Path) -> PathValue:
    absolute = os.path.abspath(path)
    return PathValue(Path(os.path.relpath(absolute, os.path.abspath(base))).as_posix(), absolute)
