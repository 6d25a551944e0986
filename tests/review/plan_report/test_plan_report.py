"""`urdf-pipeline plan --format markdown|json`: byte-for-byte golden files, determinism, every edge origin, --sample.

Regenerate the golden files with `UPDATE_GOLDEN=1 .venv/bin/pytest tests/review/plan_report/test_plan_report.py` after a deliberate
change to the report (or to the example configs), and review their diff like code.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet

from ...conftest import assert_commands_leave_out
from ...edge_helpers import write_config

GOLDEN = Path(__file__).resolve().parents[2] / "golden"
GOLDEN_CONFIGS = ["demo", "bimanual_pandas", "so101_dataset", "aloha_bimanual"]
FORMATS = {"markdown": "md", "json": "json"}


def _update_golden() -> bool:
    return os.environ.get("UPDATE_GOLDEN", "") not in ("", "0")


@pytest.mark.parametrize("output_format", sorted(FORMATS))
@pytest.mark.parametrize("name", GOLDEN_CONFIGS)
def test_plan_matches_its_golden_file(name: str, output_format: str, examples_dir: Path, run_cli) -> None:
    if name == "aloha_bimanual" and importlib.util.find_spec("rtbdata") is None:
        pytest.skip("the ALOHA xacro comes from rtb-data (the test extra)")
    result = run_cli("plan", str(examples_dir / f"{name}.yaml"), "--format", output_format)
    assert result.code == 0, result.err
    golden = GOLDEN / f"{name}.plan.{FORMATS[output_format]}"
    if _update_golden():
        golden.parent.mkdir(exist_ok=True)
        golden.write_bytes(result.out.encode("utf-8"))
    assert golden.is_file(), f"{golden} is missing: run UPDATE_GOLDEN=1 pytest {__file__}"
    assert result.out.encode("utf-8") == golden.read_bytes(), (
        f"`plan --format {output_format}` of configs/{name}.yaml differs from {golden.relative_to(GOLDEN.parents[1])}; "
        "if the change is intended, regenerate with UPDATE_GOLDEN=1 and review the diff"
    )
    assert str(examples_dir) not in result.out  # no absolute path: the same bytes on every machine


@pytest.mark.parametrize("output_format", ["text", *sorted(FORMATS)])
def test_plan_is_deterministic_across_processes(output_format: str, examples_dir: Path) -> None:
    """Two fresh interpreters (other hash seeds, other dict and set orders) print the same bytes."""
    outputs = []
    for seed in ("1", "2"):
        result = subprocess.run(
            [sys.executable, "-m", "urdf_pipeline", "plan", "bimanual_pandas.yaml", "--format", output_format],
            capture_output=True,
            cwd=examples_dir,
            env={**os.environ, "PYTHONHASHSEED": seed},
        )
        assert result.returncode == 0, result.stderr.decode()
        outputs.append(result.stdout)
    assert outputs[0] == outputs[1]


def test_paths_are_relative_to_the_config_whatever_the_working_directory(examples_dir: Path, run_cli, monkeypatch) -> None:
    by_absolute = run_cli("plan", str(examples_dir / "so101_dataset.yaml"), "--format", "json")
    monkeypatch.chdir(examples_dir / "data")
    by_relative = run_cli("plan", "../so101_dataset.yaml", "--format", "json")
    assert by_absolute.code == by_relative.code == 0
    assert by_absolute.out == by_relative.out
    output = json.loads(by_absolute.out)["output"]
    assert output["model"] == "out/so101_dataset/model.rrd" and output["segments"][0]["output"] == "out/so101_dataset/episode_000000.rrd"


def test_json_has_the_markdown_content(examples_dir: Path, run_cli) -> None:
    report = json.loads(run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "json").out)
    (robot,) = report["robots"]
    assert robot["urdf"]["origin"] == "file robots/panda.urdf" and len(robot["urdf"]["sha256"]) == 64
    assert robot["joint_counts"] == {
        "revolute": 7, "continuous": 0, "prismatic": 2, "fixed": 3, "floating": 0, "planar": 0, "mimic": 1,
    }  # fmt: skip
    rows = {row["joint"]: row for row in robot["joints"]}
    assert rows["panda_joint2"]["sign"] == -1 and rows["panda_joint3"]["offset"] == 0.1
    limit = round(math.degrees(2.8973), 9)  # the URDF's limit in degrees: check's "limits in the source unit"
    assert rows["panda_joint1"]["limits_source_units"] == [-limit, limit]
    assert rows["panda_joint1"]["slack_source_units"] == 2.0 and rows["panda_joint1"]["slack"] == {"value": 2.0, "unit": "deg"}
    assert rows["panda_finger_joint1"]["slack"] == {"value": 2.0, "unit": "mm"}
    assert rows["panda_finger_joint1"]["unit"] == "mm" and rows["panda_finger_joint1"]["limits_source_units"] == [0.0, 40.0]
    assert rows["panda_finger_joint2"]["kind"] == "mimic"
    assert rows["panda_finger_joint2"]["mimic"] == {"driver": "panda_finger_joint1", "multiplier": 1.0, "offset": 0.0}
    assert all(row["observed"] is None for row in robot["joints"]) and report["sample"] is None
    kinds = {(e["parent"], e["child"]): e["origin"]["kind"] for e in report["edges"]}
    assert kinds[("world", "panda_link0")] == "calibration_inline"
    assert kinds[("panda_link0", "panda_link1")] == "urdf_moving_joint" and kinds[("panda_link8", "panda_hand")] == "urdf_fixed_joint"
    assert report["edges"][0]["child"] == "panda_link0"  # tree order: from the root down
    assert report["frame_tree"]["mermaid"].startswith('graph TD\n  f0["world"]\n')


def test_held_joints_and_source_range(examples_dir: Path, run_cli) -> None:
    markdown = run_cli("plan", str(examples_dir / "aloha_bimanual.yaml"), "--format", "markdown").out
    assert "| — | `gripper` | continuous | rad | — | — | — | — | `hold = 0` |" in markdown
    assert "| `6` | `left_finger` | prismatic | — | — | — | source_range [0, 1] → [0.021, 0.057] | 0 .. 1 | — |" in markdown
    assert "| — | `right_finger` | prismatic | m | — | — | — | — | `left_finger` × -1 + 0 |" in markdown
    assert "- ignored source values: `7`, `8`, `9`, `10`, `11`, `12`, `13`" in markdown


@pytest.mark.parametrize("name", ["demo", "aloha_bimanual"])
def test_text_and_markdown_show_the_same_limits_in_source_units(name: str, examples_dir: Path, run_cli) -> None:
    """Issue 11: text showed each limit in URDF units too (`(URDF [-2.8973, 2.8973])`); now, as markdown, only in the
    source's units (degrees, mm, or the source_range's), the same numbers."""
    if name == "aloha_bimanual" and importlib.util.find_spec("rtbdata") is None:
        pytest.skip("the ALOHA xacro comes from rtb-data (the test extra)")
    config = str(examples_dir / f"{name}.yaml")
    text, markdown = run_cli("plan", config).out, run_cli("plan", config, "--format", "markdown").out
    number = r"-?[0-9.]+(?:e[-+]?[0-9]+)?"
    in_text = {
        (m["name"], m["joint"]): (m["low"], m["high"], m["slack"])
        for m in re.finditer(
            rf"^    (?P<name>\S+)\[\d+\] -> (?P<joint>\S+): .*; limits (?P<low>{number}) \.\. (?P<high>{number}) "
            rf"(?:deg|rad|mm|cm|m|source units), slack (?P<slack>0|{number} (?:deg|rad|mm|cm|m))$",
            text,
            re.MULTILINE,
        )
    }
    in_markdown = {
        (m["name"], m["joint"]): (m["low"], m["high"], m["slack"] or "0")
        for m in re.finditer(
            rf"^\| `(?P<name>[^`]+)` \| `(?P<joint>[^`]+)` \|.* \| (?P<low>{number}) \.\. (?P<high>{number})(?: ± (?P<slack>{number} (?:deg|rad|mm|cm|m)))? \|",
            markdown,
            re.MULTILINE,
        )
    }
    assert in_text and in_text == in_markdown
    assert "URDF [" not in text
    if name == "demo":  # degrees (and mm) in the data, radians (and m) in the URDF
        assert in_text[("j1", "panda_joint1")] == ("-166.003", "166.003", "2 deg")
        assert "j1[0] -> panda_joint1: x 0.0174533 (deg) x 1 + 0; limits -166.003 .. 166.003 deg, slack 2 deg" in text
        assert in_text[("finger", "panda_finger_joint1")] == ("0", "40", "2 mm")


@pytest.fixture(scope="module")
def rich_config(examples_dir: Path) -> Path:
    """Every kind of edge: a calibration in a sidecar file, an inline one, a fixed chain, an assumed identity, a
    temporal edge; a scene robot whose mesh does not resolve (allowed); frame names mermaid and markdown would misread."""
    name = "plan_report_rich"
    rng = np.random.default_rng(7)
    pose = np.concatenate([rng.uniform(-1, 1, (5, 3)), np.tile([0.0, 0.0, 0.0, 1.0], (5, 1))], axis=1)
    write_joint_parquet(examples_dir / "data" / f"{name}_pose.parquet", pose, column="pose")
    calib = examples_dir / "calib" / name
    calib.mkdir(parents=True, exist_ok=True)
    base = {"parent": "world", "child": "panda_link0", "translation": [0.0, 0.0, 0.5], "rpy_deg": [0, 0, 90]}
    (calib / "arm.yaml").write_text("# measured\n" + yaml.safe_dump([base], sort_keys=False))
    scene_dir = examples_dir / "robots" / name
    scene_dir.mkdir(parents=True, exist_ok=True)
    (scene_dir / "scene.urdf").write_text(
        '<robot name="scene"><link name="table"><visual><geometry><mesh filename="meshes/missing.stl"/></geometry></visual></link>'
        '<link name="mount"/><joint name="mount_joint" type="fixed"><parent link="table"/><child link="mount"/>'
        '<origin xyz="0.1 0 0.7" rpy="0 0 1.5707963267948966"/></joint></robot>'
    )
    data = yaml.safe_load((examples_dir / "demo.yaml").read_text())
    data["sources"]["tracker"] = {
        "parquet": f"data/{name}_pose.parquet",
        "column": "pose",
        "index": "frame_index",
        "names": list("xyzabcw"),
    }
    data["robots"]["scene"] = {"urdf": f"robots/{name}/scene.urdf", "frame_prefix": "scene_", "allow_missing_meshes": True}
    data["frames"]["assume_identity"] = ["scene_table"]
    data["edges"] = [
        {"file": f"calib/{name}/arm.yaml"},
        {"parent": "panda_link7", "child": 'wrist "cam" | <1>', "fixed_chain": {"from": "panda_link7", "to": "panda_hand_tcp"}},
        {"parent": "scene_mount", "child": "cup#1", "translation": [0.0, 0.0, 0.05], "quaternion_xyzw": [0, 0, 0, 1]},
        {
            "parent": "world",
            "child": "tracker",
            "source": "tracker",
            "translation": ["x", "y", "z"],
            "quaternion_xyzw": ["a", "b", "c", "w"],
        },
    ]
    data["output"]["segment"] = name
    return write_config(examples_dir, name, data)


def test_every_edge_origin(rich_config: Path, run_cli) -> None:
    result = run_cli("plan", str(rich_config), "--format", "json")
    assert result.code == 0, result.err
    report = json.loads(result.out)
    origins = {(e["parent"], e["child"]): e["origin"] for e in report["edges"]}
    sidecar = origins[("world", "panda_link0")]
    assert sidecar["kind"] == "calibration_file" and sidecar["description"] == "calibration file calib/plan_report_rich/arm.yaml:2"
    chain = origins[("panda_link7", 'wrist "cam" | <1>')]
    assert chain["kind"] == "fixed_chain" and chain["fixed_chain"] == ["panda_joint8", "panda_hand_joint", "panda_hand_tcp_joint"]
    assert chain["description"].startswith("fixed chain panda_link7 -> panda_hand_tcp of robot arm (fixed joints panda_joint8, ")
    inline = origins[("scene_mount", "cup#1")]
    assert inline["kind"] == "calibration_inline" and inline["description"].startswith("calibration inline (edges[2], line ")
    identity = origins[("world", "scene_table")]
    assert identity["kind"] == "assumed_identity" and identity["label"] == "frames.assume_identity[0]"
    assert origins[("scene_table", "scene_mount")]["description"] == "URDF fixed joint mount_joint of robot scene"
    temporal = next(e for e in report["edges"] if e["origin"]["kind"] == "temporal")
    assert temporal["origin"]["source"] == "tracker" and temporal["translation_m"] is None
    assert temporal["temporal"]["quaternion_xyzw_names"] == ["a", "b", "c", "w"]
    by_child = {e["child"]: e for e in report["edges"]}
    assert by_child["panda_link0"]["rotation_rpy_deg"] == [0.0, 0.0, 90.0]
    assert by_child["scene_mount"]["translation_m"] == [0.1, 0.0, 0.7] and by_child["scene_mount"]["rotation_rpy_deg"] == [0.0, 0.0, 90.0]
    messages = [w["message"] for w in report["warnings"]]
    assert any("frames.assume_identity" in m for m in messages) and any("allow_missing_meshes" in m for m in messages)
    assert all(w["file"] == "plan_report_rich.yaml" for w in report["warnings"])
    (scene,) = [r for r in report["robots"] if r["key"] == "scene"]
    assert scene["source"] is None and scene["joints"] == []
    assert "warning: " in result.err  # still on stderr, as validate prints them


def test_markdown_escapes_names(rich_config: Path, run_cli) -> None:
    markdown = run_cli("plan", str(rich_config), "--format", "markdown").out
    mermaid = markdown.split("```mermaid\n", 1)[1].split("```", 1)[0]
    assert '["wrist #quot;cam#quot; #124; #lt;1#gt;"]' in mermaid and '["cup#35;1"]' in mermaid
    for line in mermaid.splitlines()[1:]:  # ids are mermaid-safe: f0, f1, ...
        assert re.fullmatch(r'  f\d+\["[^"]*"\]|  f\d+ [-.=>]+(\|[a-z ]+\|)? f\d+', line), line
    assert '| `panda_link7` | `wrist "cam" \\| <1>` |' in markdown  # a pipe in a table cell is escaped
    assert "#### Warnings\n\n- `plan_report_rich.yaml:" in markdown
    assert (
        "| `world` | `tracker` | per row: `x`, `y`, `z` | per row: quaternion_xyzw `a`, `b`, `c`, `w` | temporal edge from source tracker"
        in markdown
    )


def test_sample_adds_the_observed_range(examples_dir: Path, run_cli) -> None:
    from urdf_pipeline.compile.compiler import compile_config
    from urdf_pipeline.review.check.check_joints import read_sample

    result = run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "json", "--sample", "--rows", "40")
    assert result.code == 0, result.err
    report = json.loads(result.out)
    assert report["sample"] == {"read": {"arm_state": 40}, "rows": 40}
    raw = read_sample(compile_config(examples_dir / "demo.yaml").segments[0].sources[0], 40)
    rows = {row["source_name"]: row for row in report["robots"][0]["joints"] if row["kind"] == "mapped"}
    assert rows["j2"]["observed"]["min"] == round(float(raw[:, 1].min()), 9) and rows["j2"]["observed"]["rows"] == 40
    assert all(row["observed"]["fits"] for row in rows.values())
    markdown = run_cli("plan", str(examples_dir / "demo.yaml"), "--format", "markdown", "--sample", "--rows", "40").out
    assert "| observed (source units) |" in markdown and "- sampled: the first 40 rows of source `arm_state` (at most 40)" in markdown
    text = run_cli("plan", str(examples_dir / "demo.yaml"), "--sample", "--rows", "40")
    assert text.code == 0 and "sample (at most 40 rows of each source; read arm_state: 40):" in text.out
    assert "j2 -> panda_joint2 [deg]: values " in text.out


def test_rows_without_sample_is_a_usage_error(examples_dir: Path, run_cli) -> None:
    result = run_cli("plan", str(examples_dir / "demo.yaml"), "--rows", "10")
    assert result.code == 2 and "--rows needs --sample" in result.err


@pytest.mark.parametrize("output_format", sorted(FORMATS))
def test_plan_reads_no_joint_data_and_imports_no_rerun(output_format: str, examples_dir: Path) -> None:
    assert_commands_leave_out("rerun", ["plan", str(examples_dir / "so101_dataset.yaml"), "--format", output_format])


def test_invalid_config_still_fails_with_its_errors(examples_dir: Path, run_cli, tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\n")
    result = run_cli("plan", str(bad), "--format", "markdown")
    assert result.code == 1 and result.out == "" and "bad.yaml:1" in result.err


def test_the_joint_series_option_is_shown_only_when_set(examples_dir: Path, run_cli) -> None:
    text = (
        (examples_dir / "demo.yaml")
        .read_text()
        .replace("  application_id: panda_demo\n", "  application_id: panda_demo\n  joint_series: true\n")
    )
    config = examples_dir / "demo_series.yaml"
    config.write_text(text)
    shown = "joint values also as time series (each driven joint, URDF units), plotted beside the 3D view"
    assert f"  {shown} (output.joint_series)\n" in run_cli("plan", str(config)).out
    assert f"- {shown} (`output.joint_series`)\n" in run_cli("plan", str(config), "--format", "markdown").out
    assert json.loads(run_cli("plan", str(config), "--format", "json").out)["output"]["joint_series"] is True
    plain = examples_dir / "demo.yaml"
    assert "joint_series" not in run_cli("plan", str(plain)).out + run_cli("plan", str(plain), "--format", "markdown").out
    assert "joint_series" not in json.loads(run_cli("plan", str(plain), "--format", "json").out)["output"]
