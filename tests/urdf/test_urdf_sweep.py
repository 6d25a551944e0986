"""The URDF sweep: every URDF shipped by example-robot-data and rtb-data through the real CLI, checked against pinocchio.

Each robot gets a config of its own (a generated parquet source; every moving joint in `map` but one in `hold`, the
mimic joints computed by the pipeline), is validated, run (in this process, `--jobs 1`), and its written .rrd is read
back: every link's pose relative to the root link must equal pinocchio's within 1e-5 m / rad (pinocchio builds a
floating base with a fixed root, hence root-relative poses). A robot that `validate` refuses with exit 1 is a refusal;
it must be listed in REFUSED with its reason. Anything else (exit 70, a `run` failing after `validate` said ok, a pose
off by more than the tolerance, a refusal not listed, a listed refusal that now runs) fails.

`python benchmarks/urdf_sweep.py` prints the table robot by robot.
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import re
import time
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest
import yaml

from urdf_pipeline import cli
from urdf_pipeline.examples import example_robot_data_share, write_joint_parquet

from ..reference_fk import PinocchioRobot
from ..rrd_frames import read_frames, rotation_angle

pytestmark = pytest.mark.slow  # every robot of two description packages, through the real CLI

TOLERANCE = 1e-5  # m and rad
FRAMES = 3  # random joint vectors per robot: enough to move every joint, few enough to keep the sweep at minutes

# source -> a fragment of validate's message: the robots `validate` must refuse.
REFUSED = {
    "example-robot-data/ur_description/urdf/ur3.urdf": "the URDF defines no <link>",  # an empty <robot>: pinocchio refuses it too
    "rtb-data/data/test.urdf": "is not valid XML",  # the text "hello": pinocchio refuses it too
    # A typo in the file: the driver is Left_index_q1. Pinocchio ignores <mimic> and builds it as a free joint.
    "example-robot-data/alex_description/urdf/alex_psyonic_hands.urdf": "mimics 'index_q1', which the URDF lacks",
    # Pre-ROS-2 xacro (<property> without the xacro: prefix) that today's xacro cannot expand: no reference either.
    "rtb-data/xacro/kuka_description/kuka_kr210/urdf/kr210l150.xacro": "name 'deg' is not defined",
}
# Refused for a mesh (either refused for a mesh or matching pinocchio); the mesh rules have tests of their own
# (tests/urdf/test_meshes.py). talos_full_v2's package:///example-robot-data/... meshes resolve (as pinocchio reads them).
MESH_REFUSALS = {
    "example-robot-data/romeo_description/urdf/romeo_laas_small.urdf",  # file:///usr/Romeo/...: outside the config's roots
}


@dataclass(frozen=True)
class SweepCase:
    robot: str  # a short label
    source: str  # package/path of the file
    urdf: Any  # the config's `urdf` value: a path, or {xacro: path, args: {...}}
    package_paths: dict[str, str] = field(default_factory=dict)
    xacro: bool = False

    @property
    def file(self) -> Path:
        return Path(self.urdf["xacro"] if self.xacro else self.urdf)


@dataclass(frozen=True)
class Outcome:
    case: SweepCase
    kind: str  # "match" | "refused" | "failure"
    detail: str  # the worst errors, the refusal's message, or what went wrong
    seconds: float

    def row(self) -> str:
        outcome = {"match": "within", "refused": "refused:", "failure": "FAILURE:"}[self.kind]
        detail = self.detail.replace(str(self.case.file), self.case.file.name).replace("|", "\\|")
        return f"| {self.case.robot} | {self.case.source} | {outcome} {detail} | {self.seconds:.1f} |"


def _rtb_root() -> Path | None:
    try:
        import rtbdata
    except ImportError:
        return None
    return Path(rtbdata.__file__).parent


def sweep_cases() -> list[SweepCase]:
    """Every .urdf of example-robot-data and rtb-data, and rtb-data's xacro robots with the args they need."""
    cases: list[SweepCase] = []
    erd = example_robot_data_share() / "robots"
    for path in sorted(erd.glob("**/*.urdf")):
        relative = path.relative_to(erd)
        cases.append(
            SweepCase(f"{relative.parts[0].removesuffix('_description')}/{path.stem}", f"example-robot-data/{relative}", str(path))
        )
    rtb = _rtb_root()
    if rtb is None:
        return cases
    for path in sorted(rtb.glob("**/*.urdf")):
        cases.append(SweepCase(f"rtb/{path.stem}", f"rtb-data/{path.relative_to(rtb)}", str(path), _rtb_packages(path, rtb)))
    for path, args in _rtb_xacro_robots(rtb):
        label = "rtb/" + path.name.removesuffix(".xacro").removesuffix(".urdf")
        urdf = {"xacro": str(path), "args": args} if args else {"xacro": str(path)}
        cases.append(SweepCase(label, f"rtb-data/{path.relative_to(rtb)}", urdf, _rtb_packages(path, rtb), xacro=True))
    return cases


