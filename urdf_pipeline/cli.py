"""Thin command line: one function per subcommand, each returning an exit code; one exit point for errors.

Exit status: 0 success, 1 a user error (one `error: FILE:LINE:COL: message` line each), 2 bad command-line usage,
3 (`check` only) some joint's sampled values do not fit its limits with the config's corrections,
70 an internal bug (with a traceback: please report it), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM, handled as
Ctrl-C: see interrupts.py), 141 stdout closed early (`| head`).
"""

from __future__ import annotations

import argparse
import os
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from . import PandasLeftOut
from .errors import ExitCode, UserError

if TYPE_CHECKING:
    from .execute import SegmentResult
    from .render import Size


def _positive(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError("must be at least 1")
    return value


def _size(text: str) -> Size:
    from .render import Size

    try:
        return Size.parse(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def cmd_run(args: argparse.Namespace) -> int:
    from .compile import compile_config
    from .dataset import RunOptions, register_outputs, run_dataset, summary_table, totals_line, write_report
    from .progress import SegmentProgress, say

    if args.catalog and not args.dataset:
        raise UserError("--catalog needs --dataset NAME: the catalog dataset to register the outputs in")
    plan = compile_config(Path(args.config), args.episodes)
    for robot in plan.robots:
        say(f"robot {robot.key}: URDF sha256 {robot.urdf_sha256} from {robot.urdf_origin}")
    if args.base:
        from .dataset import check_base

        say(f"all {check_base(plan, args.base)} segment id(s) found among the base recordings in {args.base}")
    segments = len(plan.segments)
    many = segments > 1 or plan.dataset.layout == "split"
    if many:
        say(f"{segments} segment(s), layout {plan.dataset.layout}, {args.jobs} job(s) on the {args.executor} executor")
    options = RunOptions(args.jobs, args.executor, args.ray_address, args.force, verbose=not many)
    run = run_dataset(plan, options, SegmentProgress() if many else None)
    if args.report:
        write_report(Path(args.report), plan, run, options)
    if run.blueprint is not None:
        say(f"blueprint (a 3D view of the scene and one per robot): {run.blueprint}")
    if many or run.interrupted:
        print(summary_table(run.results), file=sys.stderr)
        say(totals_line(run.results, run.seconds) + f"; manifest {run.manifest}")
    else:
        _print_single(run.results[0])
    for result in run.results:
        if result.status in ("written", "skipped"):
            print(result.output)
    bugs = [r for r in run.results if r.status == "bug"]
    for result in bugs:
        print(f"{result.label}: {result.reason}", file=sys.stderr)
    if run.interrupted:
        from .dataset import exit_status, signal_name

        print(f"interrupted ({signal_name(run.signal)}): only complete outputs were kept", file=sys.stderr)
        return exit_status(run.signal)
    if args.catalog:  # what was written (or is up to date) is registered even when other segments failed
        say(register_outputs(run, args.catalog, args.dataset, args.layer).summary())
    if args.spawn or args.connect:
        from .execute import send_to_viewer

        say(f"sent {send_to_viewer(plan, run.results, args.connect, args.spawn)} segment(s) to the viewer")
    if bugs:
        print("urdf-pipeline: internal error (a bug, not your config); please report it with the traceback above", file=sys.stderr)
        return ExitCode.BUG
    return ExitCode.USER_ERROR if any(r.status == "failed" for r in run.results) else ExitCode.OK


def _print_single(result: SegmentResult) -> None:
    """One recording: as a plain run always printed it (its error lines, or what was written)."""
    if result.status == "failed":
        print(result.reason, file=sys.stderr)
    elif result.status == "skipped":
        print(f"urdf-pipeline: {result.output} is up to date (same content hash); --force writes it again", file=sys.stderr)
    elif result.status == "written":
        print(f"urdf-pipeline: {result.label}: {result.frames} rows in {result.seconds:.1f} s", file=sys.stderr)


def cmd_validate(args: argparse.Namespace) -> int:
    """text: `ok: CONFIG` on stdout, `error:` / `warning: FILE:LINE:COL: ...` lines on stderr. github / json: stdout
    holds only the annotations (workflow commands, or one JSON list), `ok: CONFIG` goes to stderr. Exit 1 if any
    config has an error (warnings alone: 0)."""
    from .review import render_annotations, render_text_errors, render_text_progress, validate_config

    results = []
    for config in args.configs:
        result = validate_config(config)
        results.append(result)
        if args.format == "text":  # each config as it is done; its errors with every other's at the end
            progress = render_text_progress(result)
            sys.stderr.write(progress.stderr)
            sys.stdout.write(progress.stdout)
    if args.format == "text":
        sys.stderr.write(render_text_errors(results))
    else:
        shown = render_annotations(results, args.format)
        sys.stdout.write(shown.stdout)
        sys.stderr.write(shown.stderr)
    return ExitCode.OK if all(result.ok for result in results) else ExitCode.USER_ERROR


def cmd_check(args: argparse.Namespace) -> int:
    from .review import check_config, check_exit_code, render_check

    reports = check_config(Path(args.config), args.rows)
    sys.stdout.write(render_check(reports, args.format))
    return check_exit_code(reports)


def cmd_plan(args: argparse.Namespace) -> int:
    """text (default): the free-form account; markdown / json: the deterministic report for PR comments. Joint values
    are read only with --sample (then Rerun is imported)."""
    from .review import plan_command

    if args.rows is not None and not args.sample:
        args.parser.error("--rows needs --sample")
    if args.size is not None and args.render is None:
        args.parser.error("--size needs --render DIR")
    rows = (args.rows or 100_000) if args.sample else None
    render = Path(args.render) if args.render is not None else None
    sys.stdout.write(plan_command(Path(args.config), args.format, rows, render, args.size))
    return ExitCode.OK


def cmd_snapshot(args: argparse.Namespace) -> int:
    """Pictures of a written recording, drawn by the Rerun viewer (headless); their paths on stdout."""
    import time

    from .compile import compile_config
    from .render import DEFAULT_SIZE, SnapshotRequest, announce, snapshot

    plan = compile_config(Path(args.config))
    output = Path(args.output) if args.output else None
    request = SnapshotRequest(args.segment, args.at, args.view, args.size or DEFAULT_SIZE, output)
    started = time.perf_counter()
    pictures = snapshot(plan, request)
    announce(pictures, time.perf_counter() - started)
    for picture in pictures:
        print(picture.path)
    return ExitCode.OK


def cmd_schema(args: argparse.Namespace) -> int:
    from .config import schema_text

    sys.stdout.write(schema_text())
    return ExitCode.OK


def cmd_init(args: argparse.Namespace) -> int:
    from .review import init_config

    result, said = init_config(Path(args.urdf), args.source, Path(args.output) if args.output else None, args.force)
    if not args.output:
        sys.stdout.write(result.text)
    for line in said:
        print(line, file=sys.stderr)
    return ExitCode.OK


def cmd_diff(args: argparse.Namespace) -> int:
    from .review import diff_files, diff_git, render_diff

    if (args.git is None) == (args.new is None):
        args.parser.error("give OLD NEW, or CONFIG --git REV")
    if args.size is not None and args.render is None:
        args.parser.error("--size needs --render DIR")
    render = Path(args.render) if args.render is not None else None
    if args.git is not None:
        report = diff_git(args.old, args.git, render, args.size)
    else:
        report = diff_files(args.old, args.new, render, args.size)
    if args.format == "text":  # stdout keeps one line per change; the pictures are named on stderr
        for picture in report.pictures:
            print(f"urdf-pipeline: picture {picture.label}: {picture.path}", file=sys.stderr)
    sys.stdout.write(render_diff(report, args.format))
    return ExitCode.USER_ERROR if args.exit_code and not report.equivalent else ExitCode.OK


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="urdf-pipeline", description="A robot config file becomes one validated Rerun recording.")
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="validate CONFIG, compute forward kinematics and write the .rrd of every segment")
    run.add_argument("config")
    run.add_argument("--episodes", metavar="SPEC", help="override output.episodes: all, 0,3,7 or 10:20")
    run.add_argument("--jobs", type=_positive, default=os.cpu_count() or 1, help="segments written in parallel (default: number of cores)")
    run.add_argument("--executor", choices=("local", "ray"), default="local", help="local worker processes (default) or Ray tasks")
    run.add_argument("--ray-address", metavar="ADDR", help="the Ray cluster to run on (default: a local Ray instance)")
    run.add_argument("--force", action="store_true", help="write every segment, even those whose output is up to date")
    run.add_argument("--base", metavar="DIR_OR_GLOB", help="fail unless every segment id is the recording_id of a base .rrd there")
    run.add_argument("--catalog", metavar="URL", help="register the outputs in this Rerun catalog server (needs --dataset)")
    run.add_argument("--dataset", metavar="NAME", help="the catalog dataset (created when missing)")
    run.add_argument("--layer", default="urdf", help="the catalog layer name of the segments' outputs (default: urdf)")
    run.add_argument("--spawn", action="store_true", help="start a Rerun viewer and send it every segment (with the model)")
    run.add_argument("--connect", metavar="URL", help="send every segment to the viewer at URL (rerun+http://HOST:9876/proxy)")
    run.add_argument(
        "--report", metavar="FILE.json", help="write what the run did per segment (status, frames, seconds, worker, peak memory)"
    )
    run.set_defaults(handler=cmd_run, parser=run)
    validate = commands.add_parser("validate", help="check configs against the schema, URDFs and source metadata (no joint values read)")
    validate.add_argument("configs", nargs="+", metavar="CONFIG")
    validate.add_argument(
        "--format",
        choices=("text", "github", "json"),
        default="text",
        help="text: error: FILE:LINE:COL lines (default); github: workflow annotations; json: a list of problems",
    )
    validate.set_defaults(handler=cmd_validate, parser=validate)
    check = commands.add_parser(
        "check", help="read a sample of each source and say which corrections put every mapped joint inside its URDF limits"
    )
    check.add_argument("config")
    check.add_argument("--format", choices=("text", "json"), default="text")
    check.add_argument("--rows", type=int, default=100_000, help="rows to sample from the start of each source (default 100000)")
    check.set_defaults(handler=cmd_check, parser=check)
    plan = commands.add_parser("plan", help="validate CONFIG and print what a run would do")
    plan.add_argument("config")
    plan.add_argument(
        "--format",
        choices=("text", "markdown", "json"),
        default="text",
        help="text: the free-form account (default); markdown: a deterministic report for a PR comment; json: the same as data",
    )
    plan.add_argument("--sample", action="store_true", help="read a sample of each source and add the observed range per value")
    plan.add_argument("--rows", type=_positive, help="with --sample: rows read from the start of each source (default 100000)")
    plan.add_argument("--render", metavar="DIR", help="draw each robot at its rest pose into DIR (PNGs, by the Rerun viewer) and link them")
    plan.add_argument("--size", type=_size, metavar="WxH", help="with --render: the pictures' size in pixels (default 1024x768)")
    plan.set_defaults(handler=cmd_plan, parser=plan)
    snapshot = commands.add_parser(
        "snapshot",
        help="draw PNGs of a written recording with the Rerun viewer (headless) and print their paths",
        description="Draw pictures of a segment's recording (written by `run`) at times on its timeline, 3D view only, "
        "from a three-quarter camera that frames the robots' links over the whole segment. Needs a Vulkan driver "
        "(apt-get install mesa-vulkan-drivers on a machine without a GPU).",
    )
    snapshot.add_argument("config")
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
    snapshot.set_defaults(handler=cmd_snapshot, parser=snapshot)
    schema = commands.add_parser("schema", help="print the config's JSON Schema")
    schema.set_defaults(handler=cmd_schema, parser=schema)
    init = commands.add_parser("init", help="scaffold a config from a URDF, pre-matched to a source's names when --source is given")
    init.add_argument("--urdf", required=True, metavar="PATH", help="a plain URDF file")
    init.add_argument(
        "--source",
        metavar="SOURCE_SPEC",
        help="KIND:PATH[#PART]: lerobot:DIR[#FEATURE], parquet:FILE[#COLUMN], mcap:FILE[#TOPIC], hdf5:FILE#/DATASET, rrd:FILE#ENTITY, csv:FILE",
    )
    init.add_argument("-o", "--output", metavar="CONFIG", help="write the config here (default: stdout); paths in it are relative to it")
    init.add_argument("--force", action="store_true", help="overwrite an existing output file")
    init.set_defaults(handler=cmd_init, parser=init)
    diff = commands.add_parser(
        "diff",
        help="print the semantic difference of two configs' compiled plans (OLD NEW, or CONFIG --git REV)",
        description="Compile both configs and print what differs in their plans, one line per change (nothing when they are "
        "equivalent: key order, comments and equal spellings do not count). With --git REV, CONFIG's text at REV is compared "
        "with the working tree's; the files the old config refers to (URDF, data, sidecar edge files) are read from the working tree.",
    )
    diff.add_argument("old", metavar="OLD", help="the old config (with --git: the config)")
    diff.add_argument("new", metavar="NEW", nargs="?", help="the new config (not with --git)")
    diff.add_argument("--git", metavar="REV", help="compare CONFIG at git revision REV (git show REV:./CONFIG) with the working tree's")
    diff.add_argument(
        "--format", choices=("text", "json", "markdown"), default="text", help="markdown: for a PR comment, with links to the pictures"
    )
    diff.add_argument("--exit-code", action="store_true", help="exit 1 when there are differences (like git diff --exit-code)")
    diff.add_argument(
        "--render",
        metavar="DIR",
        help="draw the old and the new plan at the same joint values from one camera into DIR (PNGs, and the two side by side)",
    )
    diff.add_argument("--size", type=_size, metavar="WxH", help="with --render: the pictures' size in pixels (default 1024x768)")
    diff.set_defaults(handler=cmd_diff, parser=diff)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """SIGTERM is handled as Ctrl-C while a command runs (the caller's handler is given back: tests call this in-process)."""
    from .dataset import handle_sigterm, keep_sigterm_handler, restore_sigterm_handler

    # Rerun's own log lines (a WARN from its writer before our "cannot write" error) would say twice, and differently,
    # what our one error line says; RUST_LOG=warn (or any value the user sets) brings them back.
    os.environ.setdefault("RUST_LOG", "error")
    previous = keep_sigterm_handler()
    handle_sigterm()
    try:
        return _main(argv)
    finally:
        restore_sigterm_handler(previous)


