"""Thin command line: one function per subcommand, each returning an exit code; one exit point for errors.

Exit status: 0 success, 1 a user error (one `error: FILE:LINE: message` line each), 2 bad command-line usage,
3 (`check` only) some joint's sampled values do not fit its limits with the config's corrections,
70 an internal bug (with a traceback: please report it).
"""

from __future__ import annotations

import argparse
import sys
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path

from .errors import UserError

EXIT_OK, EXIT_USER_ERROR, EXIT_BUG = 0, 1, 70


def cmd_run(args: argparse.Namespace) -> int:
    from .compile import compile_config
    from .execute import execute

    plan = compile_config(Path(args.config))
    for robot in plan.robots:
        print(f"urdf-pipeline: robot {robot.key}: URDF sha256 {robot.urdf_sha256} from {robot.urdf_origin}", file=sys.stderr)
    result = execute(plan)
    rows = ", ".join(f"{key}: {count} rows" for key, count in result.rows.items())
    print(f"urdf-pipeline: {rows} in {result.seconds:.1f} s", file=sys.stderr)
    print(result.output)
    return EXIT_OK


def cmd_validate(args: argparse.Namespace) -> int:
    from .compile import compile_config
    from .errors import Problems

    problems = Problems()
    for config in args.configs:
        try:
            compile_config(Path(config))
            print(f"ok: {config}")
        except UserError as exc:
            problems.extend(exc)
    problems.raise_if_any()
    return EXIT_OK


def cmd_check(args: argparse.Namespace) -> int:
    import json

    from .check import as_json, as_text, check_plan, exit_code, read_sample
    from .compile import compile_config

    plan = compile_config(Path(args.config))
    sample = {source.name: read_sample(source, args.rows) for source in plan.sources if plan.robots_for(source.name)}
    reports = check_plan(plan, sample)
    print(json.dumps(as_json(reports), indent=2) if args.format == "json" else as_text(reports))
    return exit_code(reports)


def cmd_plan(args: argparse.Namespace) -> int:
    from .compile import compile_config
    from .plan_report import describe_plan

    print(describe_plan(compile_config(Path(args.config))))
    return EXIT_OK


def cmd_schema(args: argparse.Namespace) -> int:
    from .schema import schema_text

    sys.stdout.write(schema_text())
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="urdf-pipeline", description="A robot config file becomes one validated Rerun recording.")
    commands = parser.add_subparsers(dest="command", required=True)
    run = commands.add_parser("run", help="validate CONFIG, compute forward kinematics and write the .rrd")
    run.add_argument("config")
    run.set_defaults(handler=cmd_run)
    validate = commands.add_parser("validate", help="check configs against the schema, URDFs and source metadata (no joint values read)")
    validate.add_argument("configs", nargs="+", metavar="CONFIG")
    validate.set_defaults(handler=cmd_validate)
    check = commands.add_parser(
        "check", help="read a sample of each source and say which corrections put every mapped joint inside its URDF limits"
    )
    check.add_argument("config")
    check.add_argument("--format", choices=("text", "json"), default="text")
    check.add_argument("--rows", type=int, default=100_000, help="rows to sample from the start of each source (default 100000)")
    check.set_defaults(handler=cmd_check)
    plan = commands.add_parser("plan", help="validate CONFIG and print what a run would do")
    plan.add_argument("config")
    plan.set_defaults(handler=cmd_plan)
    schema = commands.add_parser("schema", help="print the config's JSON Schema")
    schema.set_defaults(handler=cmd_schema)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except UserError as exc:
        for line in exc.lines():
            print(line, file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception:
        traceback.print_exc()
        print("urdf-pipeline: internal error (a bug, not your config); please report it with the traceback above", file=sys.stderr)
        return EXIT_BUG


if __name__ == "__main__":
    sys.exit(main())
