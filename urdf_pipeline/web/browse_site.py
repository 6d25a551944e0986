"""`urdf-pipeline browse CONFIG -o DIR`: a dataset browser over a config's written outputs, as a static site (docs/web.md;
what it trusts of a manifest, which anyone may have written: docs/security.md).

It reads the run's manifest only (`dataset.segment_summaries`), never a recording. The rows are `segments.json`, which
`browse.js` pages (10,000 segments stay fast); a segment opens in an iframe of the site's viewer whose fragment changes,
so the wasm is loaded once. A segment without a `--base` recording gets a row note, not an error as in `run --base`:
`run` refuses to write a layer that would never attach; `browse` shows what exists.
"""

from __future__ import annotations

import json
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..confine import confinement_for
from ..errors import UserError, shown
from .browse_rows import BrowseSegment, segments_json
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
