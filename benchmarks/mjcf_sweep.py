"""The MJCF sweep of tests/urdf/test_mjcf_sweep.py as a table: model, bodies, joints, outcome, seconds.

Every MJCF file dm_control ships is loaded by `urdf: {mjcf: ...}`'s loader and its bodies compared with MuJoCo's
mj_kinematics. Prints a Markdown table and the totals (models matched, refused, the worst difference); exit 1 if any
model breaks the sweep's contract (a difference beyond the tolerance, a refusal not listed in the test's REFUSED).
Usage: python benchmarks/mjcf_sweep.py [--only SUBSTRING]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.urdf.test_mjcf_sweep import MODELS, REFUSED, ROOT, TOLERANCE, mujoco, worst_error  # noqa: E402
from urdf_pipeline.errors import UserError  # noqa: E402


def _row(relative: str) -> tuple[str, bool, float]:
    """The outcome's text, whether it keeps the contract, and the worst difference (0 for a refusal)."""
    try:
        worst = worst_error(relative)
    except UserError as exc:
        listed = relative in REFUSED and REFUSED[relative] in str(exc)
        return f"refused: {str(exc)[:120]}", listed, 0.0
    return f"{worst:.1e}", worst <= TOLERANCE and relative not in REFUSED, worst


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="the models whose path contains this text")
    args = parser.parse_args()
    print("| model | bodies | joints | worst difference (m / rad) | s |\n| --- | ---: | ---: | --- | ---: |")
    matched = refused = broken = 0
    worst = 0.0
    for relative in (m for m in MODELS if args.only in m):
        started = time.perf_counter()
        outcome, kept, difference = _row(relative)
        try:
            model = mujoco.MjModel.from_xml_path(str(ROOT / relative))
            sizes = f"{model.nbody} | {model.njnt}"
        except ValueError:
            sizes = "- | -"
        print(f"| {relative} | {sizes} | {outcome} | {time.perf_counter() - started:.2f} |")
        refused += outcome.startswith("refused")
        matched += not outcome.startswith("refused")
        broken += not kept
        worst = max(worst, difference)
    print(f"\n{matched} matched MuJoCo (worst {worst:.1e}), {refused} refused, {broken} broke the contract")
    return 1 if broken else 0


if __name__ == "__main__":
    sys.exit(main())
