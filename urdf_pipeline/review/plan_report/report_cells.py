"""The joint table's cells that Markdown and HTML share: what a cell says is decided once, here; each renderer gives
its own markup (`Markup`) for names, free text, verdicts and counts."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

from .report_model import JointRow, Observed, number, rounded

DASH = "—"


@dataclass(frozen=True)
class Markup:
    """How one renderer marks up the parts of a cell."""

    code: Callable[[object], str]  # a name from input (a joint), inert in this format
    text: Callable[[object], str]  # free text from input (the slack as written)
    literal: Callable[[str], str]  # an expression of ours shown as code (`hold = 0.5`)
    bad: Callable[[str], str]  # a verdict to see first
    good: Callable[[str], str]
    count: Callable[[int], str]


def _numbers(values: Sequence[float]) -> str:
    return ", ".join(number(v) for v in values)


def map_cell(row: JointRow) -> str:
    """The value conversion beyond unit, sign and offset: wrap, source_range, scale."""
    parts = []
    if row.wrap is not None:
        parts.append(f"wrap {number(row.wrap.period)} around {number(row.wrap.center)}")
    if row.source_range is not None:
        parts.append(f"source_range [{_numbers(row.source_range)}] → [{_numbers(row.target_range or ())}]")
    elif row.scale is not None and rounded(row.scale) != 1:
        parts.append(f"× {number(row.scale)}")
    return "; ".join(parts) or DASH


def limits_cell(row: JointRow, markup: Markup) -> str:
    if row.kind != "mapped":
        return DASH
    if row.limits_source_units is None:
        return "none"
    low, high = row.limits_source_units
    return f"{number(low)} .. {number(high)}" + (f" ± {markup.text(row.slack_text)}" if row.slack_text != "0" else "")


def driver_cell(row: JointRow, markup: Markup) -> str:
    if row.kind == "held" and row.hold is not None:
        return markup.literal(f"hold = {number(row.hold)}")
    if row.kind == "mimic" and row.mimic is not None:
        return f"{markup.code(row.mimic.driver)} × {number(row.mimic.multiplier)} + {number(row.mimic.offset)}"
    return DASH


def observed_cell(observed: Observed | None, markup: Markup) -> str:
    """The sampled range and whether it fits the limits (`plan --sample`)."""
    if observed is None:
        return DASH
    if observed.min is None or observed.max is None:
        return f"no finite values in {markup.count(observed.rows)} rows"
    if observed.verdict == "no limits":
        status = "no limits"
    elif not observed.fits:
        status = markup.bad("outside the limits")
    elif observed.slack_rows:
        status = f"fits; {markup.count(observed.slack_rows)} rows within the slack"
    else:
        status = markup.good("fits")
    return f"{number(observed.min)} .. {number(observed.max)} ({status})"
