"""Source units and their factor to URDF units (rad for angular joints, m for prismatic ones), `joints.unit` and
`limits.slack` as docs/config-reference.md describes them, and the one unit advisor."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import quoted, shown
from ..plan import JointChannel

if TYPE_CHECKING:
    import numpy as np

FACTORS: dict[str, float] = {"rad": 1.0, "deg": math.pi / 180.0, "m": 1.0, "cm": 1e-2, "mm": 1e-3}
ANGULAR_UNITS = ("rad", "deg")
LINEAR_UNITS = ("m", "cm", "mm")


def urdf_unit(angular: bool) -> str:
    return "rad" if angular else "m"


def fits(unit: str, angular: bool) -> bool:
    return unit in (ANGULAR_UNITS if angular else LINEAR_UNITS)


@dataclass(frozen=True)
class RobotUnits:
    """The unit of a robot's source values by joint kind, from `joints.unit` (omitted: the URDF's units)."""

    angle: str = "rad"
    length: str = "m"
    given: str | None = None  # the single unit the config wrote, when it wrote one (for messages)

    def for_joint(self, angular: bool) -> str:
        return self.angle if angular else self.length


def robot_units(spec: Any) -> RobotUnits:
    """`joints.unit` as the schema allows it: absent, one unit (applies to its own kind only), or {angle, length}."""
    if spec is None:
        return RobotUnits()
    if isinstance(spec, str):
        return RobotUnits(angle=spec, given=spec) if spec in ANGULAR_UNITS else RobotUnits(length=spec, given=spec)
    return RobotUnits(angle=spec.get("angle", "rad"), length=spec.get("length", "m"))


# limits.slack carries its own unit, so that changing joints.unit cannot change it (2 deg stays 2 deg when the data
# switches to rad). A string "NUMBER UNIT" applies to the joints of its unit's kind; {angle: ..., length: ...} to both.


@dataclass(frozen=True)
class Slack:
    """The overshoot clamped at the limits, by joint kind, in URDF units (rad, m), with the unit the config wrote it in."""

    angle: float = 0.0
    length: float = 0.0
    angle_unit: str = "rad"
    length_unit: str = "m"
    single: bool | None = None  # the string form names one kind (True: angles): it must apply to some mapped joint

    def for_joint(self, angular: bool) -> float:
        """The slack of one joint kind, URDF units."""
        return self.angle if angular else self.length

    def written(self, angular: bool) -> tuple[float, str]:
        """The slack of one joint kind as the config wrote it: (2.0, "deg")."""
        value, unit = (self.angle, self.angle_unit) if angular else (self.length, self.length_unit)
        return (value / FACTORS[unit], unit)


@dataclass(frozen=True)
class SlackProblem:
    """A refused slack: the key under limits.slack it is at (() for slack itself, ("angle",) for its angle) and why."""

    path: tuple[str, ...]
    message: str


def _show(written: Any) -> str:
    """A slack as written, in a message: a string quoted, a number as YAML read it; bounded and on one line."""
    return quoted(written, 60) if isinstance(written, str) else shown(written, 60)


def number_text(value: float) -> str:
    """2.0 -> 2, 0.5 -> 0.5: numbers as a person writes them in YAML."""
    return f"{value:g}"


def parse_slack(spec: Any, meant: dict[bool, str]) -> tuple[Slack, list[SlackProblem]]:
    """limits.slack as written: 0, "2 deg", or {angle: "2 deg", length: "5 mm"}. `meant` is the source unit by joint kind
    (True: angular) of the robot's mapped joints: what a bare number meant before slack carried a unit, for the fix."""
    if spec is None:
        return Slack(), []
    if isinstance(spec, dict):
        problems: list[SlackProblem] = []
        parts: dict[str, tuple[float, str]] = {}
        for key, angular in (("angle", True), ("length", False)):
            if key in spec:
                part = _slack_part(spec[key], (key,), angular, meant, problems)
                if part is not None:
                    parts[key] = part
        angle, length = parts.get("angle", (0.0, "rad")), parts.get("length", (0.0, "m"))
        return Slack(angle[0], length[0], angle[1], length[1]), problems
    problems = []
    part = _slack_part(spec, (), None, meant, problems)
    if part is None:
        return Slack(), problems
    value, unit = part
    if unit in ANGULAR_UNITS:
        return Slack(angle=value, angle_unit=unit, single=True if value else None), problems
    return Slack(length=value, length_unit=unit, single=False if value else None), problems


