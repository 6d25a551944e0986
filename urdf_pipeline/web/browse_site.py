"""`urdf-pipeline browse CONFIG -o DIR`: a dataset browser over a config's written outputs, as a static site (docs/web.md;
what it trusts of a manifest, which anyone may have written: docs/security.md).

It reads the run's manifest only (`dataset.segment_summaries`), never a recording. The rows are `segments.json`, which
`browse.js` pages (10,000 segments stay fast); a segment opens in an iframe of the site's viewer whose fragment changes,
so the wasm is loaded once. A segment without a `--base` recording gets a row note, not an error as in `run --base`:
`run` refuses to write a layer that would never attach; `browse` shows what exists.

Every string of a row is the manifest's, shown bounded (`errors.shown`), and stays data in `segments.json`: `browse.js`
puts it in the page with `textContent` and `setAttribute` only. A row is about 0.4 KB (a sparkline of at most
`SPARK_JOINTS` joints of `SPARK_BUCKETS` buckets, its names interned in one table).
"""

from __future__ import annotations

import base64
import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..confine import confinement_for
from ..errors import UserError, shown
from ..execute import JointDifferences, JointPreview, SegmentSummary, TimeRange
from .page_html import html_text, viewer_href
from .site_writer import SiteWriter, write_site

if TYPE_CHECKING:
    from ..dataset import BaseRecording, SegmentEntry
    from ..plan import Plan

DATA = "segments.json"
SCRIPT = "browse.js"
ASSETS = "recordings/shared"  # the model and the blueprint: under a folder no segment's file name can take
PAGE_ROWS = 50


@dataclass(frozen=True)
class BrowseResult:
    """What `browse` wrote: for its summary line."""

    site: Path
    segments: int
    missing: int
    seconds: float
    data_bytes: int


@dataclass(frozen=True)
class Shared:
    """The files every segment opens with its own: the split layout's model, the run's blueprint (when written)."""

    model: Path | None
    blueprint: Path | None


def browse_config(plan: Plan, target: Path, config_text: str, base: str | None = None) -> BrowseResult:
    """The browser of `plan`'s written outputs at `target`; a UserError naming the fix when the run never happened.
    `base`: `--base DIR_OR_GLOB`, the base recordings segments open with (read before anything is written)."""
    from ..dataset import base_files, bucket_state, fetch_manifest, local_outputs, run_output, segment_summaries
    from ..execute import blueprint_path

    state = None
    if plan.dataset.remote is not None:
        state = bucket_state(plan, plan.dataset.remote)  # one listing of the outputs' prefix
        fetch_manifest(plan, plan.dataset.remote, state)  # the bucket's, as the last run left it
    manifest = plan.dataset.manifest
    if not manifest.is_file():
        raise UserError(
            f"no manifest at {shown(manifest)}: the config's outputs were never written; run `urdf-pipeline run {config_text}` first",
            plan.output_where,
        )
    found = base_files(base) if base is not None else None
    entries = segment_summaries(plan)
    if state is not None:  # outputs in S3: each recording fetched (the version the manifest recorded)
        with local_outputs(plan, entries, state) as (fetched, model, blueprint):
            rows, bases = _rows(plan, fetched, config_text, found)
            return build_browser(target, plan.application_id, rows, Shared(model, blueprint), bases)
    rows, bases = _rows(plan, entries, config_text, found)
    model = plan.dataset.model if plan.dataset.layout == "split" and plan.dataset.model is not None else None
    confinement = confinement_for(plan.config_path)  # the model and blueprint as the manifest's entries: the run's own files
    shared = Shared(
        run_output(model, "recording", "the model", plan.output_where, confinement) if model is not None else None,
        run_output(blueprint_path(plan), "blueprint", "the blueprint", plan.output_where, confinement),
    )
    return build_browser(target, plan.application_id, rows, shared, bases)