def _rtb_packages(path: Path, rtb: Path) -> dict[str, str]:
    """The ROS packages `path` names (package://, $(find)) -> their folders in rtb-data (some differ in name)."""
    xacro = rtb / "xacro"
    packages = {folder.name: folder for folder in xacro.iterdir() if folder.is_dir()}
    for folder in (xacro / "kuka_description").iterdir():
        packages[folder.name] = packages[f"{folder.name}_support"] = folder  # kuka_kr6_support -> kuka_kr6
    packages["abb_irb140"] = packages["abb_irb140_support"] = xacro / "abb_irb140_description"
    packages["armer_xarm"] = packages["xarm_description"] = rtb / "armer_xarm" / "data"
    packages["ridgeback_description"] = xacro / "clearpath_ridgeback_description"
    found: dict[str, str] = {}
    pending, seen = [path], set()
    while pending:  # the file and the xacro files it includes from the same package tree
        current = pending.pop()
        if current in seen or not current.is_file():
            continue
        seen.add(current)
        text = current.read_text(encoding="utf-8", errors="replace")
        for name, folder in packages.items():
            if f"package://{name}/" in text or f"$(find {name})" in text:
                found[name] = str(folder)
        for include in _includes(text):
            package, _, rest = include.removeprefix("$(find ").partition(")/")
            if include.startswith("$(find ") and package in packages:
                pending.append(packages[package] / rest)
            elif "$(" not in include and "${" not in include:
                pending.append(current.parent / include)
    return found


def _includes(text: str) -> list[str]:
    return [part.split('filename="', 1)[-1].split('"', 1)[0] for part in text.split("<xacro:include")[1:]]


def _rtb_xacro_robots(rtb: Path) -> list[tuple[Path, dict[str, str]]]:
    """rtb-data's xacro files that describe a robot on their own (not macros, materials or accessories)."""
    frankie = rtb / "xacro" / "qut_frankie_description" / "robots"
    trossen = rtb / "xacro" / "trossen_descriptions" / "urdf"
    robots: list[tuple[Path, dict[str, str]]] = []
    for path in sorted(rtb.glob("**/*.xacro")):
        if path.name.endswith("_macro.xacro") or "accessories" in path.parts or "kuka_resources" in path.parts:
            continue
        if path.parent == frankie and not path.name.endswith(".urdf.xacro"):
            continue  # panda_arm.xacro, hand.xacro, ...: macros the .urdf.xacro files include
        robots.append((path, {"robot_name": path.name.split(".")[0]} if path.parent == trossen else {}))
    return robots


@contextlib.contextmanager
def _find_packages(packages: dict[str, str]) -> Iterator[None]:
    """xacro's $(find PKG) asks ament_index, which needs a ROS installation: answer it from `packages`."""
    import xacro.substitution_args as substitution

    original, original_eval = substitution._eval_find, substitution._eval_dict["find"]
    substitution._eval_find = substitution._eval_dict["find"] = lambda package: packages[package]
    try:
        yield
    finally:
        substitution._eval_find, substitution._eval_dict["find"] = original, original_eval


