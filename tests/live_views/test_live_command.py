"""`urdf-pipeline live` and `validate --live`: what is refused before anything is subscribed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.process import viewer_binary

from ..execute.test_fk_against_pinocchio import check_robot
from ..local_processes import free_port, stop
from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames
from .follow_motion import header_ns, log_time_ns, position
from .joint_motion import stamp_ns as motion_stamp
from .joint_motion import values as motion_values


def test_validate_live_notes_names_from_the_stream(examples_dir: Path, run_cli) -> None:
    result = run_cli("validate", "--live", str(examples_dir / "ur5_ros2_bag.yaml"))
    assert result.code == 0, result.err
    assert "note:" in result.err and "live takes them from the first message on its topic" in result.err


def test_validate_live_refuses_a_source_no_stream_carries(examples_dir: Path, run_cli) -> None:
    result = run_cli("validate", "--live", "--format", "github", str(examples_dir / "demo.yaml"))
    assert result.code == 1
    assert "::error file=" in result.out and "source 'arm_state' is a parquet source" in result.out


def test_live_refuses_before_it_connects(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    saved = tmp_path / "never.rrd"
    result = run_cli("live", str(examples_dir / "demo.yaml"), "--from", "ws://127.0.0.1:9", "--save", str(saved))
    assert result.code == 1
    lines = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1 and "sources.arm_state: live --from streams ROS 2 JointState topics" in lines[0], result.err
    assert not saved.exists() and not list(tmp_path.iterdir())


def test_live_refuses_a_url_it_cannot_follow(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    result = run_cli("live", str(examples_dir / "ur5_ros2_bag.yaml"), "--from", "http://robot:8765", "--save", str(tmp_path / "x.rrd"))
    assert result.code == 1
    assert "error: --from: http://robot:8765: live --from takes ws://HOST:PORT" in result.err, result.err
    assert not list(tmp_path.iterdir())


UR5 = {
    "shoulder_pan": "shoulder_pan_joint",
    "shoulder_lift": "shoulder_lift_joint",
    "elbow": "elbow_joint",
    "wrist_1": "wrist_1_joint",
    "wrist_2": "wrist_2_joint",
    "gripper": "wrist_3_joint",  # follow_motion's sixth name
}


def live_config(examples_dir: Path, name: str, timeline: str = "header") -> Path:
    """The UR5 bag config with the test streams' names mapped, its bag absent: live reads only the stream."""
    data = yaml.safe_load((examples_dir / "ur5_ros2_bag.yaml").read_text())
    data["sources"]["joint_states"] = {"mcap": "data/not_recorded_yet.mcap", "topic": "/joint_states", "timeline": timeline}
    data["robots"]["ur5"]["joints"]["map"] = UR5
    data["output"]["segment"] = name
    path = examples_dir / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def check_ur5(saved: Path, examples_dir: Path, timeline: str, stamps: list[int], ks: list[int], seed: int = 0) -> None:
    """Poses composed from the saved recording equal pinocchio's at follow_motion's values for messages `ks`."""
    reference = PinocchioRobot(examples_dir / "robots/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    frames = read_frames(saved, timeline)
    root = reference.model.frames[1].name
    values = {k: {UR5[j]: position(j, k, seed) for j in UR5} for k in ks}
    compared = check_robot(frames, {k: stamps[i] for i, k in enumerate(ks)}, reference, values, "", np.eye(4), root, ks)
    assert compared == len(ks) * len(reference.link_poses({}))


def test_live_follows_a_growing_bag_until_its_writer_closes_it(examples_dir: Path, run_cli, tmp_path: Path, appender) -> None:
    config = live_config(examples_dir, "live_follow")
    bag, saved = tmp_path / "growing.mcap", tmp_path / "take.rrd"
    appender(bag, "--count", "300", "--rate", "1000", "--other-every", "7")
    result = run_cli("live", str(config), "--from", str(bag), "--save", str(saved))
    assert result.code == 0, result.err
    assert "was closed by its writer after 300 messages" in result.err
    assert "live: 300 samples in" in result.err and "300 sent (the stream ended)" in result.err and "99th percentile" in result.err
    ks = [0, 1, 150, 299]
    check_ur5(saved, examples_dir, "ros2_timestamp", [header_ns(k) for k in ks], ks)
    assert len(read_frames(saved, "ros2_timestamp").temporal["shoulder_link"]) == 300
    assert {p.name for p in tmp_path.iterdir()} == {"growing.mcap", "take.rrd"}  # no partial file left


def test_live_places_samples_by_their_log_time_when_asked(examples_dir: Path, run_cli, tmp_path: Path, appender) -> None:
    """Also: a second take saved over the first (a recording live wrote: its own) replaces it; a stranger's is kept."""
    config = live_config(examples_dir, "live_log_time", timeline="log_time")
    bag, saved = tmp_path / "log_time.mcap", tmp_path / "take.rrd"
    saved.write_bytes((examples_dir / "data" / "ur5_joint_states.mcap").read_bytes())  # somebody's file at the name
    appender(bag, "--count", "40").wait()
    refused = run_cli("live", str(config), "--from", str(bag), "--save", str(saved))
    assert refused.code == 1 and "urdf-pipeline never overwrites a file it did not write" in refused.err, refused.err
    saved.unlink()
    for _ in range(2):
        result = run_cli("live", str(config), "--from", str(bag), "--save", str(saved))
        assert result.code == 0, result.err
    ks = [0, 39]
    check_ur5(saved, examples_dir, "message_log_time", [log_time_ns(k) for k in ks], ks)


def test_a_map_naming_a_joint_the_stream_lacks_is_refused_at_the_first_message(
    examples_dir: Path, run_cli, tmp_path: Path, appender
) -> None:
    config = live_config(examples_dir, "live_missing")
    text = config.read_text().replace("gripper:", "wrist_3:")
    config.write_text(text)
    bag, saved = tmp_path / "short.mcap", tmp_path / "take.rrd"
    appender(bag, "--count", "20")
    result = run_cli("live", str(config), "--from", str(bag), "--save", str(saved))
    assert result.code == 1
    errors = [line for line in result.err.splitlines() if line.startswith("error:")]
    assert errors and "wrist_3" in errors[0], result.err
    assert not saved.exists() and {p.name for p in tmp_path.iterdir()} == {"short.mcap"}


@pytest.mark.parametrize(("signum", "said"), [(signal.SIGTERM, "stopped by SIGTERM"), (signal.SIGINT, "stopped by Ctrl-C")])
def test_a_signal_ends_live_cleanly_with_a_complete_recording(
    examples_dir: Path, tmp_path: Path, appender, signum: signal.Signals, said: str
) -> None:
    config = live_config(examples_dir, f"live_{signum.name}")
    bag, saved = tmp_path / "endless.mcap", tmp_path / "take.rrd"
    appender(bag, "--count", "100000", "--rate", "200", "--no-footer")
    command = [sys.executable, "-m", "urdf_pipeline", "live", str(config), "--from", str(bag), "--save", str(saved)]
    env = {**os.environ, "URDF_PIPELINE_ALLOW_PATHS": str(examples_dir)}
    child = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, env=env)
    assert child.stderr is not None
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".take.rrd.partial-*")):  # the recording starts with the first message's views
        assert time.monotonic() < deadline and child.poll() is None
        time.sleep(0.05)
    time.sleep(1.0)  # samples flow meanwhile
    child.send_signal(signum)
    rest = child.stderr.read()
    assert child.wait(timeout=60) == 128 + signum, rest  # stopped, not ended: 130 or 143, as every command
    assert said in rest, rest
    sent = int(rest.split(" sent (")[0].rsplit(", ", 1)[1])
    assert sent > 50
    frames = read_frames(saved, "ros2_timestamp")
    assert len(frames.temporal["shoulder_link"]) == sent  # every sample sent is in the file, which reads to its end
    assert {p.name for p in tmp_path.iterdir()} == {"endless.mcap", "take.rrd"}