def _main(argv: Sequence[str] | None) -> int:
    from .dataset import exit_status, signal_number

    args = build_parser().parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    left_out = PandasLeftOut() if _pandas_unused(args) and "pandas" not in sys.modules else None
    if left_out is not None:
        sys.meta_path.insert(0, left_out)  # type: ignore[arg-type]
    try:
        return handler(args)
    except UserError as exc:
        for line in exc.lines():
            print(line, file=sys.stderr)
        return ExitCode.USER_ERROR
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM (interrupts.Terminated): 128 + the signal's number
        print("interrupted", file=sys.stderr)
        return exit_status(signal_number(stop))
    except BrokenPipeError:  # `urdf-pipeline plan ... | head`: the reader left; not a bug
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the interpreter's final flush is quiet too
        return ExitCode.BROKEN_PIPE
    except Exception:
        traceback.print_exc()
        print("urdf-pipeline: internal error (a bug, not your config); please report it with the traceback above", file=sys.stderr)
        return ExitCode.BUG
    finally:
        if left_out is not None:
            sys.meta_path.remove(left_out)  # type: ignore[arg-type]


def _pandas_unused(args: argparse.Namespace) -> bool:
    if args.command == "run":
        return not args.catalog and args.executor == "local"
    return True


if __name__ == "__main__":
    sys.exit(main())
