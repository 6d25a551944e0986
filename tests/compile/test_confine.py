"""The read rule (urdf_pipeline/confine.py) and where compile applies it: URDF, package_paths, sources, globs, sidecars."""

from __future__ import annotations

import sysconfig
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.confine import ALLOW_ENV, confinement_for
from urdf_pipeline.errors import UserError
from urdf_pipeline.examples import write_joint_parquet

ROOT_ENVS = ("ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH", "ROBOT_DESCRIPTIONS_CACHE", ALLOW_ENV)


@pytest.fixture
def clean_env(monkeypatch: pytest.MonkeyPatch) -> pytest.MonkeyPatch:
    for name in ROOT_ENVS:
        monkeypatch.delenv(name, raising=False)
    return monkeypatch


def test_reads_stay_under_the_config_folder(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    rule = confinement_for(tmp_path / "pr" / "c.yaml")
    assert rule.may_read(tmp_path / "pr" / "robots" / "r.urdf")
    assert rule.may_read(tmp_path / "pr" / "no_such_file.stl")  # the rule is about places, not existence
    assert not rule.may_read(tmp_path / "other" / "r.urdf")
    assert not rule.may_read(tmp_path / "pr" / ".." / "other" / "r.urdf")
    assert not rule.may_read(Path("/etc/hostname"))


def test_a_config_in_a_git_work_tree_reads_the_whole_work_tree(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    """configs/ beside robots/ and data/ in one repository: reads span the work tree (never .git), writes do not."""
    repo = tmp_path / "repo"
    (repo / ".git").mkdir(parents=True)
    rule = confinement_for(repo / "configs" / "c.yaml")
    assert rule.may_read(repo / "robots" / "r.urdf") and rule.may_read(repo / "data" / "e.parquet")
    assert not rule.may_read(repo / ".git" / "config")
    assert not rule.may_read(tmp_path / "elsewhere" / "r.urdf")
    assert rule.may_write(repo / "configs" / "out" / "e.rrd") and not rule.may_write(repo / "out" / "e.rrd")
    with pytest.raises(UserError) as error:
        rule.check_read(tmp_path / "elsewhere" / "r.urdf", "URDF file", None)
    assert f"is outside the config's git work tree or a declared package root ({repo.resolve()})" in error.value.message


@pytest.mark.parametrize("variable", ["ROS_PACKAGE_PATH", "AMENT_PREFIX_PATH", "ROBOT_DESCRIPTIONS_CACHE", ALLOW_ENV])
def test_the_environment_declares_more_roots(variable: str, tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    config, root = tmp_path / "pr" / "c.yaml", tmp_path / "declared"
    assert not confinement_for(config).may_read(root / "x.stl")
    clean_env.setenv(variable, str(root))
    assert confinement_for(config).may_read(root / "x.stl")
    assert confinement_for(config).may_write(root / "x.rrd") == (variable == ALLOW_ENV)  # only the opt-in allows writes


def test_site_packages_is_a_package_root(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    site = Path(sysconfig.get_paths()["purelib"])
    assert confinement_for(tmp_path / "c.yaml").may_read(site / "cmeel.prefix" / "share" / "example-robot-data" / "x.stl")


def test_symlinks_are_followed(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    (tmp_path / "pr").mkdir()
    (tmp_path / "secret").write_text("s")
    (tmp_path / "pr" / "link.stl").symlink_to(tmp_path / "secret")
    rule = confinement_for(tmp_path / "pr" / "c.yaml")
    assert not rule.may_read(tmp_path / "pr" / "link.stl")
    with pytest.raises(UserError, match=r"mesh .*link.stl \(resolves to .*secret\) is outside the config's folder"):
        rule.check_read(tmp_path / "pr" / "link.stl", "mesh", None)


def test_git_folders_are_never_read_even_when_allowed(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    clean_env.setenv(ALLOW_ENV, str(tmp_path))
    rule = confinement_for(tmp_path / "c.yaml")
    assert not rule.may_read(tmp_path / ".git" / "config")
    with pytest.raises(UserError, match="is inside a .git folder, which a config may never read"):
        rule.check_read(tmp_path / ".git" / "config", "edges file", None)


# End to end: every path a config names goes through the rule at compile time (validate, plan and diff refuse too).

ARM = '<robot name="r"><link name="base"/><link name="arm"/><joint name="j1" type="continuous"><parent link="base"/><child link="arm"/><axis xyz="0 0 1"/></joint></robot>'


def write_config(directory: Path, *, urdf: str = "r.urdf", parquet: str = "d.parquet", **extra: object) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "r.urdf").write_text(ARM, encoding="utf-8")
    write_joint_parquet(directory / "d.parquet", np.zeros((3, 1)))
    config: dict[str, object] = {
        "version": 1,
        "sources": {"s": {"parquet": parquet, "column": "observation.state", "index": "frame_index", "names": ["j"]}},
        "robots": {"arm": {"urdf": urdf, "joints": {"source": "s", "map": {"j": "j1"}}}},
        "output": {"path": "out/{segment}.rrd", "application_id": "x", "segment": "{stem}" if "*" in parquet else "x"},
        **extra,
    }
    path = directory / "c.yaml"
    path.write_text(yaml.safe_dump(config, sort_keys=False), encoding="utf-8")
    return path


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A folder beside the config's: a URDF, a parquet file and an edges file a config may not read by default."""
    folder = tmp_path / "shared"
    folder.mkdir()
    (folder / "r.urdf").write_text(ARM, encoding="utf-8")
    write_joint_parquet(folder / "d.parquet", np.zeros((3, 1)))
    (folder / "edges.yaml").write_text(
        "- {parent: world, child: base, translation: [0, 0, 0], quaternion_xyzw: [0, 0, 0, 1]}\n", encoding="utf-8"
    )
    return folder


CASES = {
    "urdf": ({"urdf": "../shared/r.urdf"}, "robots.arm.urdf: URDF file"),
    "parquet": ({"parquet": "../shared/d.parquet"}, "sources.s.parquet: parquet file"),
    "glob": ({"parquet": "../shared/*.parquet"}, "sources.s.parquet: parquet glob folder"),
    "sidecar": ({"edges": [{"file": "../shared/edges.yaml"}], "frames": {"root": "world"}}, "edges[0].file: edges file"),
}


@pytest.mark.parametrize("case", sorted(CASES))
@pytest.mark.parametrize("command", ["validate", "plan"])
def test_a_path_outside_is_refused_then_allowed_by_the_runner(
    case: str, command: str, tmp_path: Path, outside: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.delenv(ALLOW_ENV, raising=False)
    settings, message = CASES[case]
    config = write_config(tmp_path / "pr", **settings)  # type: ignore[arg-type]
    result = run_cli(command, str(config))
    assert result.code == 1, result.err
    assert f"error: {config}:" in result.err and message in result.err, result.err
    assert f"is outside the config's folder or a declared package root ({tmp_path / 'pr'})" in result.err
    assert f"{ALLOW_ENV}=/that/folder" in result.err and "Traceback" not in result.err

    monkeypatch.setenv(ALLOW_ENV, str(outside))
    result = run_cli(command, str(config))
    assert result.code == 0, result.err


def test_a_glob_match_that_links_outside_is_refused(tmp_path: Path, outside: Path, run_cli) -> None:
    config = write_config(tmp_path / "pr", parquet="data/*.parquet")
    (tmp_path / "pr" / "data").mkdir()
    (tmp_path / "pr" / "data" / "ep0.parquet").symlink_to(outside / "d.parquet")
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert f"(resolves to {outside / 'd.parquet'}) is outside the config's folder" in result.err


def test_package_paths_outside_are_refused(tmp_path: Path, outside: Path, run_cli) -> None:
    config = write_config(tmp_path / "pr")
    spec = yaml.safe_load(config.read_text())
    spec["robots"]["arm"]["package_paths"] = {"shared_pkg": "../shared"}
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "robots.arm.package_paths.shared_pkg: package 'shared_pkg' folder" in result.err
    assert f"folder {outside} is outside the config's folder" in result.err


def test_a_source_inside_git_is_refused(tmp_path: Path, run_cli) -> None:
    config = write_config(tmp_path / "pr", parquet=".git/d.parquet")
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "sources.s.parquet: parquet file" in result.err and "is inside a .git folder" in result.err


def test_the_prefix_share_folder_is_a_package_root(tmp_path: Path, clean_env: pytest.MonkeyPatch) -> None:
    """Where data-files, ament and cmeel wheels put robots and meshes: `sys.prefix/share` (cmeel's own
    `cmeel.prefix/share` is inside site-packages already). Read only: a config never writes there."""
    import sys

    share = Path(sys.prefix) / "share" / "some_description" / "robot.urdf"
    rule = confinement_for(tmp_path / "c.yaml")
    assert rule.may_read(share) and not rule.may_write(share)
    clean_env.setattr(sys, "prefix", str(tmp_path / "prefix"))
    rule = confinement_for(tmp_path / "pr" / "c.yaml")
    assert rule.may_read(tmp_path / "prefix" / "share" / "x" / "r.urdf")
    assert not rule.may_read(tmp_path / "prefix" / "lib" / "secret")  # the share folder only, not the whole prefix
    assert not rule.may_write(tmp_path / "prefix" / "share" / "x.rrd")


MESHED_ARM = """<robot name="arm"><link name="base_link"/>
<link name="link1"><visual><geometry><mesh filename="package://arm_description/meshes/link1.stl"/></geometry></visual></link>
<joint name="joint1" type="revolute"><parent link="base_link"/><child link="link1"/><axis xyz="0 0 1"/>
<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>"""


def test_init_from_a_urdf_under_the_prefix_share_writes_a_config_that_validates(
    tmp_path: Path, clean_env: pytest.MonkeyPatch, run_cli
) -> None:
    """A description package installed under `sys.prefix/share`: `init` finds its package folder there and the config
    it writes validates without URDF_PIPELINE_ALLOW_PATHS (the read rule and init agree)."""
    import struct
    import sys

    clean_env.setattr(sys, "prefix", str(tmp_path / "venv"))
    package = tmp_path / "venv" / "share" / "arm_description"
    (package / "urdf").mkdir(parents=True)
    (package / "meshes").mkdir()
    (package / "urdf" / "arm.urdf").write_text(MESHED_ARM, encoding="utf-8")
    triangle = b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<12f", 0, 0, 1, 0, 0, 0, 0.1, 0, 0, 0, 0.1, 0) + b"\0\0"
    (package / "meshes" / "link1.stl").write_bytes(triangle)
    repo = tmp_path / "repo"
    (repo / ".git").mkdir(parents=True)  # configs/ beside data/ in one work tree
    write_joint_parquet(repo / "data" / "episode.parquet", np.zeros((5, 1)))
    config = repo / "configs" / "arm.yaml"

    result = run_cli(
        "init", "--urdf", str(package / "urdf" / "arm.urdf"), "--source", f"parquet:{repo / 'data' / 'episode.parquet'}", "-o", str(config)
    )
    assert result.code == 0, result.err
    assert "outside" not in result.err, result.err
    written = yaml.safe_load(config.read_text(encoding="utf-8"))
    assert "arm_description" in written["robots"]["arm"]["package_paths"]

    result = run_cli("validate", str(config))
    assert result.code == 0, result.err
    assert f"ok: {config}" in result.out
