"""`describe`: each source kind describes a source for `init` from its metadata; the kinds are listed once."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from urdf_pipeline.config.document import Document
from urdf_pipeline.errors import UserError
from urdf_pipeline.examples import SO101_NAMES, UR5_JOINTS, write_joint_parquet
from urdf_pipeline.sources import KINDS, EntryField, SourceDescription, kind_for_path

from ..source_helpers import PANDA_JOINTS
from .test_sources_rrd import write_state_rrd


def describe(kind: str, path: Path | str, part: str | None, tmp_path: Path) -> SourceDescription:
    return KINDS[kind].describe("arm_state", str(path), part, Document(tmp_path / "config.yaml", {}, {}))


def test_every_kind_follows_the_protocol_and_says_its_form(tmp_path: Path) -> None:
    assert list(KINDS) == ["lerobot", "parquet", "mcap", "hdf5", "rrd", "csv"]  # the order init lists them in
    for kind, module in KINDS.items():
        assert module.SPEC_FORM.startswith(f"{kind}:") and callable(module.describe)
    assert [kind_for_path(p) for p in ("a.parquet", "b.MCAP", "c.h5", "d.hdf5", "e.rrd", "f.csv")] == [
        "parquet",
        "mcap",
        "hdf5",
        "hdf5",
        "rrd",
        "csv",
    ]
    (tmp_path / "ds" / "meta").mkdir(parents=True)
    assert kind_for_path(str(tmp_path / "ds")) is None
    (tmp_path / "ds" / "meta" / "info.json").write_text("{}")
    assert kind_for_path(str(tmp_path / "ds")) == "lerobot"


def test_named_kinds_read_their_names(examples_dir: Path, tmp_path: Path) -> None:
    lerobot = describe("lerobot", examples_dir / "data" / "so101_lerobot", None, tmp_path)
    assert lerobot.names == tuple(SO101_NAMES) and lerobot.fields == (EntryField("feature", "observation.state"),)
    assert lerobot.segment == "episode_{episode:06d}" and not lerobot.pattern and not lerobot.urdf_order

    mcap = describe("mcap", examples_dir / "data" / "ur5_joint_states.mcap", None, tmp_path)
    assert mcap.fields == (EntryField("topic", "/joint_states"),) and mcap.urdf_order  # names in any order per message
    assert sorted(mcap.names or ()) == sorted(UR5_JOINTS) and mcap.segment == "ur5_joint_states"

    write_state_rrd(tmp_path / "state.rrd", np.zeros((4, 8)), PANDA_JOINTS)
    rrd = describe("rrd", tmp_path / "state.rrd", "observation.state", tmp_path)
    assert rrd.names == tuple(PANDA_JOINTS) and rrd.fields == (EntryField("entity", "/observation.state"),)


def test_unnamed_kinds_give_their_width(examples_dir: Path, tmp_path: Path) -> None:
    parquet = describe("parquet", examples_dir / "data" / "episode_000.parquet", None, tmp_path)
    assert parquet.names is None and parquet.width == 8 and parquet.unnamed == "parquet carries no names"
    assert [(f.key, f.value) for f in parquet.fields] == [("column", "observation.state"), ("index", "frame_index")]
    assert parquet.fields[1].comment.startswith("review:")  # a guess, said why

    hdf5 = describe("hdf5", f"{examples_dir / 'data' / 'aloha'}/episode_*.hdf5", "observations/qpos", tmp_path)
    assert hdf5.names is None and hdf5.width == 14 and hdf5.pattern and hdf5.segment == "{stem}"
    assert hdf5.fields == (EntryField("dataset", "/observations/qpos"),)

    root = tmp_path / "ds"
    (root / "meta").mkdir(parents=True)
    features = {"observation.state": {"dtype": "float32", "shape": [6], "names": None}}
    (root / "meta" / "info.json").write_text(json.dumps({"codebase_version": "v2.1", "features": features}))
    lerobot = describe("lerobot", root, None, tmp_path)
    assert lerobot.names is None and lerobot.width == 6 and "no names" in lerobot.unnamed


def test_refusals_name_the_part_to_give(examples_dir: Path, tmp_path: Path) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    pq.write_table(pa.table({"a": pa.array([[1.0]]), "b": pa.array([[2.0]])}), tmp_path / "two.parquet")
    write_joint_parquet(tmp_path / "one.parquet", np.zeros((2, 3)))
    refusals = [
        ("parquet", tmp_path / "two.parquet", None, "name the column with parquet:FILE#COLUMN; list columns of two.parquet: a, b"),
        ("parquet", tmp_path / "one.parquet", "timestamp", "column 'timestamp' is double, not a list of numbers"),
        ("parquet", tmp_path / "none_*.parquet", None, f"'{tmp_path}/none_*.parquet' matches no file"),
        ("hdf5", examples_dir / "data" / "aloha" / "episode_0.hdf5", None, "; name it with hdf5:FILE#/DATASET"),
        ("rrd", tmp_path / "one.parquet", None, "name the entity holding the values with rrd:FILE#ENTITY"),
    ]
    for kind, path, part, message in refusals:
        with pytest.raises(UserError) as caught:
            describe(kind, path, part, tmp_path)
        assert message in caught.value.message, (kind, caught.value.message)
