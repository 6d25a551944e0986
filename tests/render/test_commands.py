"""The commands end to end with the real viewer: `snapshot`, `diff --render`, `plan --render`; no viewer left behind
after an error or SIGTERM; without a renderer, one line saying what to install."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import psutil
import pytest

from urdf_pipeline.render.captions import BAND_COLOUR, band_height
from urdf_pipeline.render.headless_viewer import HeadlessViewer

from ..dataset_helpers import isolated_examples
from .conftest import SMALL
from .pixels import assert_framed, grey, rgb

SIZE = f"{SMALL.width}x{SMALL.height}"


def _captioned(picture: Path, lines: int = 2) -> np.ndarray:
    """The picture above its caption band; the band is there, on its own colour, with text in it."""
    pixels = rgb(picture)
    band = band_height(SMALL, lines)
    below = pixels[SMALL.height - band + 1 :]
    assert (below == BAND_COLOUR).all(axis=2).mean() > 0.5 and (below != BAND_COLOUR).any(), f"{picture.name}: no caption band"
    return pixels[: SMALL.height - band]


def test_snapshot_pictures_show_each_pose_large_with_a_caption(
    renderer: None, examples_dir: Path, written: dict[str, Path], tmp_path: Path, run_cli
) -> None:
    result = run_cli("snapshot", str(examples_dir / "demo.yaml"), "--at", "first,last", "--size", SIZE, "-o", str(tmp_path))
    assert result.code == 0, result.err
    first, last = (Path(line) for line in result.out.splitlines())
    assert (first.name, last.name) == ("episode_000.scene.frame_index-0.png", "episode_000.scene.frame_index-299.png")
    assert "2 picture(s) drawn by the Rerun viewer" in result.err
    for picture in (first, last):
        assert grey(picture).shape == (SMALL.height, SMALL.width)
        found = assert_framed(picture, extent=0.5)  # each framed on its own pose: half the width or height at least
        assert found.bottom <= 1 - band_height(SMALL, 2) / SMALL.height, "the robot stays above the caption"
        _captioned(picture)
    assert not np.array_equal(grey(first), grey(last)), "the robot moved between the first and the last row"


def test_a_hostile_config_name_is_captioned_on_one_line(
    renderer: None, examples_dir: Path, allow_examples: Path, tmp_path: Path, run_cli
) -> None:
    """A config file named with a newline, a workflow command and a bidi override: the caption shows it escaped in its
    band, the picture keeps its size and the robot its place."""
    plain = isolated_examples(examples_dir, tmp_path / "hostile", "demo.yaml")
    hostile = plain.parent / ("demo\n::error::forged\u202e" + "x" * 150 + ".yaml")  # 178 bytes: room for the tool's own suffixes
    plain.rename(hostile)
    assert run_cli("run", str(hostile), "--jobs", "1").code == 0
    result = run_cli("snapshot", str(hostile), "--at", "last", "--size", SIZE, "-o", str(tmp_path / "pictures"))
    assert result.code == 0, result.err
    (picture,) = (tmp_path / "pictures").glob("*.png")
    assert grey(picture).shape == (SMALL.height, SMALL.width)
    _captioned(picture)
    assert_framed(picture, extent=0.5)


def test_a_robot_view_shows_that_robot_only(renderer: None, examples_dir: Path, written: dict[str, Path], tmp_path: Path, run_cli) -> None:
    """A timestamp timeline (the bimanual example); `--view left` draws the left Panda only."""
    config = str(examples_dir / "bimanual_pandas.yaml")
    scene = run_cli("snapshot", config, "--at", "first", "--size", SIZE, "-o", str(tmp_path))
    left = run_cli("snapshot", config, "--at", "first", "--view", "left", "--size", SIZE, "-o", str(tmp_path))
    assert scene.code == 0 and left.code == 0, scene.err + left.err
    assert Path(left.out.strip()).name == "bimanual_000.left.timestamp-1970-01-01T00-00-00.000Z.png"
    both, one = assert_framed(Path(scene.out.strip())), assert_framed(Path(left.out.strip()))
    assert one != both and not np.array_equal(grey(Path(scene.out.strip())), grey(Path(left.out.strip())))


def test_a_split_layout_segment_is_drawn_with_its_model(
    renderer: None, examples_dir: Path, allow_examples: Path, tmp_path: Path, run_cli
) -> None:
    """The layer holds the FK only: the meshes come from the dataset's model asset, as `run --spawn` sends them."""
    config = isolated_examples(examples_dir, tmp_path / "split")
    assert run_cli("run", str(config), "--episodes", "1", "--jobs", "1").code == 0
    unwritten = run_cli("snapshot", str(config), "--segment", "episode_000000", "--size", SIZE, "-o", str(tmp_path))
    assert unwritten.code == 1 and "no recording at" in unwritten.err and "episode_000000.rrd" in unwritten.err
    result = run_cli("snapshot", str(config), "--segment", "episode_000001", "--at", "last", "--size", SIZE, "-o", str(tmp_path))
    assert result.code == 0, result.err
    assert Path(result.out.strip()).name == "episode_000001.scene.frame_index-149.png"
    assert_framed(Path(result.out.strip()))


def _moved_edge(examples_dir: Path, folder: Path) -> tuple[Path, Path]:
    old = isolated_examples(examples_dir, folder, "demo.yaml")
    new = folder / "moved.yaml"
    new.write_text(old.read_text().replace("translation: [0.0, 0.0, 0.5]", "translation: [0.4, 0.0, 0.5]"))
    return old, new


