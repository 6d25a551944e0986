"""Command-line conventions: --version, -q / -v through `logging`, positive --rows, diff --exit-code as diff(1)."""

from __future__ import annotations

import logging
import shutil
import subprocess
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

import urdf_pipeline
from urdf_pipeline import cli

from ..conftest import CONFIGS
from ..live_views.conftest import appender  # noqa: F401 - the fixture: an MCAP file being written
from ..live_views.test_live_command import live_config


def _beside_the_examples(name: str, examples_dir: Path, folder: Path) -> Path:
    """An example config in `folder` (its own outputs), its robots/ and data/ linked to the session's inputs."""
    for inputs in ("robots", "data"):
        (folder / inputs).symlink_to(examples_dir / inputs, target_is_directory=True)
    shutil.copy(examples_dir / name, folder / name)
    return folder / name


@pytest.fixture
def demo(allow_examples: Path, examples_dir: Path, tmp_path: Path) -> Path:
    return _beside_the_examples("demo.yaml", examples_dir, tmp_path)


def test_version_names_ours_and_rerun_and_equals_the_installed_metadata(run_cli) -> None:
    result = run_cli("--version")
    assert result.code == 0
    assert result.out.startswith(f"urdf-pipeline {version('urdf-pipeline')} (rerun-sdk {version('rerun-sdk')}, Python ")
    assert urdf_pipeline.__version__ == version("urdf-pipeline")


def test_quiet_leaves_only_the_output_and_verbose_adds_timings(run_cli, demo: Path) -> None:
    plain = run_cli("run", str(demo), "--force")
    assert plain.code == 0 and "rows in" in plain.err and "compiled in" not in plain.err
    quiet = run_cli("run", "-q", str(demo), "--force")
    assert (quiet.code, quiet.err) == (0, "") and quiet.out == plain.out  # stdout (the written path) is the result
    before = run_cli("-q", "run", str(demo), "--force")  # before the command works too
    assert (before.code, before.err) == (0, "")
    verbose = run_cli("run", str(demo), "--force", "--verbose")
    assert verbose.code == 0 and f"{demo} compiled in " in verbose.err and "rows in" in verbose.err


def test_quiet_still_prints_errors_and_warnings(run_cli, demo: Path) -> None:
    broken = demo.with_name("broken.yaml")
    broken.write_text(demo.read_text().replace("panda.urdf", "missing.urdf"))
    result = run_cli("validate", "-q", str(broken))
    assert result.code == 1 and result.err.startswith(f"error: {broken}:")


def test_quiet_and_verbose_together_is_a_usage_error(run_cli, demo: Path) -> None:
    assert run_cli("run", "-q", "-v", str(demo)).code == 2


