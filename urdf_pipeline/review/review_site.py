"""`plan --html DIR` and `diff --html DIR`: the report as a static site on Rerun's web viewer (`web.write_site`), with
the plans at their rest pose as recordings the page opens in it (what a site holds: docs/web.md)."""

from __future__ import annotations

import tempfile
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import shown
from ..plan import Plan
from ..web import viewer_href
from .diff.diff_base import DiffReport
from .diff.diff_html import render_diff_html
from .plan_report.report_html import render_html
from .plan_report.report_model import PictureEntry, PlanReport

if TYPE_CHECKING:
    from rerun.chunk import Chunk

    from ..render import Camera
    from ..web import SiteWriter

PAGE = "index.html"
FRAME = "viewer-frame"  # the embedded viewer's name
FRAME_HEIGHT = 560  # pixels (an attribute: the page's policy allows no inline style)
VIEW_ASPECT = (4, 3)  # the camera frames the robots for a view this wide to this high (the viewer's, roughly)
PLAN_RECORDING = "rest_pose"


def write_plan_site(site: SiteWriter, plan: Plan, report: PlanReport) -> None:
    """The plan's report as `index.html`, its rest pose as a recording the page opens in the viewer, the pictures."""
    from ..render import rest_values, scene_camera, scene_chunks

    chunks = scene_chunks(plan, rest_values(plan))
    camera = scene_camera([(plan, chunks)], *VIEW_ASPECT)
    recording = _scene_recording(site, plan, chunks, camera, PLAN_RECORDING, f"rest pose: {report.config.relative}")
    report = replace(report, pictures=_site_pictures(site, report.pictures, "plan"))
    viewer = _viewer_section(
        [("rest pose", recording)],
        "Each robot at its rest pose (held joints at their value, every other joint at zero clamped into its limits), "
        "with the axes of the config's frames.",
    )
    site.write_page(PAGE, f"plan of {report.config.relative}", render_html(report, PAGE, viewer))


def write_diff_site(site: SiteWriter, old: Plan, new: Plan, report: DiffReport) -> None:
    """The diff as `index.html`; old and new at the same joint values, from one camera, as two recordings, which
    the page opens together in the embedded viewer, and each alone or both full page; the pictures."""
    from ..render import scene_camera, scene_chunks, shared_values

    values = shared_values(old, new)
    sides = {"old": (old, report.old), "new": (new, report.new)}
    chunks = {side: scene_chunks(plan, values) for side, (plan, _) in sides.items()}
    camera = scene_camera([(plan, chunks[side]) for side, (plan, _) in sides.items()], *VIEW_ASPECT)
    files = {side: _scene_recording(site, plan, chunks[side], camera, side, f"{side}: {name}") for side, (plan, name) in sides.items()}
    report = replace(report, pictures=_site_pictures(site, report.pictures, "diff"))
    viewer = _viewer_section(
        [("both", [*files["old"], *files["new"]]), ("old", files["old"]), ("new", files["new"])],
        "Old and new at the same joint values (the new config's rest pose; the old one's for joints only it has), from "
        "one camera. The viewer's recording list (left) switches between <code>old</code> and <code>new</code>.",
    )
    site.write_page(PAGE, f"diff of {shown(report.old)} and {shown(report.new)}", render_diff_html(report, PAGE, viewer))


def _viewer_section(choices: Sequence[tuple[str, Sequence[str]]], what: str) -> str:
    """The first choice's recordings in a viewer embedded in the page; every choice full page, by link. `what` and
    the labels are the tool's own HTML."""
    links = " ".join(f'<a class="button" href="{viewer_href(PAGE, files)}">{label}</a>' for label, files in choices)
    return "\n".join(
        [
            '<section id="viewer">',
            "<h2>In Rerun's web viewer</h2>",
            f'<p class="muted">{what} Drag to turn the view, scroll to zoom. Full page: {links}</p>',
            f'<iframe name="{FRAME}" title="Rerun web viewer" src="{viewer_href(PAGE, choices[0][1])}" width="100%" '
            f'height="{FRAME_HEIGHT}" loading="lazy"></iframe>',
            "</section>",
        ]
    )


def _scene_recording(site: SiteWriter, plan: Plan, chunks: list[Chunk], camera: Camera, recording_id: str, name: str) -> list[str]:
    """The scene as `recordings/RECORDING_ID.rrd` (the config's application id, the recording id, `name` for the
    viewer's recording list) and its blueprint `recordings/RECORDING_ID.rbl`; their site paths."""
    import rerun.blueprint as rrb
    from rerun.archetypes import RecordingInfo
    from rerun.chunk import Chunk, ChunkStore

    properties = Chunk.from_columns("/__properties", indexes=[], columns=RecordingInfo.columns(name=[shown(name)]))
    eye = rrb.EyeControls3D(position=camera.position, look_target=camera.target, eye_up=camera.up)
    blueprint = rrb.Blueprint(
        rrb.Spatial3DView(origin="/", name="scene", eye_controls=eye),
        rrb.TimePanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        collapse_panels=False,
    )
    with tempfile.TemporaryDirectory(prefix=".recording-", dir=site.root) as folder:  # in the site: hard links, no copy
        recording, layout = Path(folder) / f"{recording_id}.rrd", Path(folder) / f"{recording_id}.rbl"
        ChunkStore.from_chunks([*chunks, properties]).write_rrd(recording, application_id=plan.application_id, recording_id=recording_id)
        blueprint.save(plan.application_id, layout)
        return [site.add_recording(recording), site.add_recording(layout)]


def _site_pictures(site: SiteWriter, pictures: Sequence[PictureEntry], stem: str) -> tuple[PictureEntry, ...]:
    """The pictures `--render` drew, put into the site under `pictures/` by number (their file names hold config
    names), with their site paths."""
    return tuple(
        PictureEntry(picture.label, site.add_file(Path(picture.path), f"pictures/{stem}-{number}.png"))
        for number, picture in enumerate(pictures, start=1)
    )
