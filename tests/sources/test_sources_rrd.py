"""RRD sources: joint values already in a Rerun recording (as Rerun's LeRobot, MCAP or HDF5 importers write them)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
import rerun as rr
from rerun.chunk import Chunk, LazyChunkStream, McapReader
from rerun.experimental import Hdf5Reader

from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q
from .test_sources_hdf5 import write_aloha_episode
from .test_sources_mcap import shuffled_messages, write_joint_states


def write_state_rrd(path: Path, values: np.ndarray, names: list[str] | None, entity: str = "/observation.state") -> None:
    """LeRobot importer's layout: Scalars:scalars (one value per instance) per frame_index, static SeriesLines:names."""
    rows, width = values.shape
    chunks = []
    if names is not None:
        chunks.append(Chunk.from_columns(entity, indexes=[], columns=rr.SeriesLines.columns(names=names).partition([len(names)])))
    for start in range(0, rows, 16):  # several chunks
        block = values[start : start + 16]
        chunks.append(
            Chunk.from_columns(
                entity,
                indexes=[rr.TimeColumn("frame_index", sequence=np.arange(start, start + len(block)))],
                columns=rr.Scalars.columns(scalars=block.reshape(-1)).partition([width] * len(block)),
            )
        )
    path.parent.mkdir(parents=True, exist_ok=True)
    LazyChunkStream.from_iter(chunks).write_rrd(path, application_id="recorded", recording_id="take_1")


def test_lerobot_layout_with_static_names_matches_pinocchio(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=50, seed=51)
    order = [3, 0, 7, 1, 6, 2, 5, 4]  # the recording's names are in their own order
    write_state_rrd(examples_dir / "data" / "state.rrd", q[:, order], [PANDA_JOINTS[i] for i in order])
    config = panda_config(examples_dir, "rrd_static_names", {"rrd": "data/state.rrd", "entity": "/observation.state"})
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "frame_index", list(range(50)), q, [0, 15, 16, 49])


def test_mcap_importer_recording_maps_per_row_names(examples_dir: Path, run_cli) -> None:
    """Rerun's MCAP importer writes SeriesLines:names with every message, in that message's order: mapped by name."""
    q = random_panda_q(examples_dir, frames=30, seed=52)
    stamps = write_joint_states(examples_dir / "data" / "for_rrd.mcap", shuffled_messages(q, seed=53), chunk_size=1500)
    McapReader(examples_dir / "data" / "for_rrd.mcap").stream().write_rrd(
        examples_dir / "data" / "from_mcap.rrd", application_id="imported", recording_id="bag"
    )
    config = panda_config(examples_dir, "rrd_per_row_names", {"rrd": "data/from_mcap.rrd", "entity": "/joint_states/position"})
    assert run_cli("validate", str(config)).code == 0
    result = run_cli("run", str(config))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "ros2_timestamp", stamps, q, [0, 1, 29])


def test_hdf5_importer_recording_one_vector_per_row(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=20, seed=54)
    write_aloha_episode(examples_dir / "data" / "for_rrd.hdf5", q)
    reader = Hdf5Reader(examples_dir / "data" / "for_rrd.hdf5")
    reader.stream(ignore_datasets=["/action", "/observations/images"], use_structs=False).write_rrd(
        examples_dir / "data" / "from_hdf5.rrd", application_id="imported", recording_id="episode"
    )
    source = {"rrd": "data/from_hdf5.rrd", "entity": "/observations", "component": "qpos", "names": PANDA_JOINTS}
    result = run_cli("run", str(panda_config(examples_dir, "rrd_vectors", source)))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "row_index", list(range(20)), q, [0, 19])


def test_value_count_differing_from_name_count_is_refused(examples_dir: Path, run_cli) -> None:
    extra = [f"extra{i}" for i in range(16)]  # 24 names, 26 values per row
    values = np.concatenate([random_panda_q(examples_dir, frames=5, seed=56), np.zeros((5, 18))], axis=1)
    write_state_rrd(examples_dir / "data" / "wide.rrd", values, [*PANDA_JOINTS, *extra])
    source = {"rrd": "data/wide.rrd", "entity": "observation.state"}
    config = panda_config(examples_dir, "rrd_26_values", source, ignore=extra)
    result = run_cli("run", str(config))
    assert result.code == 1
    assert "source 'state' has rows of 26 values but 24 names" in result.err


@pytest.mark.parametrize(
    ("source", "expected"),
    [
        (
            {"entity": "/observation.stat"},
            "entity '/observation.stat' not in checks.rrd; entities with Scalars:scalars: /observation.state",
        ),
        (
            {"component": "Scalars:scalar"},
            "entity '/observation.state' has no component 'Scalars:scalar'; it has: Scalars:scalars, SeriesLines:names",
        ),
        ({"component": "SeriesLines:names"}, "'/observation.state' SeriesLines:names is static: it has no rows over time"),
        ({"names": list(reversed(PANDA_JOINTS))}, "names differ from the SeriesLines:names recorded on '/observation.state'"),
        ({"rrd": "data/not.rrd"}, "cannot read recording"),
    ],
    ids=["entity", "component", "static", "names-differ", "not-rrd"],
)
def test_validate_refuses_from_the_manifest(examples_dir: Path, run_cli, source: dict[str, Any], expected: str) -> None:
    write_state_rrd(examples_dir / "data" / "checks.rrd", np.zeros((3, 8)), PANDA_JOINTS)
    (examples_dir / "data" / "not.rrd").write_text("not a recording")
    result = run_cli(
        "validate", str(panda_config(examples_dir, "rrd_checks", {"rrd": "data/checks.rrd", "entity": "/observation.state", **source}))
    )
    assert result.code == 1
    assert expected in result.err, result.err
    assert "Traceback" not in result.err


def test_names_are_needed_when_the_recording_has_none(examples_dir: Path, run_cli) -> None:
    q = random_panda_q(examples_dir, frames=8, seed=55)
    write_state_rrd(examples_dir / "data" / "nameless.rrd", q, None)
    source = {"rrd": "data/nameless.rrd", "entity": "/observation.state"}
    refused = run_cli("validate", str(panda_config(examples_dir, "rrd_nameless", source)))
    assert refused.code == 1 and "'/observation.state' carries no SeriesLines:names; give the names with names: [...]" in refused.err
    result = run_cli("run", str(panda_config(examples_dir, "rrd_named_in_config", {**source, "names": PANDA_JOINTS})))
    assert result.code == 0, result.err
    assert_panda_fk(examples_dir, Path(result.out.strip()), "frame_index", list(range(8)), q, [0, 7])
