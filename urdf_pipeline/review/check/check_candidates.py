"""The corrections `check` tries on a sample of one mapped value, and which of them fit the joint's URDF limits.

A candidate is a unit of the joint's kind (rad, deg; m, cm, mm), a sign, a wrap by a full turn (angles) and an
offset (angles: the config's own, 0, +-90 and +-180 deg), with the config's scale kept. Its cost is the number of
things it changes in the config's entry: the simplest fitting candidate is the advice. Two guards keep the freedom
of these combinations from fitting anything:

- a wrap is tried only when every sampled value lies within one turn of zero (what an encoder that wraps reports);
- a unit that shrinks the values (rad -> deg, m -> mm) together with an offset or wrap is tried only when the values
  cannot be the configured unit: they go beyond a full turn and beyond the limits. Tiny values moved by 90 deg fit
  almost any joint, and a real joint swap must stay "probably another joint".
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ...compile import ANGULAR_UNITS, FACTORS, LINEAR_UNITS, UNIT_NAMES, corrected, turn, within
from ...plan import JointChannel

OFFSETS_DEG = (0.0, 90.0, -90.0, 180.0, -180.0)


def angular(channel: JointChannel) -> bool:
    return channel.source_unit in ANGULAR_UNITS


@dataclass(frozen=True)
class Candidate:
    unit: str
    sign: int
    wrap: bool
    offset: float  # URDF units (rad or m), added after conversion

    def values(self, channel: JointChannel, raw: np.ndarray) -> np.ndarray:
        return corrected(channel, raw, self.unit, self.sign, self.wrap, self.offset)

    def changes(self, channel: JointChannel) -> tuple[str, ...]:
        """What this candidate changes in the config's entry, in the order the advice names them."""
        found = []
        if self.unit != channel.source_unit:
            found.append("unit")
        if self.sign != channel.sign:
            found.append("sign")
        if self.wrap != bool(channel.wrap):
            found.append("wrap")
        if not math.isclose(self.offset, channel.offset, abs_tol=1e-9):
            found.append("offset")
        return tuple(found)

    def is_current(self, channel: JointChannel) -> bool:
        return channel.source_range is None and not self.changes(channel)

    def describe(self, channel: JointChannel) -> str:
        parts = []
        if self.unit != channel.source_unit:
            parts.append(f"unit {self.unit}")
        if self.sign < 0:
            parts.append("negate")
        if self.wrap:
            parts.append("wrap a full turn")
        if self.offset and angular(channel):
            parts.append(f"offset {math.degrees(self.offset):+.6g} deg")
        elif self.offset:
            parts.append(f"offset {self.offset:+.6g} m")
        return ", ".join(parts) or "identity"

    def advice(self, channel: JointChannel) -> str:
        """The advice in words: the unit first, as the most common mistake ("the values fit if they are degrees")."""
        changes = self.changes(channel)
        if changes == ("unit",):
            return f"the values fit if they are {UNIT_NAMES[self.unit]}: `unit: {self.unit}`"
        if "unit" in changes:
            rest = Candidate(channel.source_unit, self.sign, self.wrap, self.offset).describe(channel)
            return f"the values fit if they are {UNIT_NAMES[self.unit]} with {rest}: `unit: {self.unit}` and the rest of the entry to paste"
        return f"one correction fits: {self.describe(channel)}"

    def yaml(self, channel: JointChannel) -> str:
        entry = [f"joint: {channel.joint}", f"unit: {self.unit}"]
        if channel.scale != 1:
            entry.append(f"scale: {channel.scale:g}")
        if self.wrap:
            period = turn(channel, self.unit)
            entry.append(f"wrap: {round(period, 9):g}" if self.unit == "deg" else f"wrap: {round(period, 9)}")
        if self.sign < 0:
            entry.append("sign: -1")
        if self.offset:
            entry.append(f"offset: {round(self.offset, 9)}")
        return f"{channel.source_name}: {{{', '.join(entry)}}}"


def candidates(channel: JointChannel, raw: np.ndarray) -> list[Candidate]:
    """Every candidate worth trying on `raw` (finite values), simplest first (fewest changes, the unit changed before
    the sign, the wrap and the offset; bigger units first)."""
    signs = (int(channel.sign) if channel.sign in (1, -1) else 1, -int(channel.sign) if channel.sign in (1, -1) else -1)
    if angular(channel):
        offsets = list(dict.fromkeys([channel.offset, *(math.radians(d) for d in OFFSETS_DEG)]))
        combos = itertools.product(ANGULAR_UNITS, signs, (False, True), offsets)
    else:
        combos = itertools.product(LINEAR_UNITS, signs, (False,), list(dict.fromkeys([channel.offset, 0.0])))
    found = [Candidate(unit, sign, wrap, offset) for unit, sign, wrap, offset in combos]
    found = [c for c in found if _plausible(c, channel, raw)]
    return sorted(found, key=lambda c: _order(c, channel))


_WEIGHT = {"unit": 1, "sign": 2, "wrap": 3, "offset": 4}  # at equal counts: a unit mistake is the most common


def _order(candidate: Candidate, channel: JointChannel) -> tuple[float, ...]:
    weights = [_WEIGHT[name] for name in candidate.changes(channel)]
    return (
        len(weights),
        max(weights, default=0),
        sum(weights),
        abs(candidate.offset - channel.offset),
        candidate.offset < channel.offset,
        -FACTORS[candidate.unit],
    )


def _plausible(candidate: Candidate, channel: JointChannel, raw: np.ndarray) -> bool:
    """The two guards of the module docstring; the config's own corrections are always tried."""
    if candidate.is_current(channel) or not raw.size:
        return True
    if candidate.wrap and not channel.wrap and float(np.max(np.abs(raw))) >= turn(channel, candidate.unit):
        return False
    shrinks = FACTORS[candidate.unit] < FACTORS[channel.source_unit]
    moved = candidate.wrap or not math.isclose(candidate.offset, channel.offset, abs_tol=1e-9)
    if shrinks and moved and angular(channel):
        assert channel.lower is not None and channel.upper is not None
        as_configured = float(np.max(np.abs(raw))) * FACTORS[channel.source_unit] * abs(channel.scale)
        return as_configured > max(2 * math.pi, abs(channel.lower), abs(channel.upper)) + channel.slack
    return True


def fitting(channel: JointChannel, raw: np.ndarray) -> list[Candidate]:
    """The candidates that fit the limits, one per distinct result on the sample (the simplest of equals)."""
    kept: list[tuple[Candidate, np.ndarray]] = []
    for candidate in candidates(channel, raw):
        values = candidate.values(channel, raw)
        if within(channel, values) and not any(np.allclose(values, other, atol=1e-9) for _, other in kept):
            kept.append((candidate, values))
    return [c for c, _ in kept]