def _rows(
    plan: Plan, entries: Sequence[SegmentEntry], config_text: str, found: Mapping[str, Sequence[BaseRecording]] | None
) -> tuple[list[tuple[BrowseSegment, Path | None]], dict[str, tuple[Path, ...]]]:
    """A row per written segment and per segment of the plan not written; with `--base`, each row's base files."""
    written = {entry.segment: entry for entry in entries}
    rows: list[tuple[BrowseSegment, Path | None]] = []
    for entry in written.values():
        missing = "" if entry.summary is not None else "no summary in the manifest (written by an older run: `run --force` adds it)"
        rows.append((BrowseSegment(entry.segment, entry.frames, entry.summary, missing=missing), entry.path))
    for segment in plan.segments:
        if segment.id not in written:
            missing = f"no written file ({segment.output.name} is missing): `urdf-pipeline run {config_text}` writes it"
            rows.append((BrowseSegment(segment.id, segment.frames, None, missing=missing), None))
    rows.sort(key=lambda pair: pair[0].segment)
    bases: dict[str, tuple[Path, ...]] = {}
    if found is not None:
        rows = [(_with_base_note(row, found, plan.application_id), path) for row, path in rows]
        bases = {row.segment: tuple(f.path for f in found.get(row.segment, ())) for row, _ in rows}
    return rows, bases


def _with_base_note(row: BrowseSegment, found: Mapping[str, Sequence[BaseRecording]], application_id: str) -> BrowseSegment:
    """The row with what its base lacks added to its note: no base recording of its id, or one of another
    application (opened all the same: the viewer shows the two apart)."""
    files = found.get(row.segment, ())
    others = sorted({f.application_id for f in files if f.application_id != application_id})
    note = (
        "no base recording (none in --base has this segment's id as its recording_id)"
        if not files
        else f"the base recording's application_id is {shown(others[0], 80)!r}, not {shown(application_id, 80)!r}: the viewer shows them apart"
        if others
        else ""
    )
    if not note:
        return row
    return BrowseSegment(row.segment, row.frames, row.summary, row.recordings, "; ".join(filter(None, (row.missing, note))))


def build_browser(
    target: Path,
    title: str,
    rows: Sequence[tuple[BrowseSegment, Path | None]],
    shared: Shared,
    bases: Mapping[str, Sequence[Path]] | None = None,
) -> BrowseResult:
    """The site: recordings linked in, `segments.json`, `browse.js` and `index.html`. `rows` pair each segment with
    its recording (None: nothing to open); `bases`: per segment id, the base files it opens with (each put into the
    site once, under a made name: base files are often named as the segments' own)."""
    started = time.perf_counter()
    with write_site(target) as site:
        opened = [
            site.add_file(path, f"{ASSETS}/{name}")
            for path, name in ((shared.model, "model.rrd"), (shared.blueprint, "blueprint.rbl"))
            if path
        ]
        model = opened[0] if shared.model is not None else None
        rest = opened[1:] if model is not None else opened
        placed_bases: dict[Path, str] = {}
        placed = []
        for number, (row, path) in enumerate(rows):
            base = tuple(_placed_base(site, file, placed_bases) for file in (bases or {}).get(row.segment, ())) if path else ()
            # a name of the site's choosing, never the manifest's: a static host serves it as a recording, never as a
            # page or a script of the site's origin
            recordings = (*base, site.add_recording(path, f"{number:06d}.rrd"), *rest) if path else ()
            placed.append(BrowseSegment(row.segment, row.frames, row.summary, recordings, row.missing, base))
        hrefs = [viewer_href("index.html", row.recordings, model, row.segment) if row.recordings else None for row in placed]
        data = json.dumps(segments_json(title, placed, hrefs), ensure_ascii=False, separators=(",", ":"))
        site.write_text(DATA, data)
        site.write_text(SCRIPT, _static(SCRIPT))
        site.write_page("index.html", f"dataset {title}", _body(title, placed), scripts=[SCRIPT])
    missing = sum(1 for row in placed if row.missing)
    return BrowseResult(target, len(placed), missing, time.perf_counter() - started, len(data.encode("utf-8")))