def _slack_part(
    written: Any, path: tuple[str, ...], angular: bool | None, meant: dict[bool, str], problems: list[SlackProblem]
) -> tuple[float, str] | None:
    """One slack value: (URDF units, its unit), or None after adding why not. angular None: either kind (slack itself)."""
    return quantity_part(SLACK, written, path, angular, problems, lambda value: _no_unit(written, value, angular, meant))


@dataclass(frozen=True)
class Quantity:
    """A threshold the config writes as NUMBER UNIT (`limits.slack`, the `qa:` thresholds): its units by joint kind
    (True: angular; factor to URDF/SI units) and the words of its messages, so every such value reads and fails alike."""

    name: str  # in messages: "slack", "static_velocity"
    noun: str  # "a slack", "a velocity"
    units: dict[bool, dict[str, float]]
    kinds: dict[bool, str]  # what each kind's values are: "an angle", "a length"
    example: dict[bool, str]  # a value of each kind: "2 deg", "5 mm"
    negative: str  # why a negative value is refused
    unit_text: str = ""  # the units as messages list them; "": each kind's, "; " between

    def unit_list(self) -> str:
        return self.unit_text or "; ".join(", ".join(self.units[k]) for k in (True, False))

    def factors(self) -> dict[str, float]:
        return {**self.units[True], **self.units[False]}


_NUMBER_UNIT = re.compile(r"^\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z]+(?:/[A-Za-z]+(?:\^\d)?)?)?\s*$")


def quantity_part(
    kind: Quantity, written: Any, path: tuple[str, ...], angular: bool | None, problems: list[SlackProblem], no_unit: Callable[[float], str]
) -> tuple[float, str] | None:
    """One NUMBER UNIT value of `kind`: (URDF/SI units, its unit), or None after adding why not to `problems`. angular
    None: either kind; `no_unit(value)` says how to fix a bare number other than 0."""
    examples = f"{kind.example[True]} or {kind.example[False]}"
    if isinstance(written, bool) or not isinstance(written, int | float | str):
        problems.append(SlackProblem(path, f"wrong type: expected a number with its unit such as {examples}, got {_show(written)}"))
        return None
    match = _NUMBER_UNIT.match(written) if isinstance(written, str) else None
    if isinstance(written, str) and match is None:
        problems.append(
            SlackProblem(path, f"{_show(written)} is not {kind.noun}: write NUMBER UNIT, e.g. {examples} (units {kind.unit_list()})")
        )
        return None
    try:
        value = float(match.group(1)) if match else float(written)
    except OverflowError:  # an integer too big for a float
        value = math.inf
    unit = (match.group(2) or "") if match else ""
    if not math.isfinite(value):
        problems.append(SlackProblem(path, f"{kind.name} {_show(written)} is not a finite number"))
        return None
    if value < 0:
        problems.append(SlackProblem(path, f"{kind.name} {_show(written)} is negative; {kind.negative}"))
        return None
    factors = kind.factors()
    if value == 0 and not unit:
        return (0.0, next(iter(kind.units[angular is not False])))
    if not unit:
        problems.append(SlackProblem(path, no_unit(value)))
        return None
    if unit not in factors:
        problems.append(SlackProblem(path, f"unknown unit {quoted(unit)} in {kind.name} {_show(written)}; units are {kind.unit_list()}"))
        return None
    if angular is not None and unit not in kind.units[angular]:
        names = list(kind.units[angular])
        units = f"{', '.join(names[:-1])} or {names[-1]}"
        example_unit = kind.example[angular].split()[-1]
        problems.append(
            SlackProblem(
                path,
                f"{kind.name} {_show(written)} is {kind.kinds[not angular]}, but {path[-1]} takes {kind.kinds[angular]}: write it in "
                f"{units} (e.g. {number_text(value)} {example_unit})",
            )
        )
        return None
    return (value * factors[unit], unit)


_UNIT_LIST = "rad, deg for revolute and continuous joints; m, cm, mm for prismatic joints"
SLACK = Quantity(
    "slack",
    "a slack",
    {True: {u: FACTORS[u] for u in ANGULAR_UNITS}, False: {u: FACTORS[u] for u in LINEAR_UNITS}},
    {True: "an angle", False: "a length"},
    {True: "2 deg", False: "5 mm"},
    "the slack is the overshoot tolerated beyond each limit, 0 or more",
    _UNIT_LIST,
)


