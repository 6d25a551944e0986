"""The end-of-run summary: one line per segment (segment, frames, seconds, status, reason), then the totals."""

from __future__ import annotations

import dataclasses
import json
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import UserError
from ..execute import SegmentResult

if TYPE_CHECKING:
    from ..plan import Plan
    from .run import DatasetRun, RunOptions


def summary_table(results: tuple[SegmentResult, ...]) -> str:
    width = max([len("segment"), *(len(r.label) for r in results)])
    lines = [f"{'segment':<{width}}  {'frames':>9}  {'seconds':>8}  {'status':<11}  reason"]
    for r in results:
        reason = r.reason.strip().splitlines()[-1] if r.status == "bug" and r.reason else " | ".join(r.reason.strip().splitlines())
        lines.append(f"{r.label:<{width}}  {r.frames:>9,}  {r.seconds:>8.2f}  {r.status:<11}  {reason}".rstrip())
    return "\n".join(lines)


def totals_line(results: tuple[SegmentResult, ...], seconds: float) -> str:
    counts = Counter(r.status for r in results)
    frames = sum(r.frames for r in results)
    parts = ", ".join(f"{counts[s]} {s}" for s in ("written", "skipped", "failed", "bug", "interrupted") if counts[s])
    rate = f", {frames / seconds:,.0f} frames/s" if seconds > 0 and frames else ""
    return f"{len(results)} outputs: {parts}; {frames:,} frames in {seconds:.1f} s{rate}"


def write_report(path: Path, plan: Plan, run: DatasetRun, options: RunOptions) -> None:
    """`run --report FILE.json`: what the run did, segment by segment, for CI dashboards and benchmarks."""
    report = {
        "config": str(plan.config_path),
        "layout": plan.dataset.layout if plan.dataset else "single",
        "jobs": options.jobs,
        "executor": options.executor,
        "seconds": run.seconds,
        "interrupted": run.interrupted,
        "results": [{**dataclasses.asdict(r), "output": str(r.output)} for r in run.results],
    }
    try:
        path.write_text(json.dumps(report, indent=1) + "\n", encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write the run report {path}: {exc}") from None