def _placed_base(site: SiteWriter, file: Path, placed: dict[Path, str]) -> str:
    """The base file's site path, put into the site the first time a segment asks for it (`base_N.rrd` beside the
    shared model: no segment's file name can take it, and the base's own name never reaches a link)."""
    if file not in placed:
        placed[file] = site.add_file(file, f"{ASSETS}/base_{len(placed):06d}.rrd")
    return placed[file]


def _body(title: str, rows: Sequence[BrowseSegment]) -> str:
    """The page's skeleton; browse.js fills the table from segments.json (no row is in the HTML: 10,000 would be MBs)."""
    missing = sum(1 for row in rows if row.missing)
    counts = f"{len(rows)} segments" + (f", {missing} with something missing" if missing else "")
    return f"""<div class="browse" id="browse" data-src="{DATA}" data-page-rows="{PAGE_ROWS}">
<section class="browse-list">
<h1>Dataset {html_text(title)}</h1>
<p class="muted" id="counts">{html_text(counts)}</p>
<p class="browse-controls"><input id="search" type="search" placeholder="search by id, robot or note" aria-label="search segments">
<button id="previous" type="button">previous</button> <span id="page-info" class="muted"></span> <button id="next" type="button">next</button></p>
<p id="status" class="muted">Loading the segments… (this page needs JavaScript)</p>
<table id="segments"><thead><tr><th>segment</th><th class="number">frames</th><th class="number">seconds</th><th>time range</th><th>robots</th><th>preview</th><th>notes</th></tr></thead>
<tbody></tbody></table>
</section>
<section class="browse-viewer"><p id="viewer-hint" class="muted">Click a segment to open it in Rerun's viewer here.</p><iframe id="viewer" title="Rerun viewer" hidden></iframe></section>
</div>"""


def _static(name: str) -> str:
    from importlib.resources import files

    return (files(__package__) / "static" / name).read_text(encoding="utf-8")


FORMAT = 1
SPARK_JOINTS = 6  # joints drawn in a row's sparkline, the most moving first (the summary's order), robots in turn
SPARK_BUCKETS = 16  # buckets of a sparkline: the summary's 32 merged in pairs
ID_LIMIT = 200  # characters of a segment id shown


@dataclass(frozen=True)
class BrowseSegment:
    """One row of the browser: a segment as the manifest lists it (or as the plan names it when nothing is written)."""

    segment: str
    frames: int | None
    summary: SegmentSummary | None
    recordings: tuple[str, ...] = ()  # site paths the viewer opens for it (empty: nothing to open)
    missing: str = ""  # what is missing, said to the reader ("" when the segment is whole)
    base: tuple[str, ...] = ()  # site paths of the base recordings it opens with (`browse --base`), in `recordings` too


class NameTable:
    """Joint and robot names interned: a row holds their positions in `names`, not the names themselves."""

    def __init__(self) -> None:
        self.names: list[str] = []
        self._index: dict[str, int] = {}

    def __call__(self, name: str) -> int:
        found = self._index.get(name)
        if found is None:
            found = self._index[name] = len(self.names)
            self.names.append(name)
        return found


def segments_json(title: str, rows: Sequence[BrowseSegment], viewer_hrefs: Sequence[str | None]) -> dict[str, Any]:
    """`segments.json`: the title, the interned names, and per segment its row (`viewer_hrefs` line up with `rows`:
    the link from index.html that opens it in the viewer, None when there is nothing to open)."""
    names = NameTable()
    return {
        "format": FORMAT,
        "title": shown(title, ID_LIMIT),
        "segments": [_row(row, href, names) for row, href in zip(rows, viewer_hrefs, strict=True)],
        "names": names.names,
    }