UR5_JOINTS = ("shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint")


def ws_config(examples_dir: Path, name: str) -> Path:
    """The UR5 bag config as written (its map names the UR5's joints), its bag absent: names from the first message."""
    data = yaml.safe_load((examples_dir / "ur5_ros2_bag.yaml").read_text())
    data["sources"]["joint_states"]["mcap"] = "data/not_recorded_yet.mcap"
    data["output"]["segment"] = name
    path = examples_dir / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


class LiveChild:
    """`urdf-pipeline live` in a child process, its stderr read line by line (for the lines a test waits for)."""

    def __init__(self, examples_dir: Path, *arguments: str) -> None:
        command = [sys.executable, "-m", "urdf_pipeline", "live", *arguments]
        env = {**os.environ, "URDF_PIPELINE_ALLOW_PATHS": str(examples_dir)}
        self.process = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, env=env)
        self.lines: list[str] = []

    def wait_for(self, text: str, seconds: float = 60.0) -> str:
        assert self.process.stderr is not None
        deadline = time.monotonic() + seconds
        for line in self.process.stderr:
            self.lines.append(line)
            if text in line:
                return line
            assert time.monotonic() < deadline, "".join(self.lines)
        raise AssertionError(f"live ended without {text!r}:\n{''.join(self.lines)}")

    def stop(self) -> tuple[int, str]:
        """SIGTERM, then its exit status and the rest of its stderr."""
        assert self.process.stderr is not None
        self.process.send_signal(signal.SIGTERM)
        rest = self.process.stderr.read()
        code = self.process.wait(timeout=60)
        self.process.stderr.close()
        return code, "".join(self.lines) + rest


