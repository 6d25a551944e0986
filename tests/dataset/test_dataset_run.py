"""Whole datasets: one segment per episode, split layout, parallel workers, skipping what is up to date, failures kept
to their segment, Ctrl-C leaving only complete files, and `--base` checking that layers will attach."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from io import StringIO
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader

from urdf_pipeline.execute.segment_run import SegmentResult
from urdf_pipeline.logs import SegmentProgress

from ..dataset_helpers import (
    SO101_JOINTS,
    edit_config,
    isolated_examples,
    random_so101_episodes,
    status_lines,
    store_ids,
    write_so101_dataset,
)
from ..execute.test_fk_against_pinocchio import check_robot
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples

EPISODE_LENGTHS = [300, 150, 100, 75]  # the examples' so101 dataset (prepare(frames=300))


@pytest.fixture
def so101_dataset(examples_dir: Path, tmp_path: Path) -> Path:
    return isolated_examples(examples_dir, tmp_path / "run")


def _outputs(config: Path) -> Path:
    return config.parent / "out" / "so101_dataset"


def _manifest(config: Path) -> dict:
    return json.loads((_outputs(config) / "so101_dataset.manifest.json").read_text())


def test_split_layout_writes_the_model_once_and_a_layer_per_episode(so101_dataset: Path, run_cli) -> None:
    result = run_cli("run", str(so101_dataset), "--jobs", "2")
    assert result.code == 0, result.err
    out = _outputs(so101_dataset)
    layers = [out / f"episode_{e:06d}.rrd" for e in range(4)]
    assert result.out.split() == [str(out / "model.rrd"), *map(str, layers)]
    assert status_lines(result.err) == {"model": "written", **{f"episode_{e:06d}": "written" for e in range(4)}}

    model_chunks = RrdReader(out / "model.rrd").stream().to_chunks()
    assert all(chunk.is_static for chunk in model_chunks), "a catalog asset must hold static chunks only"
    model_entities = {chunk.entity_path for chunk in model_chunks}
    assert "/so101/tf_static" in model_entities and any("/visual_geometries/" in e for e in model_entities)
    assert store_ids(out / "model.rrd") == ("so101_dataset", "urdf_model")

    for episode, (layer, frames) in enumerate(zip(layers, EPISODE_LENGTHS, strict=True)):
        assert store_ids(layer) == ("so101_dataset", f"episode_{episode:06d}")
        chunks = RrdReader(layer).stream().to_chunks()
        entities = {chunk.entity_path for chunk in chunks}
        assert "/so101/joint_transforms" in entities
        assert not any("geometries" in e or e.endswith("tf_static") for e in entities), "a layer holds no model"
        rows = sum(c.num_rows for c in chunks if c.entity_path == "/so101/joint_transforms")
        assert rows == frames * 6  # six moving joints per frame
        assert layer.stat().st_size * 10 < (out / "model.rrd").stat().st_size

    manifest = _manifest(so101_dataset)
    assert manifest["layout"] == "split" and manifest["model"]["path"] == "model.rrd"
    assert [s["segment"] for s in manifest["segments"]] == [f"episode_{e:06d}" for e in range(4)]
    assert [s["frames"] for s in manifest["segments"]] == EPISODE_LENGTHS
    for entry in manifest["segments"]:
        assert len(entry["content_sha256"]) == 64 and entry["bytes"] == (out / entry["path"]).stat().st_size
    assert not list(out.glob(".*partial*"))


def test_split_layout_model_plus_layer_matches_pinocchio(so101_dataset: Path, run_cli, erd_share: Path) -> None:
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    episodes = random_so101_episodes(reference, [30, 25, 20], seed=21)
    dataset = so101_dataset.parent / "random_so101"
    write_so101_dataset(dataset, episodes)
    edit_config(so101_dataset, lambda d: d["sources"]["so101"].update(lerobot="random_so101"))
    result = run_cli("run", str(so101_dataset), "--jobs", "2")
    assert result.code == 0, result.err
    out = _outputs(so101_dataset)
    root = reference.model.frames[1].name
    for episode, q in enumerate(episodes):
        frames = read_frames([out / "model.rrd", out / f"episode_{episode:06d}.rrd"], "frame_index")
        values = [dict(zip(SO101_JOINTS, row, strict=True)) for row in q]
        assert check_robot(frames, list(range(len(q))), reference, values, "", np.eye(4), root, [0, len(q) // 2, len(q) - 1]) > 0


def test_a_rerun_skips_what_is_up_to_date_and_rewrites_what_changed(so101_dataset: Path, run_cli, erd_share: Path) -> None:
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    dataset = so101_dataset.parent / "random_so101"
    episodes = random_so101_episodes(reference, [20, 20, 20], seed=22)
    write_so101_dataset(dataset, episodes)
    edit_config(so101_dataset, lambda d: d["sources"]["so101"].update(lerobot="random_so101"))
    assert run_cli("run", str(so101_dataset), "--jobs", "1").code == 0
    out = _outputs(so101_dataset)
    mtimes = {p.name: p.stat().st_mtime_ns for p in out.glob("*.rrd")}

    again = run_cli("run", str(so101_dataset))
    assert again.code == 0, again.err
    assert set(status_lines(again.err).values()) == {"skipped"}
    assert {p.name: p.stat().st_mtime_ns for p in out.glob("*.rrd")} == mtimes
    assert len(again.out.split()) == 4, "skipped outputs are still listed: they are part of the result"

    episodes[1] = episodes[1][::-1].copy()  # episode 1's data changes, the others do not
    write_so101_dataset(dataset, episodes)
    changed = run_cli("run", str(so101_dataset))
    assert changed.code == 0, changed.err
    assert status_lines(changed.err) == {
        "model": "skipped",
        "episode_000000": "skipped",
        "episode_000001": "written",
        "episode_000002": "skipped",
    }

    (out / "so101_dataset.manifest.json").unlink()  # without a manifest, the hash stored in each file decides
    assert set(status_lines(run_cli("run", str(so101_dataset)).err).values()) == {"skipped"}
    assert (out / "so101_dataset.manifest.json").is_file()

    forced = run_cli("run", str(so101_dataset), "--force")
    assert set(status_lines(forced.err).values()) == {"written"}

    edit_config(so101_dataset, lambda d: d["robots"]["so101"]["joints"]["map"].update(gripper={"joint": "gripper", "offset": 0.01}))
    remapped = run_cli("run", str(so101_dataset))  # a changed correction changes every layer, not the model
    assert status_lines(remapped.err) == {"model": "skipped", **{f"episode_{e:06d}": "written" for e in range(3)}}


def test_comments_and_key_order_do_not_make_outputs_stale(so101_dataset: Path, run_cli) -> None:
    assert run_cli("run", str(so101_dataset), "--episodes", "3").code == 0
    text = so101_dataset.read_text()
    so101_dataset.write_text("# reviewed in PR 12\n" + text.replace("  layout: split\n", "") + "  layout: split\n")
    assert set(status_lines(run_cli("run", str(so101_dataset), "--episodes", "3").err).values()) == {"skipped"}


def test_episodes_select_segments_and_the_command_line_overrides(so101_dataset: Path, run_cli) -> None:
    edit_config(so101_dataset, lambda d: d["output"].update(episodes=[0, 2]))
    result = run_cli("run", str(so101_dataset))
    assert result.code == 0, result.err
    assert sorted(status_lines(result.err)) == ["episode_000000", "episode_000002", "model"]
    result = run_cli("run", str(so101_dataset), "--episodes", "2:")
    assert sorted(status_lines(result.err)) == ["episode_000002", "episode_000003", "model"]
    manifest = _manifest(so101_dataset)  # entries of earlier runs stay while their files exist
    assert [s["segment"] for s in manifest["segments"]] == ["episode_000000", "episode_000002", "episode_000003"]
    episode_0 = [path for path in manifest["files"] if path.endswith("episode_000000.parquet")]
    assert episode_0, "the hash of a file this run did not read is kept for the next full re-run"
    wrong = run_cli("run", str(so101_dataset), "--episodes", "1,9")
    assert wrong.code == 1 and "error: --episodes: episode(s) 9 do not exist (the dataset's episodes: 0..3)" in wrong.err


def test_one_failing_segment_does_not_stop_the_others(so101_dataset: Path, run_cli, erd_share: Path) -> None:
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    episodes = random_so101_episodes(reference, [20, 20, 20], seed=23)
    episodes[1][5:8, 0] = 4.0  # shoulder_pan far beyond its limits in three rows of episode 1
    dataset = so101_dataset.parent / "random_so101"
    write_so101_dataset(dataset, episodes)
    edit_config(so101_dataset, lambda d: d["sources"]["so101"].update(lerobot="random_so101"))
    result = run_cli("run", str(so101_dataset), "--jobs", "2")
    assert result.code == 1
    assert status_lines(result.err) == {
        "model": "written",
        "episode_000000": "written",
        "episode_000001": "failed",
        "episode_000002": "written",
    }
    failed = next(line for line in result.err.splitlines() if line.startswith("episode_000001"))
    assert "shoulder_pan" in failed and "Traceback" not in result.err
    assert "3 outputs: 3 written, 1 failed" in result.err.replace("4 outputs", "3 outputs")
    out = _outputs(so101_dataset)
    assert not (out / "episode_000001.rrd").exists() and not list(out.glob(".*partial*"))
    assert [s["segment"] for s in _manifest(so101_dataset)["segments"]] == ["episode_000000", "episode_000002"]
    assert str(out / "episode_000001.rrd") not in result.out


def test_single_layout_one_recording_per_globbed_file(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "glob", "demo.yaml")
    (config.parent / "episodes").mkdir()
    for stem in ("pick_a", "pick_b"):
        (config.parent / "episodes" / f"{stem}.parquet").symlink_to(examples_dir / "data" / "episode_000.parquet")
    edit_config(
        config, lambda d: (d["sources"]["arm_state"].update(parquet="episodes/*.parquet"), d["output"].update(segment="demo_{stem}"))
    )
    result = run_cli("run", str(config), "--jobs", "2")
    assert result.code == 0, result.err
    paths = [Path(p) for p in result.out.split()]
    assert [p.name for p in paths] == ["demo_pick_a.rrd", "demo_pick_b.rrd"]
    for path, stem in zip(paths, ("pick_a", "pick_b"), strict=True):
        assert store_ids(path) == ("panda_demo", f"demo_{stem}")
        assert any("/visual_geometries/" in c.entity_path for c in RrdReader(path).stream().to_chunks())


def _long_dataset(so101_dataset: Path, erd_share: Path) -> None:
    """12 episodes of 100,000 rows: long enough to stop a run in the middle."""
    reference = PinocchioRobot(erd_share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    dataset = so101_dataset.parent / "long_so101"
    write_so101_dataset(dataset, random_so101_episodes(reference, [100_000] * 12, seed=24))
    edit_config(so101_dataset, lambda d: d["sources"]["so101"].update(lerobot="long_so101"))


def _stopped_run(config: Path, signum: signal.Signals, *extra: str) -> tuple[int, str, str]:
    """`run CONFIG --jobs 2`, sent `signum` (to its whole process group, as a terminal's Ctrl-C) once some segments
    are done and others in flight: (exit status, stdout, stderr)."""
    command = [sys.executable, "-m", "urdf_pipeline", "run", str(config), "--jobs", "2", *extra]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True)
    assert process.stderr is not None
    seen = []
    for line in process.stderr:  # wait until some segments are done and others in flight
        seen.append(line)
        if "[3/" in line:
            break
    os.killpg(process.pid, signum)
    out, rest = process.communicate(timeout=60)
    return process.returncode, out, "".join(seen) + rest


def _identities(outputs: Path) -> dict[str, tuple[int, int]]:
    return {p.stem: (p.stat().st_ino, p.stat().st_mtime_ns) for p in outputs.glob("*.rrd")}


def test_ctrl_c_stops_cleanly_and_leaves_only_complete_files(so101_dataset: Path, erd_share: Path) -> None:
    _long_dataset(so101_dataset, erd_share)
    code, out, err = _stopped_run(so101_dataset, signal.SIGINT)
    assert code == 130, err
    assert "interrupted" in err and "Traceback" not in err
    outputs = _outputs(so101_dataset)
    assert not list(outputs.glob(".*partial*")), "partial files were left behind"
    written = sorted(p.name for p in outputs.glob("episode_*.rrd"))
    assert 2 <= len(written) < 12
    manifest = _manifest(so101_dataset)
    assert sorted(s["path"] for s in manifest["segments"]) == written, "the manifest lists exactly the complete files"
    for name in written:
        assert store_ids(outputs / name)[1] == name.removesuffix(".rrd")  # readable: complete
    assert set(out.split()) == {str(outputs / n) for n in written} | {str(outputs / "model.rrd")}
    # the summary says "written" for exactly the files there, "interrupted" for the others, and counts them
    statuses = status_lines(err)
    assert {label for label, status in statuses.items() if status == "written"} == {"model"} | {n.removesuffix(".rrd") for n in written}
    assert {status for label, status in statuses.items() if f"{label}.rrd" not in written and label != "model"} == {"interrupted"}
    not_done = 12 - len(written)
    assert f"interrupted (Ctrl-C): {len(written) + 1} written in this run, 0 up to date from an earlier run, {not_done} not done (" in err


def test_a_stopped_rerun_says_written_only_of_what_it_rewrote(so101_dataset: Path, erd_share: Path, run_cli) -> None:
    """A `--force` run stopped by SIGTERM after a complete run: the files it did not rewrite are the earlier run's,
    untouched, and the summary says so ("up to date", not "written"), exit 143."""
    _long_dataset(so101_dataset, erd_share)
    assert run_cli("run", str(so101_dataset), "--jobs", "2").code == 0
    outputs = _outputs(so101_dataset)
    before = _identities(outputs)
    code, out, err = _stopped_run(so101_dataset, signal.SIGTERM, "--force")
    assert code == 143, err
    assert "Traceback" not in err
    after = _identities(outputs)
    assert after.keys() == before.keys()  # every complete file is still there
    rewritten = {label for label in before if after[label] != before[label]}
    statuses = status_lines(err)
    assert {label for label, status in statuses.items() if status == "written"} == rewritten
    assert 2 <= len(rewritten) < 13
    assert {statuses[label] for label in before.keys() - rewritten} == {"skipped"}
    kept = 13 - len(rewritten)
    assert f"{len(rewritten)} written, {kept} up to date;" in err
    expected = f"interrupted (SIGTERM): {len(rewritten)} written in this run, {kept} up to date from an earlier run ({kept} of them not rewritten as --force asked), 0 not done"
    assert expected in err
    assert set(out.split()) == {str(outputs / f"{label}.rrd") for label in before}  # all complete and up to date
    manifest = _manifest(so101_dataset)
    assert all("summary" in entry for entry in manifest["segments"]), "an entry left as it was keeps its summary"


def test_base_recordings_must_hold_every_segment(so101_dataset: Path, run_cli) -> None:
    base = so101_dataset.parent / "base"
    single = edit_config(
        so101_dataset.with_name("base.yaml").absolute() if False else so101_dataset, lambda d: None
    )  # the base: the same episodes written as single recordings
    base_config = so101_dataset.with_name("base.yaml")
    base_config.write_text(
        single.read_text()
        .replace("  layout: split\n", "")
        .replace("  model: out/so101_dataset/model.rrd\n", "")
        .replace("out/so101_dataset/{segment}.rrd", "base/{segment}.rrd")
    )
    assert run_cli("run", str(base_config), "--episodes", "0:2").code == 0
    ok = run_cli("run", str(so101_dataset), "--episodes", "0:2", "--base", str(base))
    assert ok.code == 0, ok.err
    assert "all 2 segment id(s) found among the base recordings" in ok.err

    missing = run_cli("run", str(so101_dataset), "--base", str(base))
    assert missing.code == 1
    assert "2 of 4 segment(s) have no base recording" in missing.err and "episode_000002, episode_000003" in missing.err
    assert not (_outputs(so101_dataset) / "episode_000003.rrd").exists(), "refused before writing anything"

    edit_config(so101_dataset, lambda d: d["output"].update(application_id="another_app"))
    other = run_cli("run", str(so101_dataset), "--episodes", "0:2", "--base", str(base / "*.rrd"))
    assert other.code == 1 and "application_id so101_dataset" in other.err and "set output.application_id" in other.err


def test_progress_bar_on_a_terminal_and_lines_otherwise() -> None:
    class Terminal(StringIO):
        def isatty(self) -> bool:
            return True

    result = SegmentResult("episode_000000", Path("x.rrd"), "written", "h", frames=300, seconds=0.5)
    terminal, log = Terminal(), StringIO()
    for stream in (terminal, log):
        progress = SegmentProgress(stream)
        progress.start(3, 900, skipped=1)
        progress.done(result, 300)
        time.sleep(0.01)
        progress.done(result, 300)
        progress.finish()
    assert "\r" in terminal.getvalue() and "3/3 segments" in terminal.getvalue() and "frames/s, ETA" in terminal.getvalue()
    assert "\r" not in log.getvalue()
    assert "[2/3] episode_000000 written (300 frames, 0.5 s)" in log.getvalue()
    assert "1 of 3 up to date (skipped)" in log.getvalue()
