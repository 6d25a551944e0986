"""The one exit point: parse, set up logging for the command, run its function, and turn what it raised into an
exit status (a user error's lines, a bug's traceback, Ctrl-C, a closed stdout)."""

from __future__ import annotations

import argparse
import logging
import os
import sys
import traceback
from collections.abc import Callable, Sequence

from ..errors import ExitCode, UserError, neutral_text
from ..logs import command_logging, warnings_logged
from ..package import PandasLeftOut
from ..process import Stopped, sigterm_kept, stop_signal
from .parser import build_parser
from .stderr_relay import stderr_through_logger


def main(argv: Sequence[str] | None = None) -> int:
    """SIGTERM is handled as Ctrl-C while a command runs (the caller's handler is given back: tests call this in-process)."""
    with sigterm_kept(stops=True):
        return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    args = build_parser().parse_args(argv)
    handler: Callable[[argparse.Namespace], int] = args.handler
    # Rerun's own log lines (a WARN from its writer before our "cannot write" error) would say twice, and differently,
    # what our one error line says; --verbose, RUST_LOG=warn (or any value the user sets) brings them back. They and
    # Python's warnings reach stderr through our logger (stderr_relay.py), as everything else the command says.
    os.environ.setdefault("RUST_LOG", "warn" if args.verbose else "error")
    level = logging.WARNING if args.quiet else logging.DEBUG if args.verbose else logging.INFO
    with command_logging(level), stderr_through_logger(), warnings_logged():
        return _handle(handler, args)


def _handle(handler: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    """The one exit point: a user error's lines, a bug's traceback, Ctrl-C and a closed stdout, as exit statuses."""
    # `diff --exit-code` says 1 for "they differ", so its errors (a user error, a bug) say 2, as diff(1) does
    trouble = ExitCode.DIFF_TROUBLE if getattr(args, "exit_code", False) else None

    pandas_unused = args.command != "run" or (not args.catalog and args.executor == "local")  # a catalog client, Ray: pandas
    left_out = PandasLeftOut() if pandas_unused and "pandas" not in sys.modules else None
    if left_out is not None:
        sys.meta_path.insert(0, left_out)
    try:
        return handler(args)
    except UserError as exc:
        for line in exc.lines():
            print(line, file=sys.stderr)
        return trouble or ExitCode.USER_ERROR
    except KeyboardInterrupt as stop:  # Ctrl-C, or SIGTERM (process.Stopped), whichever command: 128 + the signal's number
        if not (isinstance(stop, Stopped) and stop.said):  # a command that said its own last line (live, run) keeps it last
            print("interrupted", file=sys.stderr)
        return ExitCode.for_signal(stop_signal(stop))
    except BrokenPipeError:  # `urdf-pipeline plan ... | head`: the reader left; not a bug
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())  # so the interpreter's final flush is quiet too
        return ExitCode.BROKEN_PIPE
    except Exception:
        sys.stderr.write(neutral_text(traceback.format_exc()))  # a bug's message may quote input
        print("urdf-pipeline: internal error (a bug, not your config); please report it with the traceback above", file=sys.stderr)
        return trouble or ExitCode.BUG
    finally:
        if left_out is not None:
            sys.meta_path.remove(left_out)
