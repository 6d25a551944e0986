"""The argument parser: every subcommand with -q / -v, and the types that make bad values usage errors (exit 2)."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from typing import TYPE_CHECKING, NoReturn

from .commands import (
    cmd_browse,
    cmd_check,
    cmd_diff,
    cmd_init,
    cmd_live,
    cmd_plan,
    cmd_qa,
    cmd_run,
    cmd_schema,
    cmd_serve,
    cmd_snapshot,
    cmd_validate,
)

if TYPE_CHECKING:
    from ..render import Size


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def _port(text: str) -> int:
    value = int(text)
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError("must be between 0 and 65535 (0: a free port)")
    return value


def _size(text: str) -> Size:
    from ..render import Size

    try:
        return Size.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _version() -> str:
    """Ours and the Rerun SDK's (the one a recording's format depends on), from the installed metadata: no import."""
    from importlib.metadata import PackageNotFoundError, version

    from ..package import __version__

    try:
        rerun = version("rerun-sdk")
    except PackageNotFoundError:
        rerun = "not installed"
    return f"urdf-pipeline {__version__} (rerun-sdk {rerun}, Python {sys.version.split()[0]})"


CONFIG_HELP = "the robot setup's YAML config (paths in it are relative to its folder)"
"""The help of the CONFIG argument, the same in every command that reads one."""

EXAMPLE_HEADING = "example (on the configs `make demo` writes and runs):"


def _verbosity(parser: argparse.ArgumentParser, default: object) -> None:
    """-q / -v, on the main parser and on every subcommand (`urdf-pipeline run -q CONFIG` and `urdf-pipeline -q run`)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-q", "--quiet", action="store_true", default=default, help="print only warnings and errors on stderr")
    group.add_argument("-v", "--verbose", action="store_true", default=default, help="also print timings and per-segment notes")