def reference_text(case: SweepCase) -> str:
    """The URDF pinocchio reads: the file itself, or the xacro expanded here by the xacro package (not by the pipeline)."""
    if not case.xacro:
        return case.file.read_text(encoding="utf-8")
    import xacro

    with _find_packages(case.package_paths), contextlib.redirect_stdout(io.StringIO()):
        document = xacro.process_file(str(case.file), mappings=dict(case.urdf.get("args", {})))
    return document.toprettyxml(indent="  ")


@contextlib.contextmanager
def _quiet_fd2() -> Iterator[None]:
    """urdfdom prints its complaints to file descriptor 2: keep them out of the output."""
    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
            yield
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _mimics(text: str) -> dict[str, tuple[str, float, float]]:
    """joint -> (driver, multiplier, offset) from the URDF text (pinocchio builds a mimic joint as a free joint)."""
    found = {}
    for joint in ET.fromstring(text).iter("joint"):
        mimic = joint.find("mimic")
        if mimic is not None and joint.get("type") in ("revolute", "continuous", "prismatic"):
            found[joint.get("name", "")] = (mimic.get("joint", ""), float(mimic.get("multiplier", "1")), float(mimic.get("offset", "0")))
    return found


def _cli(*args: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), _quiet_fd2():
        code = cli.main(list(args))
    return code, out.getvalue(), err.getvalue()


def _first_error(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("error")]
    lines.sort(key=lambda line: "robots.robot.urdf" not in line)  # the URDF's own problem first
    return (lines[0].split("robots.robot.urdf: ", 1)[-1] if lines else err.strip()[-300:])[:300]


def _driven(reference: PinocchioRobot, mimics: dict[str, tuple[str, float, float]]) -> list[str]:
    """Pinocchio's 1-dof joints (revolute, prismatic, continuous) that are not mimics, in model order."""
    model = reference.model
    return [model.names[i] for i in range(1, model.njoints) if model.joints[i].nv == 1 and model.names[i] not in mimics]


def _values(reference: PinocchioRobot, joints: list[str], seed: int) -> np.ndarray:
    """FRAMES x joints values inside each joint's limits (and within +-2 pi rad or m), float32-exact (the parquet stores
    float32)."""
    bounds = []
    for joint in joints:
        lower, upper = reference.limits(joint)
        if reference.model.joints[reference.model.getJointId(joint)].nq == 2 or not (math.isfinite(lower) and math.isfinite(upper)):
            lower, upper = -math.pi, math.pi  # continuous
        # Rerun stores a translation as float32 (a 1e-5 m step from 128 m on): keep joints in a range of everyday poses.
        lower, upper = max(lower, -2 * math.pi), min(upper, 2 * math.pi)
        margin = 0.01 * (upper - lower)
        bounds.append((lower + margin, upper - margin))
    low, high = np.array(bounds, dtype=np.float64).reshape(-1, 2).T
    return np.random.default_rng(seed).uniform(low, high, size=(FRAMES, len(joints))).astype(np.float32).astype(np.float64)


def _write_config(case: SweepCase, name: str, robot_joints: dict[str, Any] | str, names: list[str], directory: Path) -> Path:
    """`robot_joints`: the robot's joints section, or (nothing moves) the root link a probe frame hangs from."""
    robot: dict[str, Any] = {"urdf": case.urdf}
    if case.package_paths:
        robot["package_paths"] = dict(case.package_paths)
    config: dict[str, Any] = {"version": 1}
    config["sources"] = {"q": {"parquet": f"data/{name}.parquet", "column": "observation.state", "index": "frame_index", "names": names}}
    config["robots"] = {"robot": robot}
    if isinstance(robot_joints, dict):
        robot["joints"] = robot_joints
    else:  # nothing moves: the source drives a probe frame under the root link, so the config has a use for it
        config["edges"] = [
            {"parent": robot_joints, "child": "sweep_probe", "source": "q", "translation": names[:3], "quaternion_xyzw": names[3:]}
        ]
    config["output"] = {"path": f"out/{name}.rrd", "application_id": "urdf_sweep", "segment": name}
    path = directory / f"{name}.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


