"""Thin command line: one function per subcommand (`commands.py`), each returning an exit code; the parser
(`parser.py`); one exit point for errors (`entry.main`).

Exit status: 0 success, 1 a user error (one `error: FILE:LINE:COL: message` line each), 2 bad command-line usage,
3 (`check` only) some joint's sampled values do not fit its limits with the config's corrections; `diff --exit-code`
as diff(1): 0 equal, 1 the plans differ, 2 any error;
70 an internal bug (with a traceback: please report it), 130 interrupted (Ctrl-C), 143 terminated (SIGTERM, handled as
Ctrl-C: see process/signals.py), 141 stdout closed early (`| head`).
"""

# the surface, imported at once: every command starts at main
from .entry import main
from .parser import build_parser