class _Commands:
    """Subparsers that all take -q / -v (defaults suppressed, so the main parser's value stays) and name their handler
    and parser for `main`; each has one summary, the CONFIG argument when it reads one, and one example that runs as typed."""

    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self.actions = parser.add_subparsers(dest="command", required=True)

    def add_parser(
        self, name: str, handler: Callable[[argparse.Namespace], int], summary: str, example: str, config: str | None = None
    ) -> argparse.ArgumentParser:
        sub = self.actions.add_parser(
            name,
            help=summary,
            description=summary,
            epilog=f"{EXAMPLE_HEADING}\n  {example}",
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        _verbosity(sub, argparse.SUPPRESS)
        sub.set_defaults(handler=handler, parser=sub)
        if config is not None:
            sub.add_argument(config, metavar="CONFIG", nargs="+" if config == "configs" else None, help=CONFIG_HELP)
        return sub


class _Parser(argparse.ArgumentParser):
    """argparse quotes what it refused (`unrecognized arguments: ...`): a file name from a pull request could hold a
    newline and a workflow command, so the usage error goes out neutralised, as every line the tool prints."""

    def error(self, message: str) -> NoReturn:
        from ..errors import neutral_line

        self.print_usage(sys.stderr)
        self.exit(2, neutral_line(f"{self.prog}: error: {message}") + "\n")


def build_parser() -> argparse.ArgumentParser:
    """The main parser (--version, -q / -v) and one subparser per command, in the order `--help` lists them."""
    parser = _Parser(prog="urdf-pipeline", description="A robot config file becomes one validated Rerun recording.")
    parser.add_argument("--version", action="version", version=_version())
    _verbosity(parser, False)
    commands = _Commands(parser)
    for add_command in (
        _add_run,
        _add_validate,
        _add_check,
        _add_plan,
        _add_qa,
        _add_snapshot,
        _add_schema,
        _add_init,
        _add_diff,
        _add_browse,
        _add_serve,
        _add_live,
    ):
        add_command(commands)
    return parser


def _add_run(commands: _Commands) -> None:
    """run: the segments to write and where they go (executor, catalog, a viewer, a report)."""
    run = commands.add_parser(
        "run",
        cmd_run,
        "validate CONFIG, compute forward kinematics and write the .rrd of every segment",
        "urdf-pipeline run configs/so101_dataset.yaml --episodes 0,1",
        config="config",
    )
    run.add_argument("--episodes", metavar="SPEC", help="override output.episodes: all, 0,3,7 or 10:20")
    run.add_argument(
        "--jobs", type=_positive, help="segments written in parallel (default: the CPUs this process may use: affinity, cgroup quota)"
    )
    run.add_argument("--executor", choices=("local", "ray"), default="local", help="local worker processes (default) or Ray tasks")
    run.add_argument(
        "--ray-address", metavar="ADDR", help="the Ray cluster to run on (default: RAY_ADDRESS when set, else a local Ray instance)"
    )
    run.add_argument("--force", action="store_true", help="write every segment, even those whose output is up to date")
    run.add_argument("--base", metavar="DIR_OR_GLOB", help="fail unless every segment id is the recording_id of a base .rrd there")
    run.add_argument("--catalog", metavar="URL", help="register the outputs in this Rerun catalog server (needs --dataset)")
    run.add_argument("--dataset", metavar="NAME", help="the catalog dataset (created when missing)")
    run.add_argument("--layer", default="urdf", help="the catalog layer name of the segments' outputs (default: urdf)")
    viewer = run.add_mutually_exclusive_group()
    viewer.add_argument(
        "--spawn", action="store_true", help="start a Rerun viewer (or use the one on port 9876) and send it every segment (with the model)"
    )
    viewer.add_argument(
        "--connect", metavar="URL", help="send every segment to the viewer at URL (rerun+http://HOST:PORT/proxy), checked before the run"
    )
    run.add_argument(
        "--report", metavar="FILE.json", help="write what the run did per segment (status, frames, seconds, worker, peak memory)"
    )


def _add_validate(commands: _Commands) -> None:
    """validate: many configs at once, the output form for CI, and what to skip (the data, files that are no config)."""
    validate = commands.add_parser(
        "validate",
        cmd_validate,
        "check configs against the schema, URDFs and source metadata (no joint values read)",
        "urdf-pipeline validate --no-data configs/demo.yaml configs/ur5_ros2_bag.yaml",
        config="configs",
    )
    validate.add_argument(
        "--format",
        choices=("text", "github", "json"),
        default="text",
        help="text: error: FILE:LINE:COL lines (default); github: workflow annotations; json: a list of problems",
    )
    validate.add_argument(
        "--no-data",
        action="store_true",
        help="open no source file (configs in git, datasets elsewhere): schema, URDFs, meshes, joint coverage and frame "
        "graph only; names that only the data holds are checked by validate with the data, and by run",
    )
    validate.add_argument(
        "--live",
        action="store_true",
        help="check CONFIG for `live --from` without data: --no-data's checks, and every source a robot reads an MCAP "
        "topic (names unknown without data are taken from the stream's first message)",
    )
    validate.add_argument(
        "--skip-non-configs",
        action="store_true",
        help="skip a YAML file that is not a config (a top-level list such as a sidecar edges file, or a mapping with "
        "none of a config's top-level keys), with a `skipped:` line on stderr; for the pre-commit hook",
    )


def _add_live(commands: _Commands) -> None:
    """live: where the samples come from and where they go."""
    live = commands.add_parser(
        "live",
        cmd_live,
        "drive CONFIG's robots from a live stream (a Foxglove WebSocket server, an MCAP file being written) into a viewer",
        "urdf-pipeline live configs/ur5_ros2_bag.yaml --from configs/data/ur5_joint_states.mcap --save configs/out/live.rrd",
        config="config",
    )
    live.add_argument(
        "--from", dest="source", required=True, metavar="URL", help="ws://HOST:PORT, or the path of an MCAP file being written"
    )
    viewer = live.add_mutually_exclusive_group()
    viewer.add_argument(
        "--spawn", action="store_true", help="start a Rerun viewer (or use the one on port 9876); the default without --save"
    )
    viewer.add_argument("--connect", metavar="URL", help="send to the viewer at URL (rerun+http://HOST:PORT/proxy), checked first")
    live.add_argument("--save", metavar="FILE.rrd", help="also write what is seen to FILE.rrd (renamed into place when live ends)")
    live.add_argument(
        "--reconnects", type=_positive, default=10, metavar="N", help="reconnect attempts in a row before giving up (default: 10)"
    )


def _add_check(commands: _Commands) -> None:
    """check: how much of each source it samples."""
    check = commands.add_parser(
        "check",
        cmd_check,
        "read a sample of each source and say which corrections put every mapped joint inside its URDF limits",
        "urdf-pipeline check configs/so101_lerobot.yaml",
        config="config",
    )
    check.add_argument("--format", choices=("text", "json"), default="text")
    check.add_argument("--rows", type=_positive, default=100_000, help="rows to sample from the start of each source (default 100000)")
    check.add_argument(
        "--episode",
        metavar="SPEC",
        help="sample this episode's segment instead of the first (run's --episodes syntax: 3; with --spread, any SPEC)",
    )
    check.add_argument(
        "--spread",
        type=_positive,
        metavar="N",
        help="sample N segments spread evenly over the dataset (first, last, between), not the first only",
    )


def _add_plan(commands: _Commands) -> None:
    """plan: the report's form, an optional sample of the data and optional pictures."""
    plan = commands.add_parser(
        "plan",
        cmd_plan,
        "validate CONFIG and print what a run would do",
        "urdf-pipeline plan configs/demo.yaml --format markdown",
        config="config",
    )
    plan.add_argument(
        "--format",
        choices=("text", "markdown", "json"),
        default="text",
        help="text: the free-form account (default); markdown: a deterministic report for a PR comment; json: the same as data",
    )
    plan.add_argument("--sample", action="store_true", help="read a sample of each source and add the observed range per value")
    plan.add_argument("--rows", type=_positive, help="with --sample: rows read from the start of each source (default 100000)")
    _picture_options(
        plan,
        "draw each robot at its rest pose into DIR (PNGs, by the Rerun viewer) and link them",
        "the report as a static site in DIR too, with the rest pose in Rerun's web viewer (and the pictures of --render)",
    )


def _add_qa(commands: _Commands) -> None:
    """qa: the segments, the report's form and file, the failing flags and the exclusions file."""
    qa = commands.add_parser(
        "qa",
        cmd_qa,
        "read every segment of CONFIG and report its QA metrics and flags (spikes, still episodes, timing) without writing a recording",
        "urdf-pipeline qa configs/so101_lerobot.yaml --format markdown",
        config="config",
    )
    qa.add_argument("--episodes", metavar="SPEC", help="override output.episodes: all, 0,3,7 or 10:20")
    qa.add_argument("--format", choices=("text", "json", "github", "markdown"), default="text", help="the report's form (default text)")
    qa.add_argument("-o", "--output", metavar="FILE", help="write the report here (atomically) instead of stdout")
    qa.add_argument("--fail-on", metavar="FLAGS", help="exit 1 when a segment raises one of these flags (comma list; default: qa.fail_on)")
    qa.add_argument("--exclusions", metavar="FILE", help="write the flagged segments' LeRobot episode indices here, as a JSON list")


def _add_snapshot(commands: _Commands) -> None:
    """snapshot: which segment, at which times, of what, how big and where the pictures go."""
    snapshot = commands.add_parser(
        "snapshot",
        cmd_snapshot,
        "draw PNGs of a written recording with the Rerun viewer (headless) and print their paths",
        "urdf-pipeline snapshot configs/demo.yaml --at first,last --size 640x480",
        config="config",
    )
    snapshot.add_argument("--segment", metavar="ID", help="the segment (recording id) to draw (default: the first)")
    snapshot.add_argument(
        "--at",
        metavar="T,...",
        help="times on the segment's timeline: first, middle, last, a sequence number, or seconds (duration and timestamp "
        "timelines; an ISO 8601 time also for timestamps). Default: first,middle,last",
    )
    snapshot.add_argument("--view", default="scene", metavar="scene|ROBOT", help="the whole scene (default) or one robot's key")
    snapshot.add_argument("--size", type=_size, default=None, metavar="WxH", help="the pictures' size in pixels (default 1024x768)")
    snapshot.add_argument("-o", "--output", metavar="DIR", help="where the PNGs go (default: pictures/ beside the recording)")


def _add_schema(commands: _Commands) -> None:
    """schema: where the JSON Schema goes."""
    schema = commands.add_parser(
        "schema", cmd_schema, "print the config's JSON Schema", "urdf-pipeline schema -o configs/out/urdf-pipeline.schema.json"
    )
    schema.add_argument("-o", "--output", metavar="FILE", help="write it to FILE (schemas/urdf-pipeline.schema.json: init finds it)")


def _add_init(commands: _Commands) -> None:
    """init: exactly one form of URDF (as run loads it), an optional source to match names against, the output file."""
    init = commands.add_parser(
        "init",
        cmd_init,
        "scaffold a config from a URDF, pre-matched to a source's names when --source is given",
        "urdf-pipeline init --urdf configs/robots/panda.urdf --source parquet:configs/data/episode_000.parquet#observation.state",
    )
    robot = init.add_mutually_exclusive_group(required=True)
    robot.add_argument("--urdf", metavar="PATH", help="a plain URDF file")
    robot.add_argument("--xacro", metavar="FILE", help="a xacro file, expanded as run expands it, with each --arg NAME=VALUE")
    robot.add_argument("--robot-descriptions", metavar="NAME", help="a robot_descriptions module (so_arm101_description)")
    init.add_argument("--arg", action="append", default=[], metavar="NAME=VALUE", help="with --xacro: a xacro argument; repeatable")
    init.add_argument(
        "--source",
        metavar="SOURCE_SPEC",
        help="KIND:PATH[#PART]: lerobot:DIR[#FEATURE], parquet:FILE[#COLUMN], mcap:FILE[#TOPIC], hdf5:FILE#/DATASET, rrd:FILE#ENTITY, csv:FILE",
    )
    init.add_argument("-o", "--output", metavar="CONFIG", help="write the config here (default: stdout); paths in it are relative to it")
    init.add_argument("--force", action="store_true", help="overwrite an existing output file")


def _add_diff(commands: _Commands) -> None:
    """diff: two configs (or one and a git revision), the output form, diff(1)'s exit code and optional pictures."""
    diff = commands.add_parser(
        "diff",
        cmd_diff,
        "print the semantic difference of two configs' compiled plans (OLD NEW, or CONFIG --git REV)",
        "urdf-pipeline diff configs/demo.yaml configs/bimanual_pandas.yaml",
    )
    diff.add_argument("old", metavar="OLD", help="the old config (with --git: the config)")
    diff.add_argument("new", metavar="NEW", nargs="?", help="the new config (not with --git)")
    diff.add_argument("--git", metavar="REV", help="compare CONFIG at git revision REV (git show REV:./CONFIG) with the working tree's")
    diff.add_argument(
        "--format", choices=("text", "json", "markdown"), default="text", help="markdown: for a PR comment, with links to the pictures"
    )
    diff.add_argument(
        "--exit-code", action="store_true", help="exit 0 when the plans are equal, 1 when they differ, 2 on any error (as diff(1) does)"
    )
    _picture_options(
        diff,
        "draw the old and the new plan at the same joint values from one camera into DIR (PNGs, and the two side by side)",
        "the report as a static site in DIR too, with old and new in Rerun's web viewer (and the pictures of --render)",
    )


def _picture_options(parser: argparse.ArgumentParser, render_help: str, html_help: str) -> None:
    """--render DIR with its --size, and --html DIR (a site besides the report on stdout): the same for plan and diff."""
    parser.add_argument("--render", metavar="DIR", help=render_help)
    parser.add_argument("--size", type=_size, metavar="WxH", help="with --render: the pictures' size in pixels (default 1024x768)")
    parser.add_argument("--html", metavar="DIR", help=html_help + "; stdout keeps the --format report; look at it with `serve DIR`")


def _add_browse(commands: _Commands) -> None:
    """browse: the config and the site's folder."""
    browse = commands.add_parser(
        "browse",
        cmd_browse,
        "write a dataset browser (a static site) over CONFIG's written outputs (run CONFIG first) into DIR",
        "urdf-pipeline browse configs/demo.yaml -o configs/out/site",
        config="config",
    )
    browse.add_argument("-o", "--output", required=True, metavar="DIR", help="the site's folder (new, empty, or a site written before)")
    browse.add_argument(
        "--base",
        metavar="DIR_OR_GLOB",
        help="base .rrd recordings (as run --base): a segment opens with the one whose recording_id is its id (else a row note)",
    )


def _add_serve(commands: _Commands) -> None:
    """serve: the site's folder and the port."""
    serve = commands.add_parser(
        "serve",
        cmd_serve,
        "serve a site (plan --html, diff --html, browse -o) on http://127.0.0.1:PORT/ and print its URL; Ctrl-C stops",
        "urdf-pipeline serve configs/out/site",
    )
    serve.add_argument("dir", metavar="DIR", help="the site's folder (it holds an index.html)")
    serve.add_argument("--port", type=_port, default=0, metavar="N", help="the port to listen on (default 0: a free port, printed)")
