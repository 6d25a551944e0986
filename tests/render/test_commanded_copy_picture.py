"""`appearance:` in the real viewer: a commanded copy drawn opaque hides the measured robot in its own colour; drawn at
opacity 0.4 the measured robot's materials show through it (the viewer blends a mesh whose albedo alpha is below 1)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from urdf_pipeline.examples import example_robot_data_share

from ..execute.test_commanded_copy import COLOR, commanded_config, episodes, write_commanded_dataset
from ..reference_fk import PinocchioRobot
from .conftest import SMALL
from .pixels import rgb


def _orange_share(picture: Path) -> tuple[int, float]:
    """The lit pixels above the caption, and the share of them in the copy's own hue (green/red near COLOR's 0.5)."""
    pixels = rgb(picture)[: SMALL.height * 4 // 5].astype(np.float64)
    red, green, blue = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    lit = red > 80
    ratio = green[lit] / red[lit]
    orange = (blue[lit] < 0.25 * red[lit]) & (ratio > 0.3) & (ratio < 0.62)
    return int(lit.sum()), float(orange.mean()) if lit.any() else 0.0


def test_a_translucent_copy_shows_the_measured_robot_through_it(renderer: None, examples_dir: Path, tmp_path: Path, run_cli) -> None:
    reference = PinocchioRobot(example_robot_data_share() / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
    measured, commanded = episodes(reference)
    write_commanded_dataset(examples_dir / "data" / "cmd_pic", [np.degrees(q) for q in measured], [np.degrees(q) for q in commanded])
    shares = {}
    for opacity in (1.0, 0.4):
        name = f"cmd_pic_{int(opacity * 10)}"
        appearance = {"appearance": {"color": COLOR, "opacity": opacity}}
        config = commanded_config(examples_dir, name, "data/cmd_pic", appearance)
        assert run_cli("run", str(config)).code == 0
        # frame 0 of episode 0: both robots in the same pose, the copy over the measured robot
        result = run_cli("snapshot", str(config), "--at", "first", "--size", f"{SMALL.width}x{SMALL.height}", "-o", str(tmp_path / name))
        assert result.code == 0, result.err
        shares[opacity] = _orange_share(Path(result.out.strip()))
    (lit_opaque, opaque), (lit_translucent, translucent) = shares[1.0], shares[0.4]
    assert lit_opaque > 500 and lit_translucent > 500, shares  # the robots are in the picture
    assert opaque > 0.9, f"the opaque copy covers the measured robot in its colour: {shares}"
    assert translucent < 0.2, f"the measured robot's materials show through the translucent copy: {shares}"
