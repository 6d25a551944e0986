"""The read rule holds for what MuJoCo itself reads: every MJCF construct on which MuJoCo's XML reader (TinyXML2) and
the scan's (expat) would disagree is refused before MuJoCo opens anything. Each case first shows, with MuJoCo itself,
that the model would make it read a file outside the config's roots, then that `validate` refuses it in one line
naming the file, its line and the element."""

from __future__ import annotations

from pathlib import Path

import pytest

from ..mjcf_inputs import ARM, DOCTYPE_HIDING, robot_config, tetrahedron_stl, write_mjcf_inputs

mujoco = pytest.importorskip("mujoco", reason="MJCF robots need mujoco (pip install 'urdf-pipeline[mjcf]')")

SECRET = '<mujoco><worldbody><body name="secret"><geom size="0.1"/></body></worldbody></mujoco>'


def refused(result, config: Path, *expected: str) -> str:
    """The one error line of a refused `validate`, checked: exit 1, no traceback, the config's robot key named."""
    assert result.code == 1, f"exit {result.code}\n{result.err}"
    assert "Traceback" not in result.err, result.err
    errors = [line for line in result.err.splitlines() if line.startswith("error")]
    assert len(errors) == 1, result.err
    assert errors[0].startswith(f"error: {config}:") and "robots.arm.urdf" in errors[0], errors[0]
    for text in expected:
        assert text in errors[0], f"{text!r} not in {errors[0]!r}"
    return errors[0]


@pytest.fixture
def outside(tmp_path: Path) -> Path:
    """A model file outside the config's folder (tmp_path/pr): what a stranger's model must not make MuJoCo read."""
    folder = tmp_path / "outside"
    folder.mkdir()
    (folder / "secret.xml").write_text(SECRET, encoding="utf-8")
    return folder / "secret.xml"


def _bodies(path: Path) -> list[str]:
    model = mujoco.MjModel.from_xml_path(str(path))
    return [model.body(index).name for index in range(model.nbody)]


