"""Every command's --help as a user reads it: a one-line description (its line in the command list), the CONFIG
argument with one help text wherever a command reads a config, and one example at the end that runs as typed on the
example configs as `make demo` leaves them, from the folder holding them."""

from __future__ import annotations

import contextlib
import io
import re
import shlex
import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest

from urdf_pipeline import cli
from urdf_pipeline.render.headless_viewer import NO_RENDERER

from ..web.conftest import viewer_cache  # noqa: F401 (browse's site takes the viewer from the session's cache)

COMMANDS = re.search(r"\{([a-z,]+)\}", cli.build_parser().format_usage()).group(1).split(",")  # type: ignore[union-attr]
EXAMPLE = re.compile(r"\n\nexample \(.*\):\n  (urdf-pipeline .+)\n\Z")
NOT_RUN = {"serve": "it serves until Ctrl-C: tests/docs/test_your_robot.py starts serve, fetches a page and stops it"}


def _help(*words: str) -> str:
    out = io.StringIO()
    with contextlib.redirect_stdout(out), pytest.raises(SystemExit) as done:
        cli.main([*words, "--help"])
    assert done.value.code == 0
    return out.getvalue()


@pytest.fixture(scope="module")
def pages() -> Iterator[dict[str, str]]:
    """`urdf-pipeline --help` (key "") and each command's --help, on a terminal wide enough for a line each."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("COLUMNS", "250")
        yield {"": _help(), **{name: _help(name) for name in COMMANDS}}


def test_every_command_has_one_line_that_describes_it(pages: dict[str, str]) -> None:
    listed = dict(re.findall(r"^    ([a-z]+) {2,}(\S.*)$", pages[""], re.MULTILINE))
    assert sorted(listed) == sorted(COMMANDS)
    for name in COMMANDS:
        description = pages[name].split("\n\n")[1]
        assert description == listed[name], f"{name} --help describes it otherwise than the command list"


def test_the_config_argument_has_one_name_and_one_help(pages: dict[str, str]) -> None:
    helps = {name: re.findall(r"^  CONFIG {2,}(\S.*)$", pages[name], re.MULTILINE) for name in COMMANDS}
    takers = {name: found for name, found in helps.items() if found}
    assert len(takers) >= 7, f"the commands that read a config: {sorted(takers)}"
    assert len({help_text for found in takers.values() for help_text in found}) == 1, takers
    for name in takers:
        assert re.search(r"^usage: .*\bCONFIG\b", pages[name], re.MULTILINE | re.DOTALL), name


def test_every_help_ends_with_one_example(pages: dict[str, str]) -> None:
    for name in COMMANDS:
        found = EXAMPLE.search(pages[name])
        assert found, f"{name} --help does not end with an example"
        assert shlex.split(found.group(1))[1] == name and pages[name].count("\nexample (") == 1


@pytest.fixture(scope="module")
def examples(examples_dir: Path, tmp_path_factory: pytest.TempPathFactory, viewer_cache) -> Path:  # noqa: F811
    """A folder holding `configs/` as `make demo` leaves it: the example configs and their inputs, demo.yaml run."""
    folder = tmp_path_factory.mktemp("help-examples")
    shutil.copytree(examples_dir, folder / "configs", symlinks=True, ignore=shutil.ignore_patterns("out"))
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(folder)
        assert cli.main(["run", "configs/demo.yaml", "-q"]) == 0
    return folder


def _example(name: str) -> list[str]:
    found = EXAMPLE.search(_help(name))
    assert found, name
    words = shlex.split(found.group(1))
    assert not any(set(word) & set("*?$|<>;&`") for word in words), f"{name}: the example needs no shell to run as typed"
    return words


@pytest.mark.parametrize("name", [name for name in COMMANDS if name not in NOT_RUN])
def test_the_example_runs_as_typed(name: str, examples: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(examples)
    code = cli.main(_example(name)[1:])
    err = capsys.readouterr().err
    if code != 0 and NO_RENDERER in err:
        pytest.skip(f"{NO_RENDERER} (make test installs it when run as root)")
    assert code == 0, err


def test_only_the_listed_examples_are_left_unrun() -> None:
    assert set(NOT_RUN) <= set(COMMANDS)