def check_ur5_ws(saved: Path, examples_dir: Path, ks: list[int], period_ns: int) -> None:
    """Poses in the saved recording equal pinocchio's at joint_motion's values for messages `ks`."""
    reference = PinocchioRobot(examples_dir / "robots/share/example-robot-data/robots/ur_description/urdf/ur5_robot.urdf")
    frames = read_frames(saved, "ros2_timestamp")
    root = reference.model.frames[1].name
    values = {k: dict(zip(UR5_JOINTS, motion_values(k, UR5_JOINTS), strict=True)) for k in ks}
    stamps = {k: motion_stamp(k, period_ns) for k in ks}
    assert check_robot(frames, stamps, reference, values, "", np.eye(4), root, ks) == len(ks) * len(reference.link_poses({}))


def test_live_records_a_foxglove_server_and_survives_its_restart(examples_dir: Path, tmp_path: Path, foxglove_server) -> None:
    """A real foxglove-sdk server publishes 150 messages at 500 Hz, stops, and comes back on the same port with
    150 more: live says so in a line each, and the saved recording holds all 300, each pose equal to pinocchio's."""
    names = ",".join(UR5_JOINTS)
    server = foxglove_server("--rate", "500", "--count", "150", "--names", names, "--exit-when-done")
    saved = tmp_path / "take.rrd"
    live = LiveChild(examples_dir, str(ws_config(examples_dir, "live_ws")), "--from", server.url, "--save", str(saved))
    live.wait_for("reconnecting in")  # the server published its 150 and went away
    foxglove_server("--rate", "500", "--count", "150", "--first", "150", "--names", names, "--exit-when-done", port=server.port)
    live.wait_for("reconnected to")
    live.wait_for("reconnecting in")  # the second run published its 150 too
    code, err = live.stop()
    assert code == 143, err  # SIGTERM stopped it: 128 + 15
    assert "300 sent (stopped by SIGTERM)" in err, err
    assert {p.name for p in tmp_path.iterdir()} == {"take.rrd"}
    assert len(read_frames(saved, "ros2_timestamp").temporal["shoulder_link"]) == 300
    check_ur5_ws(saved, examples_dir, [0, 1, 149, 150, 299], period_ns=2_000_000)


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # rerun --save writes the stream as it comes, no footer
def test_live_connects_to_a_running_rerun_server(examples_dir: Path, tmp_path: Path, foxglove_server) -> None:
    """`--connect`: Rerun's own gRPC server (`rerun --save`, which writes what reaches it) receives what `--save` holds."""
    port = free_port()
    received = tmp_path / "received.rrd"
    binary = viewer_binary("start a Rerun server")  # the binary itself: `python -m rerun` would leave it running when the shim is stopped
    assert binary is not None
    command = [binary, "--bind", "127.0.0.1", "--port", str(port), "--save", str(received)]
    viewer = subprocess.Popen(command, stderr=subprocess.DEVNULL)
    try:
        server = foxglove_server("--rate", "200", "--count", "50", "--names", ",".join(UR5_JOINTS), "--exit-when-done")
        url = f"rerun+http://127.0.0.1:{port}/proxy"
        deadline = time.monotonic() + 60
        while not received.exists():  # rerun --save opens its file once it serves
            assert time.monotonic() < deadline and viewer.poll() is None
            time.sleep(0.05)
        saved = tmp_path / "take.rrd"
        live = LiveChild(
            examples_dir, str(ws_config(examples_dir, "live_connect")), "--from", server.url, "--connect", url, "--save", str(saved)
        )
        live.wait_for("reconnecting in")  # the server published its 50 and went away
        code, err = live.stop()
        assert code == 143 and "50 sent" in err, err
    finally:
        stop(viewer)
    assert len(read_frames(received, "ros2_timestamp").temporal["shoulder_link"]) == 50
    check_ur5_ws(received, examples_dir, [0, 49], period_ns=5_000_000)