def test_a_doctype_hiding_an_include_is_refused(tmp_path: Path, outside: Path, run_cli) -> None:
    pr = tmp_path / "pr"
    write_mjcf_inputs(pr)
    (pr / "robot.xml").write_text(DOCTYPE_HIDING.format(outside) + ARM, encoding="utf-8")
    assert "secret" in _bodies(pr / "robot.xml"), "MuJoCo reads the include that expat sees as a comment"

    config = robot_config(pr, {"mjcf": "robot.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, "MJCF file robot.xml:1: <!DOCTYPE> is refused", "MuJoCo's XML reader")


@pytest.mark.parametrize(
    "doctype",
    [
        '<!DOCTYPE mujoco [<!ENTITY mesh "tetra.stl">]>',
        '<!DOCTYPE mujoco SYSTEM "mujoco.dtd">',
        "<!DOCTYPE mujoco>",
        "<!doctype mujoco>",
    ],
)
def test_any_doctype_in_an_included_file_is_refused(tmp_path: Path, doctype: str, run_cli) -> None:
    write_mjcf_inputs(tmp_path)
    assets = (tmp_path / "mjcf_arm_assets.xml").read_text(encoding="utf-8")
    (tmp_path / "mjcf_arm_assets.xml").write_text(f"<!-- assets -->\n{doctype}\n{assets}", encoding="utf-8")
    config = robot_config(tmp_path, {"mjcf": "mjcf_arm.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, "MJCF file mjcf_arm_assets.xml:2: <!DOCTYPE> is refused")


def test_a_utf16_doctype_is_found_too(tmp_path: Path, run_cli) -> None:
    (tmp_path / "robot.xml").write_bytes(("<!DOCTYPE mujoco>\n" + ARM).encode("utf-16"))
    config = robot_config(tmp_path, {"mjcf": "robot.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, "MJCF file robot.xml:1: <!DOCTYPE> is refused")


def test_a_default_namespace_hides_nothing(tmp_path: Path, outside: Path, run_cli) -> None:
    """`xmlns="..."` made ElementTree name every element `{...}include`: the includes went unread and the compiler's
    folders unseen, while MuJoCo (namespace-unaware) reads both."""
    pr = tmp_path / "pr"
    pr.mkdir()
    (pr / "inner.xml").write_text(f'<mujoco><include file="{outside}"/></mujoco>', encoding="utf-8")
    (pr / "robot.xml").write_text('<mujoco model="m" xmlns="urn:x"><include file="inner.xml"/></mujoco>', encoding="utf-8")
    assert "secret" in _bodies(pr / "robot.xml"), "MuJoCo reads a namespaced model's includes"

    config = robot_config(pr, {"mjcf": "robot.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, f"MJCF <include> file '{outside}' in inner.xml:1:", "is outside the config's folder")

    (pr / "robot.xml").write_text('<mujoco xmlns="urn:x"><compiler meshdir="/etc"/></mujoco>', encoding="utf-8")
    refused(run_cli("validate", str(config)), config, "MJCF <compiler meshdir> folder in robot.xml:1: /etc is outside")


def test_a_tab_in_a_file_name_is_refused(tmp_path: Path, outside: Path, run_cli) -> None:
    """expat reads a literal tab in an attribute as a space, TinyXML2 as a tab: a link named with a tab would be
    read by MuJoCo while the scan checked a name with a space (a file that is not there, inside the roots)."""
    pr = tmp_path / "pr"
    pr.mkdir()
    (pr / "a\tb").symlink_to(outside.parent, target_is_directory=True)
    (pr / "robot.xml").write_text('<mujoco>\n<include\n file="a\tb/secret.xml"/></mujoco>', encoding="utf-8")
    assert "secret" in _bodies(pr / "robot.xml"), "MuJoCo opens the name with its tab"

    config = robot_config(pr, {"mjcf": "robot.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, "MJCF file robot.xml:2: <include file='a\\tb/secret.xml'> holds a tab or line break")


def test_a_file_in_another_encoding_is_refused(tmp_path: Path, run_cli) -> None:
    """expat honours `encoding="ISO-8859-1"`, MuJoCo reads UTF-8: the same bytes would name two different files."""
    text = ARM.replace('file="mjcf_arm_assets.xml"', 'file="\u00e9.xml"')
    (tmp_path / "robot.xml").write_bytes(b'<?xml version="1.0" encoding="ISO-8859-1"?>\n' + text.encode("latin-1"))
    config = robot_config(tmp_path, {"mjcf": "robot.xml"}, "shoulder")
    refused(run_cli("validate", str(config)), config, "MJCF file robot.xml:7 is not UTF-8 text", "save it as UTF-8")


def test_dot_dot_after_a_link_is_folded_as_mujoco_folds_it(tmp_path: Path, run_cli) -> None:
    """MuJoCo joins `meshdir` and `file` and folds `..` as written (it opens pr/m.stl for `lnk/..`, never the link's
    parent): the check resolves the same path, so `lnk/..` stays inside and `lnk` itself is refused."""
    pr, outside = tmp_path / "pr", tmp_path / "outside" / "deep"
    outside.mkdir(parents=True)
    pr.mkdir()
    (pr / "lnk").symlink_to(outside, target_is_directory=True)
    (pr / "m.stl").write_bytes(tetrahedron_stl())
    (outside.parent / "m.stl").write_bytes(tetrahedron_stl()[:84])  # no facet: MuJoCo refuses it if it opens it
    (outside / "m.stl").write_bytes(tetrahedron_stl())
    robot = '<mujoco><compiler meshdir="{}"/><asset><mesh name="m" file="m.stl"/></asset><worldbody><body><joint name="j1"/><geom type="mesh" mesh="m"/></body></worldbody></mujoco>'
    (pr / "robot.xml").write_text(robot.format("lnk/.."), encoding="utf-8")
    assert mujoco.MjModel.from_xml_path(str(pr / "robot.xml")).nmeshvert == 4, "MuJoCo opened pr/m.stl"
    config = robot_config(pr, {"mjcf": "robot.xml"})
    assert run_cli("validate", str(config)).code == 0

    (pr / "robot.xml").write_text(robot.format("lnk"), encoding="utf-8")
    refused(run_cli("validate", str(config)), config, "MJCF <compiler meshdir> folder in robot.xml:1:", "is outside the config's folder")
