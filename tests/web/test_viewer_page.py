"""The demo's recording in a site, opened in Rerun's web viewer by headless chromium from `urdf-pipeline serve`.

One page load is shared by the tests of this module (the 43 MB wasm compiles on the CPU): the site's index page is
opened under a path prefix, its link to the viewer followed, and the robot waited for on the canvas. The tests then
read what the page did: its console, its requests, what it shows.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from urdf_pipeline.web import ViewerAssets, html_text, viewer_href, write_site

from .canvas import ROBOT_SHARE, wait_for_robot
from .conftest import Served
from .devtools import Browser, Page, site_paths

PREFIX = "sites/demo"


@dataclass
class ViewerPage:
    page: Page
    site_url: str
    seconds_to_robot: float
    share: float


@pytest.fixture(scope="module")
def viewer_page(browser: Browser, served: Served, viewer_cache: ViewerAssets, demo_recording: Path) -> Iterator[ViewerPage]:
    """The demo site under a path prefix of the session's server, its viewer link followed, the robot on screen."""
    with write_site(served.root / PREFIX) as site:
        recording = site.add_recording(demo_recording)
        site.add_recording(demo_recording.with_name("demo.rbl"))
        href = viewer_href("index.html", [recording])
        site.write_page("index.html", "demo", f'<h1>{html_text("demo")}</h1><p><a id="open" href="{href}">open in the viewer</a></p>')
    page = browser.page()
    try:
        site_url = f"{served.url}{PREFIX}/index.html"
        page.navigate(site_url)
        link = page.wait_for(
            lambda: page.evaluate("document.getElementById('open') && document.getElementById('open').href"), 30, "the link"
        )
        page.navigate(link)
        share, seconds = wait_for_robot(page)
        yield ViewerPage(page, site_url, seconds, share)
    finally:
        page.close()


def test_the_viewer_shows_the_demo_robot(viewer_page: ViewerPage) -> None:
    assert viewer_page.share >= ROBOT_SHARE
    print(
        f"first robot pixels {viewer_page.seconds_to_robot:.1f} s after the viewer page was opened; {viewer_page.share:.0%} of the centre"
    )


def test_the_page_logs_no_error(viewer_page: ViewerPage) -> None:
    """No console error, no uncaught exception, no Content-Security-Policy violation."""
    assert viewer_page.page.console_errors() == []


def test_no_request_leaves_this_machine(viewer_page: ViewerPage) -> None:
    """Every request went to the server on 127.0.0.1, under the site's prefix, and was answered; none was blocked."""
    requests = viewer_page.page.requests()
    assert requests, "the page made no request at all"
    paths = site_paths(requests, PREFIX)
    assert {"viewer/re_viewer.js", "viewer/re_viewer_bg.wasm", "viewer/boot.js", "style.css", "recordings/episode_000.rrd"} <= paths


def test_a_second_recording_opens_in_the_running_viewer(viewer_page: ViewerPage) -> None:
    """A new fragment opens its recordings in the viewer already running: the wasm is not loaded again."""
    page = viewer_page.page
    page.evaluate("location.hash = '#url=../recordings/episode_000.rrd&url=../recordings/demo.rbl'")
    page.wait_for(lambda: [r for r in page.requests() if r.url.endswith("/recordings/demo.rbl") and r.status == 200], 60, "demo.rbl")
    assert len([r for r in page.requests() if r.url.endswith("/re_viewer_bg.wasm")]) == 1
    assert page.evaluate("document.body.dataset.state") == "started"
    assert page.console_errors() == []


def test_a_recording_elsewhere_is_refused(viewer_page: ViewerPage) -> None:
    """A link naming a file of another origin (a page of the site linked by a stranger) opens nothing, says so, and
    requests nothing."""
    page = viewer_page.page
    page.evaluate("location.hash = '#url=http://localhost:9/x.rrd'")
    page.wait_for(lambda: page.evaluate("document.body.dataset.state") == "refused", 30, "the refusal")
    assert "not a file of this site" in page.evaluate("document.getElementById('status').textContent")
    assert not [r for r in page.requests() if "localhost:9" in r.url]
    assert page.console_errors() == []
