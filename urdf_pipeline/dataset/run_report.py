"""The end-of-run summary: one row per segment (segment, frames, seconds, status, reason; one line per problem of a
failed segment), then the totals."""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from collections import Counter
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..confine import file_state
from ..errors import UserError, neutral_line, shown
from ..execute import SegmentResult
from ..remote import is_remote, parse_url, upload

if TYPE_CHECKING:
    from ..plan import Plan
    from .run import DatasetRun, RunOptions


def _problems(result: SegmentResult) -> list[str]:
    """The reason's lines, one problem each (a bug: its traceback's last line), each neutral: a segment id or message
    made from a file name shows no control character and forges no workflow command."""
    lines = [line for line in result.reason.strip().split("\n") if line.strip()]
    return [neutral_line(line.strip()) for line in (lines[-1:] if result.status == "bug" else lines)]


def summary_table(results: tuple[SegmentResult, ...]) -> str:
    """One row per segment; a segment that failed for several problems has one line per problem, the first on its
    row, the others under it in the reason column."""
    labels = [shown(r.label) for r in results]
    width = max([len("segment"), *(len(label) for label in labels)])
    lines = [f"{'segment':<{width}}  {'frames':>9}  {'seconds':>8}  {'status':<11}  reason"]
    indent = " " * (width + 2 + 9 + 2 + 8 + 2 + 11 + 2)
    for r, label in zip(results, labels, strict=True):
        first, *more = _problems(r) or [""]
        lines.append(neutral_line(f"{label:<{width}}  {r.frames:>9,}  {r.seconds:>8.2f}  {r.status:<11}  {first}".rstrip()))
        lines += [indent + problem for problem in more]
    return "\n".join(lines)


def differences_lines(results: tuple[SegmentResult, ...]) -> list[str]:
    """`compare:`: one line per segment and compared pair, naming the joints beyond the threshold (largest difference
    in the threshold's unit, and the rows beyond), or saying the copy kept within it; then each joint whose calibration
    bias (mean of copy - measured while both are still) is beyond `qa.bias`."""
    lines = []
    for result in results:
        for d in result.summary.differences if result.summary is not None else ():
            head = f"{shown(result.label)}: '{d.copy}' against '{d.measured}' over {d.rows:,} rows"
            unmatched = f"; {d.unmatched:,} rows of one robot had no row of the other" if d.unmatched else ""
            unmatched += "".join(
                f"; calibration bias {shown(d.joints[i])} {d.unit_text(i, d.bias_mean[i])}"
                f" (std {d.unit_text(i, d.bias_std[i])}, {d.bias_rows[i]:,} still rows)"
                for i, flagged in enumerate(d.biased)
                if flagged
            )
            if not d.rows_beyond:
                lines.append(neutral_line(f"{head}: within {d.threshold}{unmatched}"))
                continue
            joints = ", ".join(
                f"{shown(joint)} (max {d.largest_text(i)}, {rows:,} rows)"
                for i, (joint, rows) in enumerate(zip(d.joints, d.beyond, strict=True))
                if rows
            )
            lines.append(neutral_line(f"{head}: {d.rows_beyond:,} rows beyond {d.threshold}: {joints}{unmatched}"))
    return lines


_TOTALS: dict[str, str] = {"written": "written", "skipped": "up to date", "failed": "failed", "bug": "bug", "interrupted": "not done"}


def totals_line(results: tuple[SegmentResult, ...], seconds: float) -> str:
    """The counts by status, in words a reader needs no table for: "written" is only what this run wrote."""
    counts: Counter[str] = Counter(r.status for r in results)
    frames = sum(r.frames for r in results if r.status == "written")
    parts = ", ".join(f"{counts[status]} {words}" for status, words in _TOTALS.items() if counts[status])
    rate = f", {frames / seconds:,.0f} frames/s" if seconds > 0 and frames else ""
    return f"{len(results)} outputs: {parts}; {frames:,} frames written in {seconds:.1f} s{rate}"


def stopped_line(run: DatasetRun, names: int = 5) -> str:
    """After Ctrl-C or SIGTERM: what this run wrote, what was up to date, what failed, and what is not done (the first
    `names` of them named), and how to finish."""
    from ..process import signal_name

    counts: Counter[str] = Counter(r.status for r in run.results)
    kept = f" ({run.not_rewritten} of them not rewritten as --force asked)" if run.not_rewritten else ""
    said = [f"{counts['written']} written in this run", f"{counts['skipped']} up to date from an earlier run{kept}"]
    said += [f"{counts[status]} {_TOTALS[status]}" for status in ("failed", "bug") if counts[status]]
    not_done = [shown(r.label) for r in run.results if r.status == "interrupted"]
    named = ", ".join(not_done[:names]) + (f" and {len(not_done) - names} more" if len(not_done) > names else "")
    said.append(f"{len(not_done)} not done ({named}: the same command again does them)" if not_done else "0 not done")
    return neutral_line(f"interrupted ({signal_name(run.signal)}): {', '.join(said)}; only complete outputs were kept")


def _result(result: SegmentResult, run: DatasetRun) -> dict[str, Any]:
    """A segment's result as JSON: its summary in the manifest's form (its preview's codes in base64); an output in
    S3 by its URL."""
    summary = result.summary.as_json() if result.summary is not None else None
    output = run.remote.url_of(result.output) if run.remote is not None else str(result.output)
    return {**dataclasses.asdict(result), "output": output, "summary": summary}


def report_target(text: str) -> str:
    """`--report`'s target, checked before the run: a local path, or an `s3://` URL (the runner's own argument, not a
    config's: the allow rule for a config's URLs does not apply, its scheme and form do)."""
    if is_remote(text):
        parse_url(text, None, "--report")
        return text
    target = Path(text)
    if file_state(target, "--report:", None, "written") == "folder":
        raise UserError(f"--report: {text} is a folder; name a file such as {Path(text) / 'report.json'}")
    if file_state(target.parent, "--report:", None, "written") != "folder" or not os.access(target.parent, os.W_OK | os.X_OK):
        raise UserError(f"--report: cannot write {text}: {target.parent} is not a folder this process can write to")
    return text


def write_report(target: str, plan: Plan, run: DatasetRun, options: RunOptions) -> None:
    """`run --report FILE.json` (or `s3://BUCKET/KEY.json`): what the run did, segment by segment, for CI dashboards
    and benchmarks."""
    report = {
        "config": str(plan.config_path),
        "layout": plan.dataset.layout if plan.dataset else "single",
        "jobs": options.jobs,
        "executor": options.executor,
        "seconds": run.seconds,
        "interrupted": run.interrupted,
        "results": [_result(r, run) for r in run.results],
    }
    text = json.dumps(report, indent=1) + "\n"
    if is_remote(target):
        with tempfile.TemporaryDirectory(prefix="urdf-pipeline-report-") as folder:
            local = Path(folder) / "report.json"
            local.write_text(text, encoding="utf-8")
            upload(local, parse_url(target, None, "--report"), None)
        return
    try:
        Path(target).write_text(text, encoding="utf-8")
    except OSError as exc:
        raise UserError(f"cannot write the run report {target}: {exc}") from None
