"""One function per subcommand: each takes the parsed arguments and returns an exit status; errors are raised (the
one exit point, `entry._handle`, prints them). The work is in the stage packages, imported when a command runs."""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from ..errors import ExitCode, UserError, neutral_line, neutral_text, shown
from ..process import Stopped, require_viewer, spawn_viewer

if TYPE_CHECKING:
    from ..dataset import DatasetRun
    from ..execute import SegmentResult
    from ..plan import Plan
    from ..web import SiteWriter


def cmd_run(args: argparse.Namespace) -> int:
    """Compile, write every recording that is not up to date, say what happened; then register the outputs
    (--catalog) and send them to a viewer (--connect, --spawn). The exit status is the run's (`DatasetRun.exit_status`)."""
    if args.catalog and not args.dataset:
        raise UserError("--catalog needs --dataset NAME: the catalog dataset to register the outputs in")
    viewer = require_viewer(args.connect) if args.connect else None  # a viewer listening there, before any work
    if args.jobs is None:
        from ..dataset import usable_cpus

        args.jobs = usable_cpus()  # not the machine's count: the CPUs this process may use
    plan = _compiled_for_run(args)
    if args.spawn:  # a valid config: start the viewer (or find it running) before the run, so a failure costs nothing
        viewer = spawn_viewer()
    many = len(plan.segments) > 1 or plan.dataset.layout == "split"  # a dataset: a progress bar and a summary table
    run = _run_segments(args, plan, many)
    _say_results(run, many, plan.dataset.joint_series)
    if run.interrupted:
        from ..dataset import stopped_line

        print(stopped_line(run), file=sys.stderr)
        raise Stopped(run.signal, said=True)  # the exit point's status: 130 or 143
    _deliver(args, plan, run, viewer)
    if run.bugs:
        print("urdf-pipeline: internal error (a bug, not your config); please report it with the traceback above", file=sys.stderr)
    return run.exit_status


def _compiled_for_run(args: argparse.Namespace) -> Plan:
    """The config's plan, each robot's URDF named; with --base, its segment ids checked against the base recordings."""
    from ..compile import compile_config
    from ..logs import detail, say

    started = time.perf_counter()
    plan = compile_config(Path(args.config), args.episodes)
    detail(f"{args.config} compiled in {time.perf_counter() - started:.2f} s")
    for robot in plan.robots:
        say(f"robot {robot.key}: URDF sha256 {robot.urdf_sha256} from {robot.urdf_origin}")
    if args.base:
        from ..dataset import check_base

        say(f"all {check_base(plan, args.base)} segment id(s) found among the base recordings in {args.base}")
    return plan


def _run_segments(args: argparse.Namespace, plan: Plan, many: bool) -> DatasetRun:
    """The run on the executor asked for (`many`: with a progress bar, and each result's worker and notes at
    --verbose); with --report, what it did as JSON."""
    from ..dataset import RunOptions, report_target, run_dataset, write_report
    from ..logs import LOGGER, SegmentProgress, detail, say

    address, origin = _ray_address(args)

    def ready() -> None:  # said once nothing refuses the run: a refused run claims no work
        if many:
            say(f"{len(plan.segments)} segment(s), layout {plan.dataset.layout}, {args.jobs} job(s) on the {args.executor} executor")
        if args.executor == "ray":
            say(f"Ray: the cluster at {shown(address)} ({origin})" if address else f"Ray: a local instance ({origin})")

    report = report_target(args.report) if args.report else None  # a URL of the wrong form: refused before the run
    options = RunOptions(args.jobs, args.executor, address, args.force, verbose=not many)
    run = run_dataset(plan, options, SegmentProgress() if many and LOGGER.isEnabledFor(logging.INFO) else None, ready)
    for result in run.results if many else ():
        detail(f"{result.label}: {result.status} by {result.worker or 'no worker'}, peak {result.peak_rss_mib:.0f} MiB")
        for text in result.notes:
            detail(f"{result.label}: note: {text}")
    if report is not None:
        write_report(report, plan, run, options)
    return run


def _ray_address(args: argparse.Namespace) -> tuple[str | None, str]:
    """The Ray cluster `--executor ray` joins, and where that came from: `--ray-address`, else `RAY_ADDRESS` (as Ray's
    own tools read it), else none (a local instance started for the run)."""
    if args.ray_address:
        return args.ray_address, "--ray-address"
    if args.executor == "ray" and os.environ.get("RAY_ADDRESS", "").strip():
        return os.environ["RAY_ADDRESS"].strip(), "from RAY_ADDRESS; --ray-address overrides it"
    return None, "neither --ray-address nor RAY_ADDRESS is set"


