"""A run writes its blueprint; `run --connect` / `--spawn` send each segment with its own ids, the model and the blueprint."""

from __future__ import annotations

from pathlib import Path

import pytest
import rerun as rr
from rerun.chunk import RrdReader

from ..dataset_helpers import isolated_examples

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples


def test_a_run_writes_its_blueprint_beside_the_outputs(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "bp")
    result = run_cli("run", str(config), "--episodes", "0:2", "--jobs", "1")
    assert result.code == 0, result.err
    blueprint_file = config.parent / "out" / "so101_dataset" / "so101_dataset.rbl"
    assert f"blueprint (a 3D view of the scene and one per robot): {blueprint_file}" in result.err
    (blueprint,) = RrdReader(blueprint_file).blueprints()
    assert blueprint.application_id == "so101_dataset"
    for output in map(Path, result.out.split()):
        reader = RrdReader(output)
        (recording,) = reader.recordings()
        assert recording.application_id == "so101_dataset"
        assert "/__properties" not in {c.entity_path for c in reader.stream().to_chunks()}, "nothing to collide with a base's properties"


@pytest.fixture
def viewer_capture(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> dict[str, object]:
    """A stand-in viewer: what the pipeline sends to it is saved to a file per recording id."""
    captured: dict[str, object] = {"urls": [], "spawned": 0, "dir": tmp_path / "viewer"}
    (tmp_path / "viewer").mkdir()

    def connect_grpc(self: rr.RecordingStream, url: str | None = None, *, default_blueprint=None) -> None:
        captured["urls"].append(url)  # type: ignore[union-attr]
        self.save(tmp_path / "viewer" / f"{self.get_recording_id()}.rrd", default_blueprint=default_blueprint)

    def spawn(self: rr.RecordingStream, **kwargs) -> None:
        captured["spawned"] = int(captured["spawned"]) + 1  # type: ignore[call-overload]
        connect_grpc(self, "spawned", default_blueprint=kwargs.get("default_blueprint"))

    monkeypatch.setattr(rr.RecordingStream, "connect_grpc", connect_grpc)
    monkeypatch.setattr(rr.RecordingStream, "spawn", spawn)
    return captured


def test_connect_sends_each_segment_with_its_ids_and_the_model(examples_dir: Path, tmp_path: Path, run_cli, viewer_capture) -> None:
    config = isolated_examples(examples_dir, tmp_path / "connect")
    result = run_cli("run", str(config), "--episodes", "0:2", "--connect", "rerun+http://127.0.0.1:9999/proxy")
    assert result.code == 0, result.err
    assert "sent 2 segment(s) to the viewer" in result.err
    assert viewer_capture["urls"] == ["rerun+http://127.0.0.1:9999/proxy"] * 2
    for segment in ("episode_000000", "episode_000001"):
        reader = RrdReader(Path(str(viewer_capture["dir"])) / f"{segment}.rrd")
        (recording,) = reader.recordings()
        assert (recording.application_id, recording.recording_id) == ("so101_dataset", segment), "ids kept: layers merge onto their segment"
        assert len(reader.blueprints()) == 1
        entities = {c.entity_path for c in reader.stream().to_chunks()}
        assert "/so101/joint_transforms" in entities and any("/visual_geometries/" in e for e in entities), "the model comes along"


def test_spawn_starts_one_viewer_and_connects_the_other_segments(examples_dir: Path, tmp_path: Path, run_cli, viewer_capture) -> None:
    config = isolated_examples(examples_dir, tmp_path / "spawn")
    result = run_cli("run", str(config), "--episodes", "1:4", "--spawn")
    assert result.code == 0, result.err
    assert viewer_capture["spawned"] == 1
    assert viewer_capture["urls"] == ["spawned", "rerun+http://127.0.0.1:9876/proxy", "rerun+http://127.0.0.1:9876/proxy"]
