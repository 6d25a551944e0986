"""`diff --render`'s overlay as the reports link it and as its caption lists the changes; no viewer needed (the pictures
themselves: tests/render/test_commands.py)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from urdf_pipeline.review.diff.diff_base import Change, DiffReport
from urdf_pipeline.review.diff.diff_inputs import compile_quietly
from urdf_pipeline.review.diff.diff_plans import diff_plans
from urdf_pipeline.review.diff.diff_render import render_diff
from urdf_pipeline.review.picture_entries import caption_changes
from urdf_pipeline.review.plan_report.report_model import PictureEntry

PICTURES = tuple(
    PictureEntry(label, f"out/pics/new.diff{suffix}.png")
    for label, suffix in (("old", ".old"), ("new", ".new"), ("side by side", ""), ("overlay", ".overlay"))
)


@pytest.fixture
def configs(examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[Path, Path]:
    """The demo config, and one whose mount moved 40 cm, whose j2 flipped sign and whose j4 and j5 swapped joints."""
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    for name in ("robots", "data"):
        (tmp_path / name).symlink_to(examples_dir / name, target_is_directory=True)
    old = tmp_path / "demo.yaml"
    old.write_text((examples_dir / "demo.yaml").read_text())
    text = old.read_text()
    for before, after in (
        ("j2: {joint: panda_joint2, sign: -1}", "j2: {joint: panda_joint2, sign: 1}"),
        ("j4: panda_joint4", "j4: panda_jointX"),
        ("j5: panda_joint5", "j5: panda_joint4"),
        ("panda_jointX", "panda_joint5"),
        ("translation: [0.0, 0.0, 0.5]", "translation: [0.4, 0.0, 0.5]"),
    ):
        assert before in text, before
        text = text.replace(before, after)
    new = tmp_path / "moved.yaml"
    new.write_text(text)
    return old, new


def test_the_caption_lists_moves_then_remaps_then_the_rest(configs: tuple[Path, Path]) -> None:
    old, new = configs
    changes = diff_plans(compile_quietly(old), compile_quietly(new))
    assert [c.line.split(":")[0] for c in changes][0] == "robot arm", "the report keeps its own order"
    assert caption_changes(changes) == (
        "edge world -> panda_link0: moved 400.0 mm, 0.00 deg",
        "robot arm: j4: remapped panda_joint4 -> panda_joint5",
        "robot arm: j5: remapped panda_joint5 -> panda_joint4",
        "robot arm: j2 -> panda_joint2: sign -1 -> 1",
    )


def test_a_moved_joint_origin_counts_as_a_move_and_names_pass_through_unchanged() -> None:
    """The caption's lines are the report's words; making them safe to draw is the picture's job (render/captions.py)."""
    changes = (
        Change("output", "output", "path out/a.rrd -> out/b.rrd"),
        Change("robot", "robot arm", "panda_joint1: origin moved 5.0 mm, 0.00 deg (xyz [0, 0, 0.333] -> [0, 0, 0.338])"),
        Change("edges", "edge world -> cam\n::error::x", "moved 1.0 mm, 0.00 deg (translation [0, 0, 0] -> [0.001, 0, 0])"),
    )
    assert caption_changes(changes) == (
        "robot arm: panda_joint1: origin moved 5.0 mm, 0.00 deg",
        "edge world -> cam\n::error::x: moved 1.0 mm, 0.00 deg",
        "output: path out/a.rrd -> out/b.rrd",
    )


def test_the_reports_link_the_overlay_beside_the_side_by_side() -> None:
    report = DiffReport("demo.yaml", "moved.yaml", (Change("edges", "edge world -> base", "moved 1.0 mm, 0.00 deg"),), PICTURES)
    markdown = render_diff(report, "markdown")
    assert "[side by side](out/pics/new.diff.png) · [overlay](out/pics/new.diff.overlay.png)" in markdown
    assert "the overlay: old as a blue ghost" in markdown
    data = json.loads(render_diff(report, "json"))
    assert [p["label"] for p in data["pictures"]] == ["old", "new", "side by side", "overlay"]
    assert data["pictures"][3]["path"] == "out/pics/new.diff.overlay.png"
    assert render_diff(report, "text") == "edge world -> base: moved 1.0 mm, 0.00 deg\n", "text keeps one line per change"
    assert "pictures" not in json.loads(render_diff(DiffReport("a", "b", ()), "json")), "no --render, no pictures"
