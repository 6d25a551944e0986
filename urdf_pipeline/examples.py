"""Generate the example inputs that `configs/` refers to: robot descriptions from the installed
`example-robot-data` package and joint trajectories within each robot's limits (`make demo`, the tests).

Installed from a wheel, the same command also writes the example configs into DIR: exactly `EXAMPLE_CONFIGS`.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shlex
import shutil
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from .urdf import UrdfModel, read_urdf

PANDA_NAMES = ["j1", "j2", "j3", "j4", "j5", "j6", "j7", "finger"]
SO101_NAMES = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def example_robot_data_share() -> Path:
    """The installed package's share folder (it installs under site-packages/cmeel.prefix)."""
    for entry in map(Path, sys.path):
        candidate = entry / "cmeel.prefix" / "share" / "example-robot-data"
        if (candidate / "robots").is_dir():
            return candidate
    raise SystemExit('example-robot-data is not installed: pip install "urdf-pipeline[demo]" (or pip install example-robot-data)')


def smooth_trajectory(model: UrdfModel, joints: list[str], frames: int, seed: int) -> np.ndarray:
    """Sinusoids inside each joint's limits (URDF units), one column per joint."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 30.0
    lower = np.array([model.joint(j).lower for j in joints])  # type: ignore[union-attr]
    upper = np.array([model.joint(j).upper for j in joints])  # type: ignore[union-attr]
    middle, half = (lower + upper) / 2, (upper - lower) / 2 * 0.8
    phase = rng.uniform(0, 2 * math.pi, len(joints))
    speed = rng.uniform(0.2, 0.6, len(joints))
    return middle + half * np.sin(2 * math.pi * speed * t + phase)


def panda_raw_values(frames: int, panda: UrdfModel, seed: int = 0) -> np.ndarray:
    """Panda values in the contract config's units: degrees, j2 negated, j3 offset 0.1 rad, finger in mm."""
    joints = [f"panda_joint{i}" for i in range(1, 8)] + ["panda_finger_joint1"]
    q = smooth_trajectory(panda, joints, frames, seed)
    raw = np.degrees(q[:, :7])
    raw[:, 1] = -raw[:, 1]
    raw[:, 2] = np.degrees(q[:, 2] - 0.1)
    return np.concatenate([raw, q[:, 7:8] * 1000.0], axis=1)


def write_joint_parquet(path: Path, values: np.ndarray, column: str = "observation.state") -> None:
    frames, width = values.shape
    path.parent.mkdir(parents=True, exist_ok=True)
    table = pa.table(
        {
            "frame_index": pa.array(np.arange(frames), pa.int64()),
            "timestamp": pa.array(np.arange(frames) / 30.0, pa.float64()),
            column: pa.FixedSizeListArray.from_arrays(pa.array(values.astype(np.float32).reshape(-1)), width),
        }
    )
    pq.write_table(table, path)


LEROBOT_CHUNK_SIZE = 1000  # episodes per data/chunk-NNN folder, as LeRobot v2.1 writes them


def write_lerobot_dataset(root: Path, episodes: np.ndarray | list[np.ndarray], names: list[str], fps: int = 30) -> None:
    """A minimal LeRobot v2.1 dataset without videos: one parquet file per episode (one array of values each), in the
    chunk folder info.json's `chunks_size` puts it (Rerun's reader refuses a dataset with episode 1000 in chunk-000)."""
    episodes = [episodes] if isinstance(episodes, np.ndarray) else episodes
    (root / "meta").mkdir(parents=True, exist_ok=True)
    width = episodes[0].shape[1]
    first_index = 0
    for episode, values in enumerate(episodes):
        frames = len(values)
        data = root / "data" / f"chunk-{episode // LEROBOT_CHUNK_SIZE:03d}" / f"episode_{episode:06d}.parquet"
        data.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(
            pa.table(
                {
                    "observation.state": pa.FixedSizeListArray.from_arrays(pa.array(values.astype(np.float32).reshape(-1)), width),
                    "timestamp": pa.array(np.arange(frames) / fps, pa.float32()),
                    "frame_index": pa.array(np.arange(frames), pa.int64()),
                    "episode_index": pa.array(np.full(frames, episode), pa.int64()),
                    "index": pa.array(first_index + np.arange(frames), pa.int64()),
                    "task_index": pa.array(np.zeros(frames), pa.int64()),
                }
            ),
            data,
        )
        first_index += frames
    scalar = {"dtype": "int64", "shape": [1], "names": None}
    info = {
        "codebase_version": "v2.1",
        "robot_type": "so101",
        "total_episodes": len(episodes),
        "total_frames": first_index,
        "total_tasks": 1,
        "total_videos": 0,
        "total_chunks": -(-len(episodes) // LEROBOT_CHUNK_SIZE),
        "chunks_size": LEROBOT_CHUNK_SIZE,
        "fps": fps,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet",
        "video_path": None,
        "features": {
            "observation.state": {"dtype": "float32", "shape": [width], "names": names},
            "timestamp": {"dtype": "float32", "shape": [1], "names": None},
            "frame_index": scalar,
            "episode_index": scalar,
            "index": scalar,
            "task_index": scalar,
        },
    }
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=2))
    lines = [json.dumps({"episode_index": e, "tasks": ["wave"], "length": len(v)}) for e, v in enumerate(episodes)]
    (root / "meta" / "episodes.jsonl").write_text("\n".join(lines) + "\n")
    (root / "meta" / "tasks.jsonl").write_text(json.dumps({"task_index": 0, "task": "wave"}) + "\n")