def test_diff_render_draws_a_moved_edge_side_by_side_and_as_a_ghost(
    renderer: None, examples_dir: Path, allow_examples: Path, tmp_path: Path, run_cli
) -> None:
    old, new = _moved_edge(examples_dir, tmp_path / "configs")
    pictures = tmp_path / "pictures"
    result = run_cli("diff", str(old), str(new), "--render", str(pictures), "--size", SIZE, "--format", "markdown")
    assert result.code == 0, result.err
    assert "edge world -> panda_link0: moved 400.0 mm" in result.out
    names = ("moved.diff.old.png", "moved.diff.new.png", "moved.diff.png", "moved.diff.overlay.png")
    for label, name in zip(("old", "new", "side by side", "overlay"), names, strict=True):
        assert f"[{label}]({pictures / name})" in result.out
    before, after = (assert_framed(pictures / name, share=0.005) for name in names[:2])
    assert not np.array_equal(grey(pictures / names[0]), grey(pictures / names[1]))
    assert abs(before.left - after.left) + abs(before.bottom - after.bottom) > 0.03, "the robot stands elsewhere in the new picture"
    assert grey(pictures / names[2]).shape == (SMALL.height, 2 * SMALL.width + 8)
    ghost, solid = _captioned(pictures / names[3]), _captioned(pictures / names[1])
    changed = np.abs(ghost - solid).max(axis=2) > 24
    assert changed.mean() > 0.002, "the old robot shows over the new picture"
    assert (ghost[changed][:, 2] > ghost[changed][:, 0]).mean() > 0.9, "as a blue ghost"
    rows, columns = np.nonzero(changed)
    assert abs(columns.mean() / SMALL.width - (before.left + before.right) / 2) < 0.15, "where the old robot stood"
    same = run_cli("diff", str(old), str(old), "--render", str(tmp_path / "same"), "--size", SIZE, "--format", "json")
    data = json.loads(same.out)
    assert data["equivalent"] and [p["label"] for p in data["pictures"]] == ["old", "new", "side by side", "overlay"]
    paths = [Path(p["path"]) for p in data["pictures"]]
    assert np.array_equal(_captioned(paths[0]), _captioned(paths[1])), "equal plans draw equal pictures (their captions aside)"
    assert np.array_equal(_captioned(paths[3]), _captioned(paths[1])), "no ghost where nothing moved"


def test_plan_render_draws_the_rest_pose_and_links_it(renderer: None, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    result = run_cli("plan", str(examples_dir / "bimanual_pandas.yaml"), "--format", "json", "--render", str(tmp_path), "--size", SIZE)
    assert result.code == 0, result.err
    pictures = json.loads(result.out)["pictures"]
    assert [p["label"] for p in pictures] == ["scene", "left", "right"]
    for picture in pictures:
        assert_framed(Path(picture["path"]), extent=0.5)
        _captioned(Path(picture["path"]))
    markdown = run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "markdown", "--render", str(tmp_path), "--size", SIZE)
    assert f"[scene]({tmp_path / 'demo.plan.scene.png'})" in markdown.out
    plain = run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "json")
    assert "pictures" not in json.loads(plain.out), "without --render the report is as before (the golden files)"


def test_no_viewer_is_left_after_an_error(renderer: None) -> None:
    with pytest.raises(RuntimeError, match="on purpose"), HeadlessViewer(SMALL) as viewer:
        process = viewer._process
        assert process is not None and process.poll() is None
        raise RuntimeError("on purpose")
    assert process.poll() is not None, "the viewer ended with the block"


def _viewers_of(parent: psutil.Process) -> list[psutil.Process]:
    try:
        return [child for child in parent.children(recursive=True) if child.name() == "rerun"]
    except psutil.NoSuchProcess:
        return []


def test_sigterm_stops_the_command_and_its_viewer(renderer: None, examples_dir: Path, written: dict[str, Path], tmp_path: Path) -> None:
    command = [sys.executable, "-m", "urdf_pipeline", "snapshot", str(examples_dir / "demo.yaml"), "--size", SIZE, "-o", str(tmp_path)]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        parent = psutil.Process(process.pid)
        viewers: list[psutil.Process] = []
        for _ in range(1200):  # until the viewer is up (or the command is over)
            viewers = _viewers_of(parent)
            if viewers or process.poll() is not None:
                break
            time.sleep(0.05)
        assert viewers, "the command started no viewer"
        process.send_signal(signal.SIGTERM)
        out, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 143, err
    assert "interrupted" in err
    for viewer in viewers:
        assert not viewer.is_running() or viewer.status() == psutil.STATUS_ZOMBIE, f"viewer {viewer.pid} left behind"


def test_without_a_renderer_one_line_says_what_to_install(examples_dir: Path, written: dict[str, Path], tmp_path: Path) -> None:
    """No Vulkan driver (the loader pointed at none): exit 1, one line, no panic, no viewer left."""
    environment = {**os.environ, "VK_ICD_FILENAMES": str(tmp_path / "none.json"), "VK_DRIVER_FILES": str(tmp_path / "none.json")}
    command = [sys.executable, "-m", "urdf_pipeline", "snapshot", str(examples_dir / "demo.yaml"), "--size", SIZE, "-o", str(tmp_path)]
    result = subprocess.run(command, capture_output=True, text=True, env=environment, timeout=300)
    assert result.returncode == 1, result.stderr
    assert result.stdout == ""
    assert result.stderr.splitlines() == [
        "error: cannot draw pictures: the Rerun viewer found no Vulkan driver; install one (apt-get install mesa-vulkan-drivers, "
        "a software renderer for any machine, or your GPU's Vulkan driver)"
    ]
    assert not list(tmp_path.glob("*.png"))