def _say_results(run: DatasetRun, many: bool, joint_series: bool) -> None:
    """The blueprint, the summary (a dataset's table, or one recording's lines), the usable outputs' paths on stdout,
    and the traceback of every bug on stderr."""
    from ..dataset import differences_lines, summary_table, totals_line
    from ..logs import LOGGER, say

    if run.blueprint is not None:
        plots = ", beside plots of the driven joints" if joint_series else ""
        say(f"blueprint (a 3D view of the scene and one per robot{plots}): {run.blueprint}")
    if many or run.interrupted:
        LOGGER.info(summary_table(run.results))
        listed = f"manifest {run.manifest}" if run.manifest.is_file() else "no manifest: nothing to list"
        say(f"{totals_line(run.results, run.seconds)}; {listed}")
    else:
        _print_single(run.results[0])
    for line in differences_lines(run.results):
        say(line)
    for output in run.locations:
        print(neutral_line(output))
    for result in run.bugs:
        print(neutral_text(f"{result.label}: {result.reason}"), file=sys.stderr)


def _deliver(args: argparse.Namespace, plan: Plan, run: DatasetRun, viewer: str | None) -> None:
    """What was written (or is up to date) registered in the catalog and sent to the viewer, even when other
    segments failed."""
    from ..logs import say

    if args.catalog:
        from ..dataset import register_outputs

        say(register_outputs(run, args.catalog, args.dataset, args.layer).summary())
    if viewer is not None:
        from ..execute import send_to_viewer

        say(f"sent {send_to_viewer(plan, run.results, viewer)} segment(s) to the viewer at {viewer}")


def _print_single(result: SegmentResult) -> None:
    """One recording: as a plain run always printed it (its error lines, or what was written)."""
    from ..logs import say

    if result.status == "failed":
        print(neutral_text(result.reason), file=sys.stderr)
    elif result.status == "skipped":
        say(f"{result.output} is up to date (same content hash); --force writes it again")
    elif result.status == "written":
        say(f"{result.label}: {result.frames:,} rows in {result.seconds:.1f} s, written to {result.output}")


def cmd_validate(args: argparse.Namespace) -> int:
    """text: `ok: CONFIG` on stdout, `error:` / `warning: FILE:LINE:COL: ...` lines on stderr. github / json: stdout
    holds only the annotations (workflow commands, or one JSON list), `ok: CONFIG` goes to stderr. Exit 1 if any
    config has an error (warnings and notes alone: 0). `--no-data` opens no source file; `--skip-non-configs` skips
    (with a `skipped:` line on stderr) a YAML file that is not a config, for the pre-commit hook."""
    from ..review import render_annotations, render_text_errors, render_text_progress, validate_config

    results = []
    for config in args.configs:
        result = validate_config(config, data=not args.no_data, skip_non_configs=args.skip_non_configs, live=args.live)
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


def cmd_live(args: argparse.Namespace) -> int:
    """A robot's stream into a viewer (--connect, --spawn: the default without --save) and/or a file (--save): the
    config checked before anything is subscribed; the stream's end exits 0, Ctrl-C or SIGTERM end it the same way
    (its line said, --save kept) and exit 130 or 143, as they do every command."""
    from ..execute import folders_removed_if_left_empty
    from ..live_views import LiveOptions, live_command
    from ..logs import say

    viewer = require_viewer(args.connect) if args.connect else None
    if args.spawn or (viewer is None and args.save is None):
        viewer = spawn_viewer()
    save = Path(args.save) if args.save else None
    with folders_removed_if_left_empty([save.parent] if save is not None else []):  # refused at the first message: none left
        summary = live_command(LiveOptions(Path(args.config), args.source, viewer, save, args.reconnects))
    say(summary.line())
    return ExitCode.OK


def cmd_check(args: argparse.Namespace) -> int:
    from ..review import check_config, check_exit_code, render_check

    reports = check_config(Path(args.config), args.rows, args.episode, args.spread)
    text = render_check(reports, args.format)
    sys.stdout.write(neutral_text(text) if args.format == "text" else text)
    return check_exit_code(reports)


def cmd_plan(args: argparse.Namespace) -> int:
    """text (default): the free-form account; markdown / json: the deterministic report for PR comments. Joint values
    are read only with --sample (then Rerun is imported)."""
    from ..review import plan_command

    if args.rows is not None and not args.sample:
        args.parser.error("--rows needs --sample")
    if args.size is not None and args.render is None:
        args.parser.error("--size needs --render DIR")
    rows = (args.rows or 100_000) if args.sample else None
    render = Path(args.render) if args.render is not None else None
    with _site(args.html) as site:
        text = plan_command(Path(args.config), args.format, rows, render, args.size, site)
    _say_site(args.html)
    sys.stdout.write(text)
    return ExitCode.OK


@contextlib.contextmanager
def _site(folder: str | None) -> Iterator[SiteWriter | None]:
    """`--html DIR`: the site being built (a folder that is not a site is refused before any work), in its place when
    the command succeeds, DIR as it was when it fails; None without --html."""
    if folder is None:
        yield None
        return
    from ..execute import folders_removed_if_left_empty
    from ..web import write_site

    with folders_removed_if_left_empty([Path(folder).parent]), write_site(Path(folder)) as site:
        yield site


def _say_site(folder: str | None) -> None:
    if folder is not None:
        from ..logs import say

        say(f"site written to {folder}; look at it with: urdf-pipeline serve {folder}")