UR5_JOINTS = ["shoulder_pan_joint", "shoulder_lift_joint", "elbow_joint", "wrist_1_joint", "wrist_2_joint", "wrist_3_joint"]
JOINT_STATE_MSGDEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


def write_ros2_bag(path: Path, names: list[str], q: np.ndarray, hz: float = 100.0) -> bool:
    """A ROS 2 bag (MCAP, CDR) with sensor_msgs/msg/JointState on /joint_states, names in a shuffled order per message,
    as robot drivers publish them. Needs mcap-ros2-support (a test dependency); returns False without it."""
    try:
        from mcap_ros2.writer import Writer
    except ImportError:
        return False
    rng = np.random.default_rng(5)
    start_ns, step_ns = 1_700_000_000_000_000_000, int(1e9 / hz)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("wb") as stream:
        writer = Writer(stream)
        schema = writer.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        for row, values in enumerate(q):
            order = rng.permutation(len(names))
            stamp = start_ns + row * step_ns
            message = {
                "header": {"stamp": {"sec": stamp // 10**9, "nanosec": stamp % 10**9}, "frame_id": ""},
                "name": [names[i] for i in order],
                "position": [float(values[i]) for i in order],
                "velocity": [],
                "effort": [],
            }
            writer.write_message("/joint_states", schema, message, log_time=stamp + 2_000_000, publish_time=stamp + 2_000_000)
        writer.finish()
    return True


G1_ARM_NAMES = [
    f"k{side}{joint}"
    for side in ("Left", "Right")
    for joint in ("ShoulderPitch", "ShoulderRoll", "ShoulderYaw", "Elbow", "WristRoll", "WristPitch", "WristYaw")
]
G1_HAND_NAMES = [
    f"k{side}Hand{finger}" for side in ("Left", "Right") for finger in ("Pinky", "Ring", "Middle", "Index", "ThumbBend", "ThumbRotation")
]


def g1_arm_joints() -> list[str]:
    """The G1 URDF joints of G1_ARM_NAMES, in the same order (kLeftShoulderPitch -> left_shoulder_pitch_joint)."""
    import re

    return [re.sub(r"(?<!^)([A-Z])", r"_\1", name[1:]).lower() + "_joint" for name in G1_ARM_NAMES]


VX300S_ARM = ["waist", "shoulder", "elbow", "forearm_roll", "wrist_angle", "wrist_rotate"]
VX300S_LIMITS = [(-3.14, 3.14), (-1.85, 1.76), (-1.6, 1.76), (-3.14, 3.14), (-2.26, 1.86), (-3.14, 3.14)]


def aloha_qpos(frames: int, seed: int = 4) -> np.ndarray:
    """ALOHA's /observations/qpos: per arm six joint angles (rad) then the gripper normalised to 0..1; left arm first."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / 50.0
    lower, upper = np.array(VX300S_LIMITS).T

    def arm() -> np.ndarray:
        middle, half = (lower + upper) / 2, (upper - lower) / 2 * 0.5
        angles = middle + half * np.sin(2 * math.pi * rng.uniform(0.1, 0.4, 6) * t + rng.uniform(0, 2 * math.pi, 6))
        gripper = 0.5 + 0.45 * np.sin(2 * math.pi * 0.3 * t + rng.uniform(0, 2 * math.pi))
        return np.concatenate([angles, gripper], axis=1)

    return np.concatenate([arm(), arm()], axis=1)


def write_aloha_episode(path: Path, qpos: np.ndarray) -> None:
    """An ALOHA-layout episode: /observations/qpos and /observations/qvel [N, 14], /action [N, 14]."""
    import h5py

    path.parent.mkdir(parents=True, exist_ok=True)
    with h5py.File(path, "w") as file:
        file.attrs["sim"] = False
        file.create_dataset("/observations/qpos", data=qpos)
        file.create_dataset("/observations/qvel", data=np.gradient(qpos, axis=0) * 50.0)
        file.create_dataset("/action", data=qpos)


def _rtb_xacro() -> Path | None:
    """The rtb-data package's xacro descriptions (Trossen/Interbotix arms), when installed."""
    try:
        import rtbdata
    except ImportError:
        return None
    return Path(rtbdata.__file__).parent / "xacro"


def _link(link: Path, target: Path) -> None:
    if link.is_symlink() or link.exists():
        if link.is_symlink() and link.resolve() == target.resolve():
            return
        link.unlink() if link.is_symlink() or link.is_file() else shutil.rmtree(link)
    link.parent.mkdir(parents=True, exist_ok=True)
    link.symlink_to(target, target_is_directory=True)


MISSING_EXTRAS = {  # config -> (what it needs, the package that provides it): the inputs prepare cannot make without it
    "aloha_bimanual.yaml": ("robots/rtbdata (the ViperX xacro)", "rtb-data"),
    "ur5_ros2_bag.yaml": ("data/ur5_joint_states.mcap", "mcap-ros2-support"),
}


def prepare(directory: Path, frames: int = 900) -> list[str]:
    """Create directory/robots and directory/data as the example configs expect them. Returns the configs whose inputs
    could not be made because an optional package is missing (one line each, naming the package)."""
    missing: list[str] = []
    share = example_robot_data_share()
    robots = directory / "robots"
    _link(robots / "share" / "example-robot-data", share)
    panda_urdf = share / "robots" / "panda_description" / "urdf" / "panda.urdf"
    shutil.copyfile(panda_urdf, robots / "panda.urdf")
    _, panda = read_urdf(panda_urdf)
    write_joint_parquet(directory / "data" / "episode_000.parquet", panda_raw_values(frames, panda))
    left, right = panda_raw_values(frames, panda, seed=1), panda_raw_values(frames, panda, seed=2)
    write_joint_parquet(directory / "data" / "bimanual_000.parquet", np.concatenate([left, right], axis=1))
    rtb = _rtb_xacro()
    if rtb is not None:
        _link(robots / "rtbdata", rtb)
    else:
        missing.append("aloha_bimanual.yaml")
    for episode in range(3):  # ALOHA records one HDF5 file per episode
        write_aloha_episode(directory / "data" / "aloha" / f"episode_{episode}.hdf5", aloha_qpos(frames // (episode + 1), seed=4 + episode))
    _, so101 = read_urdf(share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    so101_episodes = [np.degrees(smooth_trajectory(so101, SO101_NAMES, frames // (e + 1), seed=3 + e)) for e in range(4)]
    write_lerobot_dataset(directory / "data" / "so101_lerobot", so101_episodes, SO101_NAMES)
    ur5_urdf = share / "robots" / "ur_description" / "urdf" / "ur5_robot.urdf"
    _, ur5 = read_urdf(ur5_urdf)
    if not write_ros2_bag(directory / "data" / "ur5_joint_states.mcap", UR5_JOINTS, smooth_trajectory(ur5, UR5_JOINTS, frames, seed=8)):
        missing.append("ur5_ros2_bag.yaml")
    _, g1 = read_urdf(share / "robots" / "g1_description" / "urdf" / "g1_29dof_rev_1_0.urdf")
    g1_episodes = []
    for episode in range(2):  # like the real G1 recording: 14 arm joints in radians, then 12 hand values in 0..1
        arms = smooth_trajectory(g1, g1_arm_joints(), frames // (episode + 1), seed=9 + episode)
        hands = np.clip(0.5 + 0.4 * np.sin(np.arange(len(arms))[:, None] / 20.0 + np.arange(12)), 0.0, 1.0)
        g1_episodes.append(np.concatenate([arms, hands], axis=1))
    write_lerobot_dataset(directory / "data" / "g1_lerobot", g1_episodes, G1_ARM_NAMES + G1_HAND_NAMES)
    return [f"{config}: not prepared, {MISSING_EXTRAS[config][0]} needs pip install {MISSING_EXTRAS[config][1]}" for config in missing]


# The shipped example configs, by name: the folder they come from may hold more (a checkout's configs/ holds what its
# user added there; a wheel built from such a checkout carries it too). tests/cli/test_examples.py checks this list
# against the configs git tracks and the wheel's package data.
EXAMPLE_CONFIGS = (
    "aloha_bimanual.yaml",
    "bimanual_pandas.yaml",
    "demo.yaml",
    "g1_held_joints.yaml",
    "so101_dataset.yaml",
    "so101_lerobot.yaml",
    "ur5_ros2_bag.yaml",
)


def example_configs() -> Path:
    """The folder of the shipped example configs: in a wheel, urdf_pipeline/example_configs; in a checkout, its configs/."""
    packaged = Path(__file__).parent / "example_configs"
    return packaged if packaged.is_dir() else Path(__file__).resolve().parent.parent / "configs"


def copy_configs(directory: Path) -> list[str]:
    """Write the example configs (`EXAMPLE_CONFIGS`, nothing else) into `directory`, their schema line pointing where
    it resolves from there. A config already there and edited is kept (the lines say which); nothing to do when
    `directory` is their own folder."""
    from .scaffold import schema_reference

    source = example_configs()
    if directory.resolve() == source.resolve():
        return []
    directory.mkdir(parents=True, exist_ok=True)
    schema_line = f"# yaml-language-server: $schema={schema_reference(directory)}"
    said = []
    for config in (source / name for name in EXAMPLE_CONFIGS):
        if not config.is_file():  # a checkout whose user deleted one: the others are still written
            said.append(f"{config}: missing from the installed examples; not written")
            continue
        lines = config.read_text(encoding="utf-8").splitlines(keepends=True)
        if lines and lines[0].startswith("# yaml-language-server: $schema="):
            lines[0] = schema_line + "\n"
        text, target = "".join(lines), directory / config.name
        if target.exists() and target.read_text(encoding="utf-8") != text:
            said.append(f"{target}: kept as it is (it differs from the example; delete it to get the example back)")
        elif not target.exists():
            target.write_text(text, encoding="utf-8")
    return said


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m urdf_pipeline.examples",
        description="Write the example configs (from a wheel; a checkout has them in configs/) and their inputs into "
        "DIR: robot descriptions linked from example-robot-data and rtb-data, joint data as parquet, LeRobot, HDF5 and "
        "MCAP. Then: urdf-pipeline run DIR/demo.yaml (the command's last line says how to call it here). The inputs need the [demo] extra: pip install "
        '"urdf-pipeline[demo]".',
    )
    parser.add_argument("directory", nargs="?", default="configs", metavar="DIR", help="where they go (default: configs)")
    parser.add_argument("--frames", type=int, default=900, help="frames per generated episode (default 900)")
    args = parser.parse_args(argv)
    if args.frames < 1:
        parser.error("--frames must be at least 1")
    directory = Path(args.directory)
    if directory.exists() and not directory.is_dir():
        parser.error(f"{directory} is not a folder")
    for line in copy_configs(directory) + prepare(directory, args.frames):
        print(f"urdf_pipeline.examples: {line}", file=sys.stderr)
    print(f"urdf_pipeline.examples: ready; try: {cli_command()} run {shlex.quote(str(directory / 'demo.yaml'))}", file=sys.stderr)
    return 0


def cli_command() -> str:
    """How to call the CLI of this interpreter's environment, as the user can type it here: `urdf-pipeline` when that
    is what PATH finds, else the script beside the interpreter (`.venv/bin/urdf-pipeline`: `make demo` runs with no
    venv activated), else `PYTHON -m urdf_pipeline`."""
    bin_dir = Path(sys.executable).parent  # not resolved: a venv's python is a link to the base interpreter
    script = bin_dir / "urdf-pipeline"
    if not (script.is_file() and os.access(script, os.X_OK)):
        return f"{shlex.quote(_shown_path(Path(sys.executable)))} -m urdf_pipeline"
    found = shutil.which("urdf-pipeline")
    if found is not None and Path(found).resolve() == script.resolve():
        return "urdf-pipeline"
    return shlex.quote(_shown_path(script))


def _shown_path(path: Path) -> str:
    """Relative to the current folder when it is inside it (`.venv/bin/...`), else absolute."""
    absolute = Path(os.path.abspath(path))
    try:
        return str(absolute.relative_to(Path.cwd()))
    except ValueError:
        return str(absolute)


if __name__ == "__main__":
    sys.exit(main())
