"""docs/your-robot.md as a reader follows it: every command of its console blocks, typed in order from a folder laid
out as `make demo` leaves the repository (configs/ with its inputs, .venv/bin/), and the last one, serve, answering
the page's address until SIGTERM stops it."""

from __future__ import annotations

import re
import shlex
import shutil
import signal
import subprocess
import sysconfig
import urllib.request
from pathlib import Path

from ..conftest import REPO
from ..web.conftest import viewer_cache  # noqa: F401 (plan --html takes the viewer from the session's cache)

PAGE = REPO / "docs" / "your-robot.md"
SECONDS = 120


def _commands() -> list[str]:
    blocks = re.findall(r"^```console\n(.*?)^```$", PAGE.read_text(encoding="utf-8"), re.MULTILINE | re.DOTALL)
    return [line[2:] for block in blocks for line in block.splitlines() if line.startswith("$ ")]


def test_the_page_shows_init_check_run_plan_and_serve() -> None:
    tools = [shlex.split(command)[1] for command in _commands() if command.startswith(".venv/bin/urdf-pipeline ")]
    assert tools == ["init", "check", "run", "plan", "serve"]


def test_the_page_runs_as_typed(examples_dir: Path, tmp_path: Path, viewer_cache) -> None:  # noqa: F811
    shutil.copytree(examples_dir, tmp_path / "configs", symlinks=True, ignore=shutil.ignore_patterns("out"))
    (tmp_path / ".venv").mkdir()
    (tmp_path / ".venv" / "bin").symlink_to(sysconfig.get_path("scripts"))
    *commands, serve = _commands()
    for command in commands:
        done = subprocess.run(shlex.split(command), cwd=tmp_path, capture_output=True, text=True, timeout=SECONDS)
        assert done.returncode == 0, f"{command}\n{done.stderr}"
    assert (tmp_path / "my_robot" / "out" / "episode_000.rrd").is_file()
    process = subprocess.Popen(shlex.split(serve), cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert process.stdout is not None
        url = process.stdout.readline().strip()
        assert url.startswith("http://127.0.0.1:"), url
        with urllib.request.urlopen(url, timeout=SECONDS) as answer:
            assert answer.status == 200 and b"panda" in answer.read()
    finally:
        process.send_signal(signal.SIGTERM)
        assert process.wait(SECONDS) == 143