def test_an_embedding_program_silences_the_package_with_its_logger(demo: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """No handler of ours in a library call: the `urdf_pipeline` logger's level decides, in every worker too."""
    logger = logging.getLogger("urdf_pipeline")
    previous = logger.level
    logger.setLevel(logging.ERROR)
    try:
        written = urdf_pipeline.run(demo, jobs=1, force=True)
    finally:
        logger.setLevel(previous)
    assert [p.suffix for p in written] == [".rrd"]
    assert capfd.readouterr().err == ""


def test_a_config_warning_goes_to_the_urdf_pipeline_logger(demo: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A library call raises its errors and logs its warnings; an embedding program's logging shows them."""
    text = demo.read_text().replace("      example-robot-data: robots/share/example-robot-data\n", "      example-robot-data: robots\n")
    demo.write_text(text.replace("    collision_geometries: drop", "    collision_geometries: drop\n    allow_missing_meshes: true"))
    with caplog.at_level(logging.INFO, logger="urdf_pipeline"):
        urdf_pipeline.load(demo)
    warned = [r for r in caplog.records if r.name == "urdf_pipeline" and r.levelno == logging.WARNING]
    assert warned and "invisible (allow_missing_meshes: true)" in warned[0].getMessage()


def test_a_many_segment_run_is_silent_with_quiet_in_its_workers_too(
    run_cli, allow_examples: Path, examples_dir: Path, tmp_path: Path
) -> None:
    config = _beside_the_examples("so101_dataset.yaml", examples_dir, tmp_path)
    result = run_cli("run", "-q", str(config), "--jobs", "2")
    assert result.code == 0, result.err
    assert result.err == "" and result.out.count(".rrd") >= 2


@pytest.mark.parametrize("rows", ["0", "-5", "ten"])
def test_check_rows_takes_positive_numbers_only(run_cli, demo: Path, rows: str) -> None:
    result = run_cli("check", str(demo), "--rows", rows)
    assert result.code == 2 and "--rows" in result.err


def test_diff_exit_code_is_0_equal_1_different_2_error(run_cli, demo: Path) -> None:
    assert run_cli("diff", str(demo), str(demo), "--exit-code").code == 0
    flipped = demo.with_name("flipped.yaml")
    flipped.write_text(demo.read_text().replace("j2: {joint: panda_joint2, sign: -1}", "j2: panda_joint2"))
    assert run_cli("diff", str(demo), str(flipped), "--exit-code").code == 1
    missing = run_cli("diff", str(demo), str(demo.with_name("missing.yaml")), "--exit-code")
    assert missing.code == 2 and "error:" in missing.err
    broken = demo.with_name("broken.yaml")
    broken.write_text(demo.read_text().replace("panda.urdf", "missing.urdf"))
    assert run_cli("diff", str(demo), str(broken), "--exit-code").code == 2
    assert run_cli("diff", str(demo), str(broken)).code == 1  # without --exit-code, a user error is 1 as everywhere


def test_diff_exit_code_maps_a_bug_to_2(run_cli, demo: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from urdf_pipeline import review

    def crash(*args: object) -> None:
        raise RuntimeError("a bug")

    monkeypatch.setattr(review, "diff_files", crash)
    result = run_cli("diff", str(demo), str(demo), "--exit-code")
    assert result.code == 2 and "internal error" in result.err
    assert run_cli("diff", str(demo), str(demo)).code == 70


def test_the_installed_command_prints_its_version() -> None:
    """The console script as installed (what `pip install` gives), not only cli.main."""
    script = Path(sys.executable).with_name("urdf-pipeline")
    done = subprocess.run([str(script), "--version"], capture_output=True, text=True, timeout=60)
    assert done.returncode == 0 and done.stdout.startswith(f"urdf-pipeline {urdf_pipeline.__version__} ")


def test_every_config_in_configs_is_a_shipped_example() -> None:
    """The wheel's example_configs is configs/*.yaml (pyproject maps it), so `python -m urdf_pipeline.examples` writes them."""
    from urdf_pipeline.examples import example_configs

    assert sorted(p.name for p in example_configs().glob("*.yaml")) == sorted(p.name for p in CONFIGS.glob("*.yaml"))


def test_main_is_the_one_exit_point_for_help(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as done:
        cli.main(["run", "--help"])
    assert done.value.code == 0 and "-q, --quiet" in capsys.readouterr().out


def test_a_refused_html_command_leaves_no_folder_it_made(run_cli, demo: Path, tmp_path: Path) -> None:
    """`plan --html` refused (a config that is not there): the site's new parent folders are gone, an existing one kept."""
    missing = str(tmp_path / "missing.yaml")
    result = run_cli("plan", missing, "--html", str(tmp_path / "new" / "deeper" / "site"))
    assert result.code == 1 and "config file not found" in result.err, result.err
    assert not (tmp_path / "new").exists()
    (tmp_path / "kept").mkdir()
    assert run_cli("plan", missing, "--html", str(tmp_path / "kept" / "site")).code == 1
    assert (tmp_path / "kept").is_dir() and not list((tmp_path / "kept").iterdir())


def test_live_refused_at_the_first_message_leaves_no_save_folder(examples_dir: Path, run_cli, tmp_path: Path, appender) -> None:  # noqa: F811
    """`live --save NEW/FOLDERS/take.rrd` refused at the stream's first message (a joint the map names is missing):
    nothing saved, and the folders it would have saved into are gone."""
    config = live_config(examples_dir, "live_refused_save")
    config.write_text(config.read_text().replace("gripper:", "wrist_3:"))
    bag = tmp_path / "short.mcap"
    appender(bag, "--count", "20")
    result = run_cli("live", str(config), "--from", str(bag), "--save", str(tmp_path / "takes" / "today" / "take.rrd"))
    assert result.code == 1 and "wrist_3" in result.err, result.err
    assert {p.name for p in tmp_path.iterdir()} == {"short.mcap"}
