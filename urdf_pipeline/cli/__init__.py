"""Thin command line: one function per subcommand (`commands.py`), the parser (`parser.py`), and one exit point
(`entry.main`) whose statuses are `errors.ExitCode`."""

# the surface, imported at once: every command starts at main
from .entry import main
from .parser import build_parser
