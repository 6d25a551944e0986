"""The URDF sweep of tests/urdf/test_urdf_sweep.py as a table: robot, source file, outcome, seconds.

Every URDF of example-robot-data and rtb-data (and rtb-data's xacro robots) is validated, run through the real CLI
in this one process and compared with pinocchio. Prints a Markdown table and the totals; exit 1 if any robot breaks
the sweep's contract (a failure, or a refusal not listed in the test's REFUSED).
Usage: python benchmarks/urdf_sweep.py [--only SUBSTRING] [--workdir DIR]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.urdf.test_urdf_sweep import check_outcome, run_case, sweep_cases  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="run the robots whose source contains this text")
    parser.add_argument("--workdir", type=Path, help="keep configs, data and recordings here")
    args = parser.parse_args()
    directory = args.workdir or Path(tempfile.mkdtemp(prefix="urdf-sweep-"))
    started = time.perf_counter()
    kinds: Counter[str] = Counter()
    broken = 0
    print("| robot | source file | outcome | s |\n| --- | --- | --- | --- |", flush=True)
    for case in sweep_cases():
        if args.only not in case.source:
            continue
        outcome = run_case(case, directory)
        kinds[outcome.kind] += 1
        try:
            check_outcome(outcome)
        except AssertionError as exc:
            broken += 1
            print(f"<!-- contract broken: {exc} -->")
        print(outcome.row(), flush=True)
    total = sum(kinds.values())
    summary = ", ".join(f"{count} {kind}" for kind, count in sorted(kinds.items()))
    print(f"\n{total} robots in {time.perf_counter() - started:.0f} s: {summary}; {broken} break the contract")
    return 1 if broken else 0


if __name__ == "__main__":
    raise SystemExit(main())