def run_case(case: SweepCase, directory: Path, seed: int = 0) -> Outcome:
    """Validate, run and compare one robot in `directory` (its config, data and output go there)."""
    started = time.perf_counter()
    name = "".join(c if c.isalnum() else "_" for c in case.robot)
    (directory / "data").mkdir(parents=True, exist_ok=True)
    try:
        text = reference_text(case)
        (directory / f"{name}.reference.urdf").write_text(text, encoding="utf-8")
        with _quiet_fd2():
            reference = PinocchioRobot(directory / f"{name}.reference.urdf")
    except Exception as exc:  # a file ROS and pinocchio refuse: the pipeline must refuse it too, not crash
        write_joint_parquet(directory / "data" / f"{name}.parquet", np.zeros((FRAMES, 1)))
        code, _, err = _cli("validate", str(_write_config(case, name, {"source": "q", "map": {"a": "a"}}, ["a"], directory)))
        seconds = time.perf_counter() - started
        if code == 1 and "Traceback" not in err and "robots.robot.urdf: " in err:
            return Outcome(case, "refused", f"{_first_error(err)} (no pinocchio reference either)", seconds)
        problem = f"no pinocchio reference ({str(exc).strip()[:100]}), but validate does not refuse the URDF: exit {code}"
        return Outcome(case, "failure", f"{problem}: {err.strip()[-300:]}", seconds)
    mimics = _mimics(text)
    joints = _driven(reference, mimics)
    values = _values(reference, joints, seed)
    mapped, held = (joints[:-1], joints[-1:]) if len(joints) >= 2 else (joints, [])
    values[:, len(mapped) :] = values[0, len(mapped) :]  # a held joint keeps one value
    if joints:
        prismatic = {j for j in mapped if "P" in reference.model.joints[reference.model.getJointId(j)].shortname()}
        robot_joints = {
            "source": "q",
            "map": {j: ({"joint": j, "unit": "m"} if j in prismatic else j) for j in mapped},
            **({"hold": {j: float(values[0, -1]) for j in held}} if held else {}),
        }
        write_joint_parquet(directory / "data" / f"{name}.parquet", values[:, : len(mapped)])
        config = _write_config(case, name, robot_joints, mapped, directory)
    else:
        probe = np.tile([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0], (FRAMES, 1))
        write_joint_parquet(directory / "data" / f"{name}.parquet", probe)
        config = _write_config(case, name, _root(reference), ["x", "y", "z", "qx", "qy", "qz", "qw"], directory)

    code, _, err = _cli("validate", str(config))
    if code == 1 and "Traceback" not in err:
        return Outcome(case, "refused", _first_error(err), time.perf_counter() - started)
    if code != 0:
        return Outcome(case, "failure", f"validate exit {code}: {err.strip()[-400:]}", time.perf_counter() - started)
    code, out, err = _cli("run", "--jobs", "1", str(config))
    if code != 0:
        return Outcome(case, "failure", f"validate said ok, then run exit {code}: {err.strip()[-400:]}", time.perf_counter() - started)
    kind, detail = _compare(reference, Path(out.strip()), joints, values, mimics)
    return Outcome(case, kind, detail, time.perf_counter() - started)


def _root(reference: PinocchioRobot) -> str:
    return next(frame.name for frame in reference.model.frames if frame.type == pin.FrameType.BODY)  # the URDF's root link


