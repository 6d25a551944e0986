"""Inputs of the MCAP / HDF5 / RRD / wide-table cases in tests/configs/invalid/ (made by test_invalid_configs.py's fixture)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from urdf_pipeline.examples import PANDA_NAMES

from .bag_inputs import write_robot_bag
from .sources.test_sources_hdf5 import write_aloha_episode
from .sources.test_sources_mcap import write_joint_states
from .sources.test_sources_rrd import write_state_rrd
from .sources.test_sources_wide import write_wide_inputs


def write_source_inputs(data: Path, raw: np.ndarray) -> None:
    """`raw`: Panda values in the contract config's units, one column per PANDA_NAMES (j1..j7, finger)."""
    rng = np.random.default_rng(7)
    messages = []
    for row, values in enumerate(raw):
        order = rng.permutation(len(PANDA_NAMES))
        names, positions = [PANDA_NAMES[i] for i in order], [float(values[i]) for i in order]
        if 100 <= row < 110:  # these ten messages lack j4
            keep = [i for i, name in enumerate(names) if name != "j4"]
            names, positions = [names[i] for i in keep], [positions[i] for i in keep]
        messages.append((names, positions))
    write_joint_states(data / "lacking_j4.mcap", messages)
    write_joint_states(data / "unstamped.mcap", messages[:20], stamps_ns=[0] * 20)
    write_aloha_episode(data / "aloha_26.hdf5", np.concatenate([raw, np.zeros((len(raw), 18))], axis=1))
    write_state_rrd(data / "named_state.rrd", raw, PANDA_NAMES)
    write_wide_inputs(data, raw)
    camera = ("panda_hand", "camera_link", (0.05, 0.0, 0.04), (0.0, 0.0, 0.0, 1.0))
    hand = ("panda_link8", "panda_hand", (0.0, 0.0, 0.0), (0.0, 0.0, -0.3826834, 0.9238795))  # what the URDF's joint places
    base = [[("world", "panda_link0", (0.01 * row, 0.0, 0.5), (0.0, 0.0, 0.0, 1.0))] for row in range(20)]
    bag_values = np.zeros((20, 1))
    write_robot_bag(data / "robot_bag.mcap", ["<robot name='x'><link name='a'/></robot>"], [[camera, hand]], ["j"], bag_values, base)
