"""A refused run claims no work and leaves no trace: no "writing" line (nor the dataset's "N segment(s) ... job(s)"
line) before the refusal, and no output folder it made and wrote nothing into; a folder that was there is left as it
was."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from ..dataset_helpers import edit_config, isolated_examples

pytestmark = pytest.mark.usefixtures("allow_examples")  # configs elsewhere read the session's examples


@pytest.fixture
def demo(examples_dir: Path, tmp_path: Path) -> Path:
    """The one-segment demo writing into out/deep/er/ (three folders the run would make)."""
    config = isolated_examples(examples_dir, tmp_path / "run", "demo.yaml")
    return edit_config(config, lambda d: d["output"].update(path="out/deep/er/{segment}.rrd"))


def _claims_work(err: str) -> list[str]:
    return [line for line in err.splitlines() if "writing" in line or "job(s) on the" in line or " written" in line]


def test_a_data_error_in_the_only_segment_leaves_no_folder_and_claims_no_writing(demo: Path, run_cli) -> None:
    edit_config(demo, lambda d: d["robots"]["arm"]["joints"].update(unit="rad"))  # degrees read as radians: beyond limits
    result = run_cli("run", str(demo))
    assert result.code == 1 and "beyond the URDF limits" in result.err, result.err
    assert not _claims_work(result.err), result.err
    assert "Traceback" not in result.err
    assert not (demo.parent / "out").exists(), "the folders the run made and wrote nothing into are removed"


def test_a_folder_that_was_there_is_left_as_it_was(demo: Path, run_cli) -> None:
    edit_config(demo, lambda d: d["robots"]["arm"]["joints"].update(unit="rad"))
    (demo.parent / "out" / "deep").mkdir(parents=True)
    result = run_cli("run", str(demo))
    assert result.code == 1
    assert [p.name for p in (demo.parent / "out").iterdir()] == ["deep"]  # kept, empty as it was
    assert not list((demo.parent / "out" / "deep").iterdir()), "er/, made by the run, is removed"


def test_a_written_run_keeps_its_folder_and_says_where_it_wrote(demo: Path, run_cli) -> None:
    result = run_cli("run", str(demo))
    assert result.code == 0, result.err
    output = demo.parent / "out" / "deep" / "er" / "episode_000.rrd"
    assert output.is_file()
    assert re.search(rf"episode_000: [0-9,]+ rows in [0-9.]+ s, written to {re.escape(str(output))}\n", result.err), result.err


def test_a_file_the_tool_did_not_write_refuses_the_dataset_before_any_line_of_work(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "run")
    outputs = config.parent / "out" / "so101_dataset"
    outputs.mkdir(parents=True)
    (outputs / "episode_000002.rrd").write_text("not a recording")
    result = run_cli("run", str(config), "--jobs", "2")
    assert result.code == 1 and "it exists and it is not a Rerun recording" in result.err, result.err
    assert not _claims_work(result.err), result.err
    assert [p.name for p in outputs.iterdir()] == ["episode_000002.rrd"]


def test_a_report_that_cannot_be_written_refuses_the_run_before_it(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "run")
    for report, why in [(tmp_path / "no" / "such" / "report.json", "is not a folder"), (tmp_path, "is a folder")]:
        result = run_cli("run", str(config), "--report", str(report))
        assert result.code == 1 and "error: --report: " in result.err and why in result.err, result.err
        assert not _claims_work(result.err), result.err
        assert not (config.parent / "out").exists(), "refused before the run"


def test_a_dataset_whose_every_segment_fails_leaves_no_folder_and_names_no_manifest(examples_dir: Path, tmp_path: Path, run_cli) -> None:
    config = isolated_examples(examples_dir, tmp_path / "run")

    def every_segment_fails(data: dict) -> None:
        data["output"]["layout"] = "single"
        del data["output"]["model"]
        joints = data["robots"]["so101"]["joints"]
        joints["limits"] = {"slack": 0.0, "on_violation": "error"}
        joints["map"]["shoulder_pan"] = {"joint": "shoulder_pan", "scale": 3.0}  # tripled: beyond the limits everywhere

    edit_config(config, every_segment_fails)
    result = run_cli("run", str(config), "--jobs", "1")
    assert result.code == 1, result.err
    assert "4 outputs: 4 failed; 0 frames written in" in result.err and "no manifest: nothing to list" in result.err
    assert not (config.parent / "out").exists()
