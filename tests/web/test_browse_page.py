"""`browse`'s site (the SO-101 dataset in the split layout, its first episode with a base recording) in headless
chromium, from the session's `urdf-pipeline serve`: the list, its search and pages, and segments opening in the viewer
pane beside it.

One page load is shared by the tests of this module (the wasm compiles on the CPU), in order: the list renders two
rows a page (`#n=2`), page 2 and a search work, the first segment opens in the viewer pane and the robot shows (its
meshes are the model asset's, added to the layer's recording by boot.js) in ONE recording with its base, then a second
segment opens in the same running viewer. The last tests read the page's console and requests, then give the viewer
an asset that is no .rrd.
"""

from __future__ import annotations

import base64
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from urdf_pipeline import cli
from urdf_pipeline.web import ViewerAssets

from .canvas import ROBOT_SECONDS, ROBOT_SHARE, drawn_share
from .conftest import Served
from .devtools import Browser, Page, site_paths
from .test_browse_site import base_recording, run_variant

PREFIX = "sites/browse"
BASE_TIMELINE = "base_tick"  # the base recording's own timeline: in the viewer's state of the segment's recording
ROWS = "Array.from(document.querySelectorAll('#segments tbody tr')).map(r => r.dataset.id)"
FRAME_STATE = "(() => { const f = document.getElementById('viewer'); return f.contentDocument && f.contentDocument.body && f.contentDocument.body.dataset.state; })()"


@dataclass
class BrowsePage:
    page: Page
    ids: list[str]


@pytest.fixture(scope="module")
def browse_page(
    browser: Browser, served: Served, viewer_cache: ViewerAssets, examples_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[BrowsePage]:
    config = run_variant(examples_dir, "so101_browse_page")
    ids = sorted(p.stem for p in (examples_dir / "out" / "so101_browse_page").glob("episode_*.rrd"))
    base = tmp_path_factory.mktemp("browse-base")
    base_recording(base / "first.rrd", ids[0], timeline=BASE_TIMELINE)
    assert cli.main(["browse", str(config), "-o", str(served.root / PREFIX), "--base", str(base), "-q"]) == 0
    assert len(ids) >= 3
    page = browser.page(1600, 900)
    try:
        page.navigate(f"{served.url}{PREFIX}/index.html#n=2")
        page.wait_for(lambda: page.evaluate("document.getElementById('browse').dataset.state") == "ready", 30, "segments.json")
        yield BrowsePage(page, ids)
    finally:
        page.close()


def frame_share(page: Page) -> float:
    """The robot's share of the viewer pane's centre (a screenshot of the iframe's box only)."""
    box = page.evaluate(
        "(() => { const r = document.getElementById('viewer').getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()"
    )
    clip = {"x": box[0], "y": box[1], "width": box[2], "height": box[3], "scale": 1}
    png = base64.b64decode(page.call("Page.captureScreenshot", {"format": "png", "clip": clip})["data"])
    return drawn_share(png) if page.evaluate(FRAME_STATE) == "started" else 0.0


def test_the_list_shows_a_page_of_rows_with_sparklines(browse_page: BrowsePage) -> None:
    page = browse_page.page
    assert page.evaluate(ROWS) == browse_page.ids[:2]
    assert page.evaluate("document.querySelectorAll('#segments svg.spark polygon').length") >= 2
    assert "so101" in page.evaluate("document.querySelector('#segments svg.spark title').textContent")
    assert page.evaluate("document.getElementById('page-info').textContent").startswith("page 1 of ")


def test_page_two_and_search(browse_page: BrowsePage) -> None:
    page = browse_page.page
    page.evaluate("document.getElementById('next').click()")
    assert page.evaluate(ROWS) == browse_page.ids[2:4]
    assert "p=2" in page.evaluate("location.hash")
    wanted = browse_page.ids[-1]
    page.evaluate(
        f"(() => {{ const s = document.getElementById('search'); s.value = {wanted[-3:]!r}; s.dispatchEvent(new Event('input')); }})()"
    )
    page.wait_for(lambda: page.evaluate(ROWS) == [wanted], 10, "the search's one row")
    assert f"q={wanted[-3:]}" in page.evaluate("location.hash")
    page.evaluate("(() => { const s = document.getElementById('search'); s.value = ''; s.dispatchEvent(new Event('input')); })()")
    page.wait_for(lambda: page.evaluate(ROWS) == browse_page.ids[:2], 10, "the first page again")


def test_a_segment_opens_in_the_viewer_pane_and_a_second_one_after_it(browse_page: BrowsePage) -> None:
    page = browse_page.page
    started = time.monotonic()
    page.evaluate("document.querySelector('#segments tbody tr a').click()")
    share = page.wait_for(lambda: (s := frame_share(page)) >= ROBOT_SHARE and s, ROBOT_SECONDS, "the robot in the viewer pane")
    print(f"first robot pixels {time.monotonic() - started:.1f} s after the click; {share:.0%} of the pane's centre")
    first, second = browse_page.ids[:2]
    assert page.evaluate("document.querySelector('#segments tr.selected').dataset.id") == first
    state = page.viewer_state()  # one recording: the layer, its base and the model asset under the segment's id
    assert b"recording_id=" + first.encode() in state and b"urdf_model" not in state
    assert BASE_TIMELINE.encode() in state and b"frame_index" in state
    page.evaluate("document.querySelectorAll('#segments tbody tr a')[1].click()")
    # the second row's recording, under the name the site chose for it (its row's number)
    page.wait_for(lambda: [r for r in page.requests() if r.url.endswith("/recordings/000001.rrd") and r.status == 200], 60, second)
    assert page.evaluate("document.querySelector('#segments tr.selected').dataset.id") == second
    assert second in page.evaluate("document.getElementById('viewer').contentWindow.location.hash")
    assert len([r for r in page.requests() if r.url.endswith("/re_viewer_bg.wasm")]) == 1  # the viewer kept running
    assert len([r for r in page.requests() if r.url.endswith("/recordings/shared/model.rrd")]) == 1  # the model: fetched once
    assert page.wait_for(lambda: frame_share(page) >= ROBOT_SHARE, 60, "the robot after the switch")
    state = page.viewer_state()
    assert b"recording_id=" + second.encode() in state and b"urdf_model" not in state


def test_the_page_logs_no_error_and_asks_only_this_machine(browse_page: BrowsePage) -> None:
    page = browse_page.page
    assert page.console_errors() == []
    site_paths(page.requests(), PREFIX)


def test_an_asset_that_is_no_rrd_is_said_on_the_page(browse_page: BrowsePage) -> None:
    """Last (it logs an error): an `asset` the viewer page cannot read is named in its status and console."""
    page = browse_page.page
    page.evaluate("document.getElementById('viewer').contentWindow.location.hash = '#asset=../index.html&into=x'")
    page.wait_for(lambda: page.evaluate(FRAME_STATE) == "failed", 30, "the viewer page's failed state")
    status = page.evaluate("document.getElementById('viewer').contentDocument.getElementById('status').textContent")
    assert "model could not be added" in status and "not an .rrd stream" in status
    assert any("not an .rrd stream" in error for error in page.console_errors())
