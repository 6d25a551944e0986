"""`qa:` -> `QaPlan`: the dataset checks' thresholds, each written with its unit (as `limits.slack`, read by the same
`units.quantity_part`) and kept in SI units; a wrong kind of unit, a negative value, a bare number other than 0 or an
unknown flag is refused where it is written."""

from __future__ import annotations

import math
from functools import partial
from typing import Any, cast

from ..errors import did_you_mean, listing, quoted, shown
from ..plan import QA_FLAGS, ByKind, QaFlag, QaPlan
from .context import CompileContext
from .units import ANGULAR_UNITS, FACTORS, LINEAR_UNITS, SLACK, Quantity, SlackProblem, number_text, quantity_part


def _per_second(power: str) -> dict[bool, dict[str, float]]:
    """The units of a rate (`/s`, `/s^3`) of angles and lengths."""
    return {True: {f"{u}/s{power}": FACTORS[u] for u in ANGULAR_UNITS}, False: {f"{u}/s{power}": FACTORS[u] for u in LINEAR_UNITS}}


VELOCITY = Quantity(
    "static_velocity",
    "a velocity",
    _per_second(""),
    {True: "an angular velocity", False: "a linear velocity"},
    {True: "5 deg/s", False: "5 mm/s"},
    "it is the speed below which a row is still, 0 or more",
)
JERK = Quantity(
    "spike.jerk",
    "a jerk",
    _per_second("^3"),
    {True: "an angular jerk", False: "a linear jerk"},
    {True: "100000 deg/s^3", False: "1000 m/s^3"},
    "it is the |jerk| above which a row spikes, 0 or more",
)
BIAS = Quantity(
    "bias",
    "a bias",
    SLACK.units,  # an angle or a length, as limits.slack
    {True: "an angle", False: "a length"},
    {True: "2 deg", False: "2 mm"},
    "it is the |mean difference| tolerated between a copy and its measured robot, 0 or more",
)
GAP = Quantity(  # "kinds" here are the two forms of a gap: a duration, or a number of nominal steps
    "gap",
    "a gap",
    {True: {"s": 1.0, "ms": 1e-3}, False: {"steps": 1.0}},
    {True: "a duration", False: "a number of steps"},
    {True: "50 ms", False: "1.5 steps"},
    "it is the largest step between timestamps tolerated, 0 or more",
)


def compile_qa(ctx: CompileContext) -> QaPlan:
    """The config's `qa:` (defaults for what it omits); problems added to ctx, located at the key at fault."""
    spec: dict[str, Any] = ctx.data.get("qa") or {}
    default = QaPlan()
    problems: list[tuple[tuple[str | int, ...], str]] = []

    def by_kind(key: str, kind: Quantity, fallback: ByKind | None) -> ByKind | None:
        if key not in spec:
            return fallback
        found = _by_kind(kind, spec[key], fallback)
        for problem in found[1]:
            problems.append(((key, *problem.path), problem.message))
        return found[0] if not found[1] else fallback

    static = by_kind("static_velocity", VELOCITY, default.static_velocity)
    bias = by_kind("bias", BIAS, default.bias)
    spike: dict[str, Any] = spec.get("spike") or {}
    jerk: ByKind | None = None
    if "jerk" in spike:
        found = _by_kind(JERK, spike["jerk"], None)
        problems.extend((("spike", "jerk", *p.path), p.message) for p in found[1])
        jerk = found[0] if not found[1] else None
    factor = _factor(spike.get("factor", default.spike_factor), ("spike", "factor"), "the spike factor", problems)
    iqr = _factor(spec.get("length_outlier", default.length_iqr), ("length_outlier",), "the IQR factor", problems)
    gap_seconds, gap_steps = default.gap_seconds, default.gap_steps
    if "gap" in spec:
        gap_problems: list[SlackProblem] = []
        part = quantity_part(GAP, spec["gap"], (), None, gap_problems, lambda v: _no_unit(GAP, spec["gap"], v))
        problems.extend((("gap",), p.message) for p in gap_problems)
        if part is not None:
            gap_seconds, gap_steps = (part[0], default.gap_steps) if part[1] != "steps" else (None, part[0])
    fail_on = _fail_on(spec.get("fail_on", []), problems)
    for path, message in problems:
        ctx.problems.add(message, ctx.where("qa", *path))
    assert static is not None and bias is not None
    return QaPlan(static, default.static_share, factor, jerk, gap_seconds, gap_steps, iqr, bias, fail_on)


def _by_kind(kind: Quantity, written: Any, fallback: ByKind | None) -> tuple[ByKind | None, list[SlackProblem]]:
    """NUMBER UNIT (its unit's kind set, the other kept from `fallback`, else unbounded) or {angle: ..., length: ...}."""
    problems: list[SlackProblem] = []
    base = fallback or ByKind(math.inf, math.inf, "")
    if isinstance(written, dict):
        values = {True: base.angle, False: base.length}
        for key, angular in (("angle", True), ("length", False)):
            if key in written:
                item = written[key]
                part = quantity_part(kind, item, (key,), angular, problems, partial(_no_unit, kind, item, angular=angular))
                if part is not None:
                    values[angular] = part[0]
        text = "{" + ", ".join(f"{k}: {written[k]}" for k in ("angle", "length") if k in written) + "}"
        return ByKind(values[True], values[False], text), problems
    part = quantity_part(kind, written, (), None, problems, lambda v: _no_unit(kind, written, v))
    if part is None:
        return None, problems
    angular = part[1] in kind.units[True]
    text = f"{number_text(float(part[0] / kind.factors()[part[1]]))} {part[1]}"
    return (ByKind(part[0], base.length, text) if angular else ByKind(base.angle, part[0], text)), problems


def _no_unit(kind: Quantity, written: Any, value: float, *, angular: bool | None = None) -> str:
    """The fix for a bare number: the same number with the unit it most likely meant."""
    examples = [kind.example[angular]] if angular is not None else [kind.example[True], kind.example[False]]
    fixes = " or ".join(f"{number_text(value)} {e.split()[-1]}" for e in examples)
    return f"{kind.name} {shown(written, 60)} has no unit: write it with one, e.g. {fixes} (units {kind.unit_list()})"


def _factor(written: Any, path: tuple[str, ...], what: str, problems: list[tuple[tuple[str | int, ...], str]]) -> float:
    """A plain factor (no unit: it multiplies a spread of the dataset's own); the schema made it a finite number."""
    value = float(written)
    if value < 0:
        problems.append((path, f"{what} {shown(written, 60)} is negative; it multiplies a spread of the dataset's own, 0 or more"))
        return 0.0
    return value


def _fail_on(written: list[Any], problems: list[tuple[tuple[str | int, ...], str]]) -> tuple[QaFlag, ...]:
    """The flags that fail `qa`, each from QA_FLAGS (in the order written, once each)."""
    flags: list[QaFlag] = []
    for index, name in enumerate(written):
        if name not in QA_FLAGS:
            problems.append(
                (("fail_on", index), f"unknown flag {quoted(name)}{did_you_mean(str(name), QA_FLAGS)}; flags are {listing(QA_FLAGS)}")
            )
        elif name not in flags:
            flags.append(cast(QaFlag, name))
    return tuple(flags)
