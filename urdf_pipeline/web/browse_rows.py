"""The rows of the dataset browser (`browse`): one JSON-ready mapping per segment, from the manifest's typed entries.

Everything here comes from the manifest, which anyone may have edited: every string is shown bounded
(`errors.shown`) and stays data in `segments.json`; `browse.js` puts it in the page with `textContent` and
`setAttribute` only. A row is small (about 0.4 KB): the sparkline keeps at most `SPARK_JOINTS` joints of
`SPARK_BUCKETS` buckets, its joint names interned in one table, so 10,000 segments are a few MB of JSON.
"""

from __future__ import annotations

import base64
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import shown
from ..execute import JointPreview, SegmentSummary, TimeRange

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
            for d in summary.differences
        ]
    return entry


def time_text(timelines: Sequence[TimeRange], frames: int | None) -> tuple[float | None, str]:
    """The segment's duration in seconds (None without a time timeline) and its time range as text: ISO dates for a
    timestamp timeline, seconds for a duration one, the index range for a sequence (LeRobot's `frame_index`: the
    plan knows no frame rate, so frames it is)."""
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