def cmd_qa(args: argparse.Namespace) -> int:
    """Every selected segment's joint data read as `run` reads it (no recording written), measured and flagged; the
    report on stdout or -o FILE, the flagged episodes in --exclusions FILE; exit 1 when a --fail-on flag is raised."""
    from ..compile import compile_config
    from ..execute import dataset_qa, write_file_atomically
    from ..review import fail_on_flags, failure, render_qa

    fail_on_flags(args.fail_on, ())  # a bad --fail-on is refused before any data is read
    plan = compile_config(Path(args.config), args.episodes)
    report = dataset_qa(plan)
    data = report.as_data()
    text = render_qa(data, args.format, args.config)
    if args.output:
        write_file_atomically(Path(args.output), lambda partial: partial.write_text(text, encoding="utf-8"), None)
    else:
        sys.stdout.write(neutral_text(text) if args.format == "text" else text)  # the other forms escape their own data
    if args.exclusions:
        listed = json.dumps(report.exclusions()) + "\n"
        write_file_atomically(Path(args.exclusions), lambda partial: partial.write_text(listed, encoding="utf-8"), None)
    problem = failure(data, fail_on_flags(args.fail_on, plan.qa.fail_on))
    if problem is not None:
        raise problem
    return ExitCode.OK


def cmd_snapshot(args: argparse.Namespace) -> int:
    """Pictures of a written recording, drawn by the Rerun viewer (headless); their paths on stdout."""
    from ..compile import compile_config
    from ..render import DEFAULT_SIZE, SnapshotRequest, announce, snapshot

    plan = compile_config(Path(args.config))
    output = Path(args.output) if args.output else None
    request = SnapshotRequest(args.segment, args.at, args.view, args.size or DEFAULT_SIZE, output)
    started = time.perf_counter()
    pictures = snapshot(plan, request)
    announce(pictures, time.perf_counter() - started)
    for picture in pictures:
        print(neutral_line(str(picture.path)))
    return ExitCode.OK


def cmd_schema(args: argparse.Namespace) -> int:
    from ..config import schema_text
    from ..scaffold import write_schema

    if args.output:
        write_schema(Path(args.output))
    else:
        sys.stdout.write(schema_text())
    return ExitCode.OK


def cmd_init(args: argparse.Namespace) -> int:
    from ..scaffold import init_config, urdf_argument

    try:
        urdf = urdf_argument(args.urdf, args.xacro, args.arg, args.robot_descriptions)
    except ValueError as exc:  # --arg malformed, or without --xacro
        args.parser.error(str(exc))
    result, said = init_config(urdf, args.source, Path(args.output) if args.output else None, args.force)
    if not args.output:
        sys.stdout.write(result.text)
    for line in said:
        print(neutral_line(line), file=sys.stderr)
    return ExitCode.OK


def cmd_diff(args: argparse.Namespace) -> int:
    from ..review import diff_files, diff_git, render_diff

    if (args.git is None) == (args.new is None):
        args.parser.error("give OLD NEW, or CONFIG --git REV")
    if args.size is not None and args.render is None:
        args.parser.error("--size needs --render DIR")
    render = Path(args.render) if args.render is not None else None
    with _site(args.html) as site:
        if args.git is not None:
            report = diff_git(args.old, args.git, render, args.size, site)
        else:
            report = diff_files(args.old, args.new, render, args.size, site)
    _say_site(args.html)
    if args.format == "text":  # stdout keeps one line per change; the pictures are named on stderr
        for picture in report.pictures:
            print(neutral_line(f"urdf-pipeline: picture {picture.label}: {picture.path}"), file=sys.stderr)
    sys.stdout.write(render_diff(report, args.format))
    return ExitCode.DIFFERENT if args.exit_code and not report.equivalent else ExitCode.OK


def cmd_browse(args: argparse.Namespace) -> int:
    """A dataset browser over the config's written outputs (from the run's manifest only); the site's folder on stdout."""
    from ..compile import compile_config
    from ..execute import folders_removed_if_left_empty
    from ..logs import say
    from ..web import browse_config

    plan = compile_config(Path(args.config))
    with folders_removed_if_left_empty([Path(args.output).parent]):
        result = browse_config(plan, Path(args.output), args.config, args.base)
    missing = f", {result.missing} with something missing" if result.missing else ""
    say(
        f"browser of {result.segments} segment(s){missing} written in {result.seconds:.3f} s "
        f"(segments.json {result.data_bytes / 1e6:.1f} MB); `urdf-pipeline serve {args.output}` shows it"
    )
    print(neutral_line(str(result.site)))
    return ExitCode.OK


def cmd_serve(args: argparse.Namespace) -> int:
    """A site on http://127.0.0.1:PORT/ until Ctrl-C or SIGTERM (exit 130 or 143, as every command they stop); its URL
    is the one line on stdout."""
    from ..logs import say
    from ..web import SiteServer, serve_site

    def ready(server: SiteServer) -> None:
        chosen = "a free port" if args.port == 0 else f"port {server.port}"
        say(f"serving {server.folder} on {chosen} of 127.0.0.1 (only this machine can connect); Ctrl-C stops")
        print(server.url, flush=True)

    serve_site(Path(args.dir), args.port, ready)
    return ExitCode.OK
