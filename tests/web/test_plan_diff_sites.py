"""`plan --html` and `diff --html` sites in headless chromium, served by the session's `urdf-pipeline serve` under a path
prefix: the plan page's embedded viewer shows the rest pose, the diff page's holds old and new (both recordings in
the viewer), and neither page logs an error or requests anything off 127.0.0.1.

Two page loads for the module (the wasm compiles on the CPU for each): the plan page and the diff page, each opened
once and read by every test.
"""

from __future__ import annotations

import base64
import json
import shutil
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

FRAME = "document.querySelector('iframe')"
HEIGHT = 1100  # the tab's height: the page's summary and its embedded viewer fit


@dataclass
class SitePage:
    page: Page
    prefix: str  # the site's folder under the server's root
    seconds_to_robot: float
    share: float


def _build(served: Served, name: str, command: list[str]) -> str:
    prefix = f"sites/{name}"
    assert cli.main([*command, "--html", str(served.root / prefix), "-q"]) in (0, 1)  # diff --exit-code: 1 when they differ
    return prefix


def _frame_state(page: Page) -> str | None:
    state: str | None = page.evaluate(f"{FRAME}?.contentDocument?.body?.dataset.state ?? null")
    return state


def _frame_share(page: Page) -> float:
    """The robot's share of the embedded viewer's centre (a screenshot clipped to the iframe)."""
    box = json.loads(page.evaluate(f"JSON.stringify({FRAME}.getBoundingClientRect())"))
    clip = {"x": box["x"], "y": box["y"], "width": box["width"], "height": box["height"], "scale": 1}
    return drawn_share(base64.b64decode(page.call("Page.captureScreenshot", {"format": "png", "clip": clip})["data"]))


def _open(browser: Browser, served: Served, prefix: str) -> SitePage:
    """The site's index page opened; returned once its embedded viewer has started and draws a robot."""
    page = browser.page(1024, HEIGHT)
    started = time.monotonic()
    page.navigate(f"{served.url}{prefix}/index.html")

    def robot() -> float:
        share = _frame_share(page) if _frame_state(page) == "started" else 0.0
        return share if share >= ROBOT_SHARE else 0.0

    try:
        share = page.wait_for(robot, ROBOT_SECONDS, f"the robot in the embedded viewer (console errors: {page.console_errors()})", poll=1.0)
    except BaseException:
        page.close()
        raise
    return SitePage(page, prefix, time.monotonic() - started, share)


@pytest.fixture(scope="module")
def plan_page(browser: Browser, served: Served, viewer_cache: ViewerAssets, examples_dir: Path) -> Iterator[SitePage]:
    opened = _open(browser, served, _build(served, "plan-review", ["plan", str(examples_dir / "demo.yaml")]))
    yield opened
    opened.page.close()


@pytest.fixture(scope="module")
def diff_page(
    browser: Browser, served: Served, viewer_cache: ViewerAssets, examples_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[SitePage]:
    """demo.yaml against a copy whose arm is mounted 20 cm higher, both at the same joint values."""
    work = tmp_path_factory.mktemp("diff-site")
    for name in ("robots", "data"):
        (work / name).symlink_to(examples_dir / name, target_is_directory=True)
    shutil.copy(examples_dir / "demo.yaml", work / "demo.yaml")
    moved = work / "moved.yaml"
    moved.write_text((work / "demo.yaml").read_text().replace("translation: [0.0, 0.0, 0.5]", "translation: [0.0, 0.0, 0.7]"))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
        prefix = _build(served, "diff-review", ["diff", str(work / "demo.yaml"), str(moved)])
    opened = _open(browser, served, prefix)
    yield opened
    opened.page.close()


def test_the_plan_page_shows_the_rest_pose(plan_page: SitePage) -> None:
    assert plan_page.share >= ROBOT_SHARE
    print(f"plan page: first robot pixels {plan_page.seconds_to_robot:.1f} s after it was opened; {plan_page.share:.0%} of the centre")
    state = plan_page.page.viewer_state()
    assert b"app_id=panda_demo&recording_id=rest_pose" in state


def test_the_diff_page_holds_old_and_new(diff_page: SitePage) -> None:
    """Both recordings are in the one embedded viewer (its recording list switches between them)."""
    assert diff_page.share >= ROBOT_SHARE
    print(f"diff page: first robot pixels {diff_page.seconds_to_robot:.1f} s after it was opened; {diff_page.share:.0%} of the centre")
    page = diff_page.page

    def both() -> bytes | None:
        state = page.viewer_state()
        return state if b"recording_id=old" in state and b"recording_id=new" in state else None

    state = page.wait_for(both, 60, "old and new in the viewer")
    assert b"Recording:panda_demo:old" in state and b"Recording:panda_demo:new" in state
    assert len([r for r in page.requests() if r.url.endswith("/re_viewer_bg.wasm")]) == 1


@pytest.mark.parametrize("which", ["plan_page", "diff_page"])
def test_no_error_and_no_request_off_this_machine(which: str, request: pytest.FixtureRequest) -> None:
    opened: SitePage = request.getfixturevalue(which)
    assert opened.page.console_errors() == []  # the page's and its viewer's: no error, exception or policy violation
    paths = site_paths(opened.page.requests(), opened.prefix)
    recordings = {"rest_pose.rrd", "rest_pose.rbl"} if which == "plan_page" else {"old.rrd", "old.rbl", "new.rrd", "new.rbl"}
    assert {"index.html", "style.css", "viewer/index.html", "viewer/re_viewer_bg.wasm", *(f"recordings/{r}" for r in recordings)} <= paths