def _row(row: BrowseSegment, href: str | None, names: NameTable) -> dict[str, Any]:
    summary = row.summary
    entry: dict[str, Any] = {"id": shown(row.segment, ID_LIMIT), "frames": row.frames}
    if row.missing:
        entry["missing"] = row.missing
    if href is not None:
        entry["href"] = href
    if row.base:
        entry["base"] = list(row.base)
    if summary is None:
        return entry
    seconds, when = time_text(summary.timelines, row.frames)
    entry.update(seconds=seconds, time=when, robots=list(summary.robots), notes=list(summary.notes))
    if summary.notes_left_out:
        entry["left"] = summary.notes_left_out
    spark = sparkline(summary.previews, names)
    if spark is not None:
        entry["spark"] = spark
    if summary.differences:  # compare: each copy against its measured robot; the names as read back, bounded
        entry["diff"] = [
            {"copy": d.copy, "measured": d.measured, "rows": d.rows, "beyond": d.rows_beyond, "joints": list(d.joints_beyond)}
            | ({"bias": bias} if (bias := _bias_texts(d)) else {})
            for d in summary.differences
        ]
    return entry


def _bias_texts(d: JointDifferences) -> list[str]:
    """compare: each joint whose calibration bias is beyond qa.bias, with its mean in the threshold's unit."""
    return [f"{joint} {d.unit_text(i, d.bias_mean[i])}" for i, joint in enumerate(d.joints) if i < len(d.biased) and d.biased[i]]


def time_text(timelines: Sequence[TimeRange], frames: int | None) -> tuple[float | None, str]:
    """The segment's duration in seconds (None without a time timeline) and its time range as text: ISO dates for a
    timestamp timeline, seconds for a duration one (LeRobot's `time`), the index range for a sequence alone."""
    timed = [t for t in timelines if t.kind != "sequence"]
    if timed:
        first = next((t for t in timed if t.kind == "timestamp"), timed[0])
        if first.kind == "timestamp":
            return first.seconds, f"{first.first_iso} → {first.last_iso}"
        return first.seconds, f"{first.first / 1e9:.3f} s → {first.last / 1e9:.3f} s on {first.timeline}"
    if timelines:
        sequence = timelines[0]
        return None, f"{sequence.first} → {sequence.last} on {sequence.timeline}"
    return None, "" if frames is None else f"{frames} frames"


def sparkline(previews: Sequence[JointPreview], names: NameTable) -> dict[str, Any] | None:
    """The preview cut to at most SPARK_JOINTS joints of at most SPARK_BUCKETS buckets: `b` buckets, per joint its
    robot and name (interned, `r` and `j`) and whether its scale is its limits (`l`), `c` the codes as base64 (per
    joint its min codes then its max codes, as in the manifest; an empty bucket is 255, 0)."""
    chosen: list[tuple[JointPreview, int]] = []
    depth = 0
    while len(chosen) < SPARK_JOINTS and any(depth < len(p.joints) for p in previews):
        chosen.extend((p, depth) for p in previews if depth < len(p.joints))  # robots in turn, most moving first
        depth += 1
    chosen = chosen[:SPARK_JOINTS]
    if not chosen:
        return None
    buckets = min(p.buckets for p, _ in chosen)
    target = min(buckets, SPARK_BUCKETS)
    codes = [_merged(p, j, target) for p, j in chosen]
    return {
        "b": target,
        "r": [names(p.robot) for p, _ in chosen],
        "j": [names(p.joints[j]) for p, j in chosen],
        "l": [int(p.limited[j]) for p, j in chosen],
        "c": base64.b64encode(b"".join(codes)).decode("ascii"),
    }


def _merged(preview: JointPreview, joint: int, target: int) -> bytes:
    """The joint's min and max codes over `target` buckets: runs of the preview's buckets merged (min of the mins,
    max of the maxes), so an empty bucket merged with a full one is full and two empty ones stay empty."""
    minima, maxima = (np.frombuffer(codes, dtype=np.uint8) for codes in preview.codes_of(joint))
    starts = (np.arange(target) * preview.buckets) // target
    return np.minimum.reduceat(minima, starts).tobytes() + np.maximum.reduceat(maxima, starts).tobytes()
