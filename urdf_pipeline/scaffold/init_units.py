"""init with a source: each joint's unit chosen from a bounded sample of the data against the URDF limits, and what
`check` would still refuse in the written config (then init does not say "the config validates").

The sample is check's (`check.plan_sample`, the first rows of each robot source); the units are judged as check and run
judge them (`compile.unit_fits`, the one unit advisor): a unit in which the values fit the limits as they are (sign 1, no offset). One such unit: it is
the choice. Several (values near zero fit deg and rad alike): the biggest in which the values reach a tenth of the
joint's range, as check judges "looks like a bigger unit" (only one: a sure choice); else the URDF's own. None: the unit of check's simplest
advice when every equally simple advice shares it (degrees with a sign, say), else the URDF's own, and the config
says to run check.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from ..compile import ANGULAR_UNITS, FACTORS, LINEAR_UNITS, UNIT_NAMES, reaches, unit_fits
from ..errors import UserError
from ..plan import JointChannel, Plan
from ..review import check_plan, fitting, plan_sample


@dataclass(frozen=True)
class UnitChoice:
    unit: str
    reason: str  # for the YAML comment: "sampled values -171..175 fit the limits only in degrees"
    sure: bool  # the values fit the limits in this unit only


@dataclass(frozen=True)
class SampledUnits:
    """The unit init writes per URDF joint, and why, from `rows` sampled rows."""

    joints: dict[str, UnitChoice]
    rows: int

    def robot_unit(self, angular: bool) -> tuple[str, str] | None:
        """The unit most joints of a kind take (ties: the URDF's), with the comment that says why; None: none sampled."""
        units = ANGULAR_UNITS if angular else LINEAR_UNITS
        chosen = [c for c in self.joints.values() if c.unit in units]
        if not chosen:
            return None
        counts = Counter(c.unit for c in chosen)
        default = units[0]
        unit = max(counts, key=lambda u: (counts[u], u == default))
        agreeing = [c for c in chosen if c.unit == unit]
        sure = [c for c in agreeing if c.sure]
        kind = "revolute and continuous" if angular else "prismatic"
        if sure:
            why = f"sampled values point to {UNIT_NAMES[unit]} for {len(sure)} of {len(chosen)} {kind} joints"
        else:
            why = f"sampled values of {len(chosen)} {kind} joints do not settle it: {UNIT_NAMES[unit]} kept"
        return unit, f"review: {why} ({self.rows} rows; each entry says why)"


def _span(values: np.ndarray) -> str:
    return f"{float(values.min()):.4g}..{float(values.max()):.4g}"


def choose_unit(channel: JointChannel, raw: np.ndarray) -> UnitChoice | None:
    """The unit for one joint from its sampled raw values (the channel as init first wrote it: sign 1, no offset)."""
    finite = raw[np.isfinite(raw)]
    if channel.source_range is not None or channel.lower is None or channel.upper is None or not finite.size:
        return None
    units = ANGULAR_UNITS if channel.source_unit in ANGULAR_UNITS else LINEAR_UNITS
    in_units = [u for u in units if unit_fits(channel, u, finite)]
    span = _span(finite)
    if len(in_units) == 1:
        return UnitChoice(in_units[0], f"sampled values {span} fit the limits only in {UNIT_NAMES[in_units[0]]}", True)
    if in_units:
        looks = [u for u in sorted(in_units, key=lambda u: -FACTORS[u]) if reaches(channel, finite, u)]
        others = [u for u in in_units if looks and u != looks[0]]
        if looks and all(FACTORS[looks[0]] >= 20 * FACTORS[u] for u in others):  # in the others they would barely leave zero
            smaller = " or ".join(UNIT_NAMES[u] for u in others)
            reason = f"sampled values {span} fit the limits in {UNIT_NAMES[looks[0]]} (in {smaller} they would barely leave zero)"
            return UnitChoice(looks[0], reason, True)
        unit = looks[0] if looks else (units[0] if units[0] in in_units else in_units[0])
        listed = " and ".join(in_units)
        return UnitChoice(unit, f"sampled values {span} fit the limits in {listed}: {unit} (settle against a known pose)", False)
    kept = fitting(channel, finite)
    simplest = {c.unit for c in kept if len(c.changes(channel)) == len(kept[0].changes(channel))} if kept else set()
    if len(simplest) == 1:
        (advised,) = simplest
        more = "" if advised == channel.source_unit else f" in {UNIT_NAMES[advised]}"
        return UnitChoice(advised, f"sampled values {span} fit the limits{more} only with another correction: see check", False)
    return UnitChoice(channel.source_unit, f"sampled values {span} fit the limits in no unit as they are: see check", False)


def sampled_units(plan: Plan, sample: dict[str, np.ndarray]) -> SampledUnits:
    joints: dict[str, UnitChoice] = {}
    rows = 0
    for robot in plan.robots:
        if robot.source is None:
            continue
        raw = sample[robot.source]
        rows = max(rows, len(raw))
        for channel in robot.channels:
            choice = choose_unit(channel, raw[:, channel.source_index])
            if choice is not None:
                joints[channel.joint] = choice
    return SampledUnits(joints, rows)


def refused_by_check(plan: Plan, sample: dict[str, np.ndarray]) -> list[str]:
    """check's rule on the written config: each mapped value whose sample does not fit as configured, one line each."""
    lines = []
    for r in check_plan(plan, sample):
        if r.current_fits:
            continue
        advice = f"; paste: {r.paste}" if r.paste else ""
        lines.append(
            f"{r.source_name} -> {r.joint} [{r.source_unit}]: values {r.values_text()} outside the limits {r.limits_text()}: {r.message}{advice}"
        )
    return lines


def read_units(plan: Plan) -> tuple[SampledUnits | None, dict[str, np.ndarray], str]:
    """(the units, the sample, "") or (None, {}, why not) when the sample cannot be read."""
    try:
        sample = plan_sample(plan)
    except UserError as exc:
        return None, {}, exc.message
    return sampled_units(plan, sample), sample, ""