def _compare(
    reference: PinocchioRobot, rrd: Path, joints: list[str], values: np.ndarray, mimics: dict[str, tuple[str, float, float]]
) -> tuple[str, str]:
    frames = read_frames(rrd, "frame_index")
    root = _root(reference)
    worst_position = worst_angle = 0.0
    missing: list[str] = []
    links = 0
    for frame in range(FRAMES):
        q = dict(zip(joints, values[frame], strict=True))
        for _ in range(len(mimics)):  # a mimic may follow another mimic
            q.update({joint: q[driver] * multiplier + offset for joint, (driver, multiplier, offset) in mimics.items() if driver in q})
        expected = reference.link_poses(q)
        links = len(expected)
        for link, pose in expected.items():
            try:
                recorded = frames.world_pose(link, frame, root)
            except KeyError as exc:
                missing.append(f"link '{link}' does not reach root '{root}' in the recording (no edge for {exc})")
                continue
            worst_position = max(worst_position, float(np.linalg.norm(recorded[:3, 3] - pose[:3, 3])))
            worst_angle = max(worst_angle, rotation_angle(recorded, pose))
    detail = f"{worst_position:.1e} m, {worst_angle:.1e} rad ({links} links x {FRAMES} frames)"
    if missing:
        return "failure", f"{missing[0]} ({len(missing)} such)"
    if worst_position > TOLERANCE or worst_angle > TOLERANCE:
        return "failure", f"poses differ from pinocchio's: {detail}"
    return "match", detail


def check_outcome(outcome: Outcome) -> None:
    """The sweep's contract for one robot."""
    case = outcome.case
    assert outcome.kind != "failure", f"{case.source}: {outcome.detail}"
    if case.source in MESH_REFUSALS:
        assert outcome.kind == "match" or "mesh" in outcome.detail, f"{case.source} is refused: {outcome.detail}"
    elif outcome.kind == "refused":
        assert case.source in REFUSED, f"{case.source} is refused: {outcome.detail}"
        assert REFUSED[case.source] in outcome.detail, f"{case.source} is refused for another reason: {outcome.detail}"
    else:
        assert case.source not in REFUSED, f"{case.source} runs now ({outcome.detail}); remove it from REFUSED"


CASES = sweep_cases()


@pytest.fixture(scope="module")
def sweep_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("urdf_sweep")


def test_sweep_covers_both_packages() -> None:
    sources = [case.source for case in CASES]
    assert len(sources) == len(set(sources))
    assert sum(s.startswith("example-robot-data/") for s in sources) >= 60
    assert sum(s.startswith("rtb-data/") and s.endswith(".xacro") for s in sources) >= 30
    assert set(REFUSED) | MESH_REFUSALS <= set(sources)


@pytest.mark.parametrize("case", CASES, ids=[case.robot for case in CASES])
def test_urdf_matches_pinocchio_or_is_refused(case: SweepCase, sweep_dir: Path) -> None:
    check_outcome(run_case(case, sweep_dir))


@pytest.mark.parametrize(
    "robot", ["panda_description/urdf/panda.urdf", "g1_description/urdf/g1_29dof_rev_1_0.urdf", "tiago_description/robots/tiago.urdf"]
)
def test_scaled_axes_give_the_same_poses(robot: str, tmp_path: Path) -> None:
    """URDF axes are directions: every <axis> scaled (by 0.3 to 4.7) must not move a link (pinocchio normalises them)."""
    share = example_robot_data_share()
    text = (share / "robots" / robot).read_text(encoding="utf-8")
    factors = iter(np.linspace(0.3, 4.7, len(re.findall(r"<axis\s+xyz=", text))))

    def scale(match: re.Match[str]) -> str:
        factor = float(next(factors))
        return '<axis xyz="{}"'.format(" ".join(repr(float(v) * factor) for v in match.group(1).split()))

    scaled = re.sub(r'<axis\s+xyz="([^"]*)"', scale, text)
    assert scaled != text
    (tmp_path / "robot.urdf").write_text(scaled, encoding="utf-8")
    case = SweepCase(robot, robot, str(tmp_path / "robot.urdf"), {"example-robot-data": str(share)})
    outcome = run_case(case, tmp_path)
    assert outcome.kind == "match", outcome.detail