def _no_unit(written: Any, value: float, angular: bool | None, meant: dict[bool, str]) -> str:
    """The fix for a bare number: what it meant when slack was in each joint's source unit."""
    kinds = [angular] if angular is not None else [k for k in (True, False) if k in meant] or [True]
    units = {k: meant.get(k, urdf_unit(k)) for k in kinds}
    text = number_text(value)
    if angular is not None:
        fix, how = f"{'angle' if angular else 'length'}: {text} {units[angular]}", f"unit {units[angular]}"
    elif len(kinds) == 2:
        fix = f"slack: {{angle: {text} {units[True]}, length: {text} {units[False]}}}"
        how = f"angles in {units[True]} and lengths in {units[False]}"
    else:
        fix, how = f"slack: {text} {units[kinds[0]]}", f"unit: {units[kinds[0]]}"
    return (
        f"{_show(written)} has no unit; slack now carries its own so that changing joints.unit cannot change it: "
        f"write {fix} (what {_show(written)} meant with {how})"
    )


UNIT_NAMES = {"rad": "radians", "deg": "degrees", "m": "metres", "cm": "centimetres", "mm": "millimetres"}


# The one unit advisor ("in which unit would these values fit?") of run's refusal, check's advice and init's choice.


def corrected(channel: JointChannel, raw: np.ndarray, unit: str, sign: float, wrap: bool, offset: float) -> np.ndarray:
    """Raw values in URDF units had the entry said `unit`, `sign`, `offset` (URDF units) and, with `wrap`, a wrap by a
    full turn of that unit about the limits' middle; the config's scale kept."""
    gain = FACTORS[unit] * channel.scale * sign
    if wrap:
        from ..sources import wrapped

        assert channel.lower is not None and channel.upper is not None
        raw = wrapped(raw, ((channel.lower + channel.upper) / 2 - offset) / gain, turn(channel, unit))
    return raw * gain + offset


def turn(channel: JointChannel, unit: str) -> float:
    """A full turn in raw values of `unit`, with the config's scale."""
    return 2 * math.pi / (FACTORS[unit] * channel.scale)


def within(channel: JointChannel, values: np.ndarray) -> bool:
    """Every value (URDF units) within the joint's limits and slack."""
    assert channel.lower is not None and channel.upper is not None
    return bool(((values >= channel.lower - channel.slack) & (values <= channel.upper + channel.slack)).all())


def unit_fits(channel: JointChannel, unit: str, raw: np.ndarray) -> bool:
    """Whether the raw values fit the limits read in `unit`, every other correction of the entry kept."""
    return within(channel, corrected(channel, raw, unit, channel.sign, bool(channel.wrap), channel.offset))


def units_that_fit(channel: JointChannel, raw: np.ndarray) -> list[str]:
    """The other units of the channel's joint kind in which the raw values fit the limits, every other correction
    kept: the likely unit mistake. Biggest unit first."""
    if channel.source_range is not None or channel.lower is None or channel.upper is None or channel.source_unit not in FACTORS:
        return []
    kind = ANGULAR_UNITS if channel.source_unit in ANGULAR_UNITS else LINEAR_UNITS
    return [unit for unit in kind if unit != channel.source_unit and unit_fits(channel, unit, raw)]


REACH_SHARE = 0.1  # values that reach this share of the joint's range in a unit look like that unit; below, near zero


def reaches(channel: JointChannel, raw: np.ndarray, unit: str) -> bool:
    """Whether the raw values, read in `unit`, reach at least REACH_SHARE of the joint's range from zero (where in a
    smaller unit they would barely leave it): check's "clearly ambiguous" and init's choice of unit."""
    assert channel.lower is not None and channel.upper is not None
    width = channel.upper - channel.lower
    return width > 0 and float(abs(raw).max()) * FACTORS[unit] * abs(channel.scale) >= REACH_SHARE * width


def bigger_unit(channel: JointChannel, raw: np.ndarray) -> str | None:
    """For values that fit as configured: the bigger unit (deg -> rad, mm -> m) in which they fit as well and reach
    REACH_SHARE of the joint's range, where as configured they stay near zero. Clearly ambiguous: check says so."""
    if channel.wrap or not raw.size:
        return None
    bigger = [u for u in units_that_fit(channel, raw) if FACTORS[u] > FACTORS[channel.source_unit]]
    return next((u for u in bigger if reaches(channel, raw, u)), None)


def unit_hint(channel: JointChannel, raw_low: float, raw_high: float) -> str:
    """ "the values fit the limits if they are degrees: `unit: deg`" when another unit fits (run's refusal), else "".
    A wrapped entry gets none: the range's two ends say nothing of where its wrapped values land."""
    import numpy as np

    units = [] if channel.wrap else units_that_fit(channel, np.array([raw_low, raw_high]))
    if not units:
        return ""
    names = " or ".join(UNIT_NAMES[u] for u in units)
    return f"the values fit the limits if they are {names}: `unit: {units[0]}`"
