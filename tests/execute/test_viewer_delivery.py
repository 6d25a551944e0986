"""A run writes its blueprint; `run --connect` / `--spawn` send each segment with its own ids, the model and the blueprint."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
import rerun as rr
from rerun.chunk import RrdReader

from urdf_pipeline.cli import commands
from urdf_pipeline.errors import UserError
from urdf_pipeline.process import rerun_viewer

from ..dataset_helpers import isolated_examples
from ..local_processes import free_port

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
def listener() -> Iterator[str]:
    """Something that accepts TCP connections on a free port (the check before the run connects, nothing more): its URL."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        yield f"rerun+http://127.0.0.1:{server.getsockname()[1]}/proxy"


@pytest.fixture
def viewer_capture(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> dict[str, object]:
    """A stand-in viewer: what the pipeline sends to it is saved to a file per recording id; --spawn "starts" it."""
    captured: dict[str, object] = {"urls": [], "spawned": 0, "dir": tmp_path / "viewer"}
    (tmp_path / "viewer").mkdir()

    def connect_grpc(self: rr.RecordingStream, url: str | None = None, *, default_blueprint=None) -> None:
        captured["urls"].append(url)  # type: ignore[union-attr]
        self.save(tmp_path / "viewer" / f"{self.get_recording_id()}.rrd", default_blueprint=default_blueprint)

    def spawn_viewer(port: int | None = None) -> str:
        captured["spawned"] = int(captured["spawned"]) + 1  # type: ignore[call-overload]
        return "rerun+http://127.0.0.1:9876/proxy"

    monkeypatch.setattr(rr.RecordingStream, "connect_grpc", connect_grpc)
    monkeypatch.setattr(commands, "spawn_viewer", spawn_viewer)
    return captured


def test_connect_sends_each_segment_with_its_ids_and_the_model(
    examples_dir: Path, tmp_path: Path, run_cli, viewer_capture, listener: str
) -> None:
    config = isolated_examples(examples_dir, tmp_path / "connect")
    result = run_cli("run", str(config), "--episodes", "0:2", "--connect", listener)
    assert result.code == 0, result.err
    assert f"sent 2 segment(s) to the viewer at {listener}" in result.err
    assert viewer_capture["urls"] == [listener] * 2
    for segment in ("episode_000000", "episode_000001"):
        reader = RrdReader(Path(str(viewer_capture["dir"])) / f"{segment}.rrd")
        (recording,) = reader.recordings()
        assert (recording.application_id, recording.recording_id) == ("so101_dataset", segment), "ids kept: layers merge onto their segment"
        assert len(reader.blueprints()) == 1
        entities = {c.entity_path for c in reader.stream().to_chunks()}
        assert "/so101/joint_transforms" in entities and any("/visual_geometries/" in e for e in entities), "the model comes along"


def test_spawn_starts_one_viewer_and_sends_every_segment_to_it(examples_dir: Path, tmp_path: Path, run_cli, viewer_capture) -> None:
    config = isolated_examples(examples_dir, tmp_path / "spawn")
    result = run_cli("run", str(config), "--episodes", "1:4", "--spawn")
    assert result.code == 0, result.err
    assert viewer_capture["spawned"] == 1
    assert viewer_capture["urls"] == ["rerun+http://127.0.0.1:9876/proxy"] * 3


def test_connect_to_no_viewer_is_one_line_and_nothing_is_written(examples_dir: Path, tmp_path: Path) -> None:
    """Nothing listens at the URL: refused before any work, in one line, without Rerun's own ERROR lines (the real
    command, so that Rerun's writes to file descriptor 2 would show)."""
    config = isolated_examples(examples_dir, tmp_path / "nobody")
    url = f"rerun+http://127.0.0.1:{free_port()}/proxy"
    env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
    done = subprocess.run(
        [sys.executable, "-m", "urdf_pipeline", "run", str(config), "--connect", url], capture_output=True, text=True, env=env
    )
    assert done.returncode == 1, done.stderr
    assert done.stderr.splitlines() == [
        f"error: --connect: no Rerun viewer at {url} (127.0.0.1:{url.split(':')[2].split('/')[0]}: Connection refused); "
        f"start one there (`rerun --port {url.split(':')[2].split('/')[0]}`), or use --spawn"
    ]
    assert done.stdout == ""
    assert not (config.parent / "out").exists()


@pytest.mark.parametrize(
    "url",
    [
        "http://127.0.0.1:9876/proxy",  # Rerun's scheme missing
        "rerun+http://127.0.0.1/proxy",  # no port
        "rerun+http://127.0.0.1:98765/proxy",  # no such port
        "rerun+http://127.0.0.1:9876",  # no /proxy
        "rerun+http://:9876/proxy",  # no host
        "127.0.0.1:9876",
        "rerun+http://127.0.0.1:9876/proxy\n::error::forged",
    ],
)
def test_a_url_not_of_the_viewer_form_is_one_line_naming_the_form(examples_dir: Path, tmp_path: Path, run_cli, url: str) -> None:
    config = isolated_examples(examples_dir, tmp_path / "form")
    result = run_cli("run", str(config), "--connect", url)
    assert result.code == 1
    (line,) = result.err.splitlines()
    assert line.startswith("error: --connect: ") and line.endswith(
        "is not a viewer address; expected rerun+http://HOST:PORT/proxy (a viewer started with `rerun` listens at "
        "rerun+http://127.0.0.1:9876/proxy)"
    )
    assert not (config.parent / "out").exists()


def test_spawn_and_connect_together_are_a_usage_error(run_cli) -> None:
    result = run_cli("run", "x.yaml", "--spawn", "--connect", "rerun+http://127.0.0.1:9876/proxy")
    assert result.code == 2 and "not allowed with argument" in result.err


def test_spawn_without_a_screen_is_one_line_and_nothing_is_written(
    examples_dir: Path, tmp_path: Path, run_cli, monkeypatch: pytest.MonkeyPatch
) -> None:
    for name in ("DISPLAY", "WAYLAND_DISPLAY", "WAYLAND_SOCKET"):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setattr(rerun_viewer, "DEFAULT_PORT", free_port())  # no viewer of anyone's there to reuse
    monkeypatch.setattr(rerun_viewer.sys, "platform", "linux")
    config = isolated_examples(examples_dir, tmp_path / "screenless")
    result = run_cli("run", "-q", str(config), "--spawn")
    assert result.code == 1
    assert result.err.splitlines() == [
        "error: --spawn: cannot start the Rerun viewer: no screen here (neither DISPLAY nor WAYLAND_DISPLAY is set); run "
        "`rerun` where there is one and send to it with --connect URL, or run without --spawn and open the written .rrd "
        "files there"
    ]
    assert not (config.parent / "out").exists()


def test_a_viewer_that_cannot_start_is_one_error_with_its_reason(monkeypatch: pytest.MonkeyPatch) -> None:
    """The viewer binary starts, opens its port and exits (an X display that is not there): seen within a second."""
    monkeypatch.setenv("DISPLAY", ":75")  # no X server answers there
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(UserError) as refused:
        rerun_viewer.spawn_viewer(free_port())
    assert refused.value.message.startswith("the Rerun viewer stopped at its start (exit status ")
    assert "X server" in refused.value.message or "display" in refused.value.message.lower(), refused.value.message
    assert "\n" not in refused.value.message and "\x1b" not in refused.value.message


def test_a_viewer_already_listening_is_used_not_started_again(listener: str, monkeypatch: pytest.MonkeyPatch) -> None:
    port = int(listener.split(":")[2].split("/")[0])
    monkeypatch.setattr(rerun_viewer.subprocess, "Popen", None)  # would fail if called
    assert rerun_viewer.spawn_viewer(port) == f"rerun+http://127.0.0.1:{port}/proxy"
