"""Shared fixtures: example inputs generated once per session, and a helper to run the CLI in-process."""

from __future__ import annotations

import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from urdf_pipeline import cli
from urdf_pipeline.examples import example_robot_data_share, prepare

REPO = Path(__file__).resolve().parents[1]
CONFIGS = REPO / "configs"
SHARED = REPO.parent / "shared"


@pytest.fixture(scope="session", autouse=True)
def ctrl_c_as_a_terminal_gives_it() -> Iterator[None]:
    """The Ctrl-C and SIGTERM tests need SIGINT to act, in this process and in the commands it starts. A test run
    started in the background of a non-interactive shell (`make test &` in a script) inherits SIGINT ignored, and so
    would every command it starts; the suite runs as from a terminal whatever started it."""
    previous = signal.getsignal(signal.SIGINT)
    if previous == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


def assert_commands_leave_out(module: str, *commands: list[str]) -> None:
    """The command lines, run by cli.main one after the other in a fresh interpreter, all exit 0 and never import
    `module` (validate and plan must not import Rerun: a second of start-up for nothing)."""
    code = (
        "import sys; from urdf_pipeline import cli; "
        f"failed = [c for c in {list(commands)!r} if cli.main(c) != 0]; "
        f"assert not failed, failed; assert {module!r} not in sys.modules, {module + ' imported'!r}"
    )
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


@dataclass(frozen=True)
class CliResult:
    code: int
    out: str
    err: str


@pytest.fixture(scope="session")
def examples_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A scratch copy of configs/ with its generated inputs (robots/ and data/)."""
    directory = tmp_path_factory.mktemp("examples")
    for config in CONFIGS.glob("*.yaml"):
        shutil.copy(config, directory / config.name)
    prepare(directory, frames=300)
    return directory


@pytest.fixture(scope="session")
def erd_share() -> Path:
    return example_robot_data_share()


@pytest.fixture
def allow_examples(examples_dir: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """For tests whose configs live elsewhere but read the session's examples: the runner allows that folder."""
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    return examples_dir


@pytest.fixture
def run_cli(capsys: pytest.CaptureFixture[str]):
    def run(*args: str) -> CliResult:
        try:
            code = cli.main(list(args))
        except SystemExit as usage:  # argparse's usage errors (parser.error) exit 2 as the real command does
            code = usage.code if isinstance(usage.code, int) else 1
        captured = capsys.readouterr()
        return CliResult(code, captured.out, captured.err)

    return run


@dataclass(frozen=True)
class S3:
    """The session's S3 endpoint as a test sees it: a fresh bucket of its own, the environment set (endpoint,
    credentials, URDF_PIPELINE_ALLOW_URLS allowing the bucket) for this process and the commands it starts."""

    endpoint: str
    bucket: str

    def url(self, key: str = "") -> str:
        return f"s3://{self.bucket}/{key}"

    def client(self):  # boto3's client of this endpoint, for a test to put and read objects itself
        import boto3

        return boto3.session.Session().client("s3", endpoint_url=self.endpoint)


@pytest.fixture(scope="session")
def s3_endpoint() -> Iterator[str]:
    """One moto_server for the session (tests/s3_server.py); skipped where moto is not installed."""
    from .s3_server import moto_server
    from .s3_server import s3_endpoint as started

    if moto_server() is None:
        pytest.skip("no moto_server: pip install 'moto[server]' (the test extra has it)")
    with started() as (url, _):
        yield url


@pytest.fixture
def s3(s3_endpoint: str, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest) -> S3:
    from .s3_server import CREDENTIALS

    for name, value in CREDENTIALS.items():
        monkeypatch.setenv(name, value)
    monkeypatch.setenv("AWS_ENDPOINT_URL", s3_endpoint)
    bucket = "t-" + "".join(c if c.isalnum() else "-" for c in request.node.name.lower())[:40].strip("-") + f"-{len(_BUCKETS)}"
    _BUCKETS.append(bucket)
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_URLS", f"s3://{bucket}/")
    found = S3(s3_endpoint, bucket)
    found.client().create_bucket(Bucket=bucket)
    return found


_BUCKETS: list[str] = []


@pytest.fixture
def remote_dataset(s3: S3, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """configs/so101_dataset.yaml (split layout) in a folder of the test's own, its outputs in the test's bucket
    (s3://BUCKET/so101/...), staged under tmp_path/staging."""
    from .dataset_helpers import edit_config, isolated_examples

    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))  # robots/ and data/ link to the session's examples
    monkeypatch.setenv("URDF_PIPELINE_STAGING", str(tmp_path / "staging"))
    config = isolated_examples(examples_dir, tmp_path / "run")

    def to_s3(data: dict) -> None:
        data["output"]["path"] = s3.url("so101/{segment}.rrd")
        data["output"]["model"] = s3.url("so101/model.rrd")

    return edit_config(config, to_s3)
