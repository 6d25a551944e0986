"""A glob's files (or S3 objects) become segments by stem: two matches sharing one are refused by name, the others
still checked, so every problem of the config is said at once."""

from __future__ import annotations

from pathlib import Path

from urdf_pipeline.examples import write_joint_parquet

from ..source_helpers import PANDA_JOINTS, panda_config, random_panda_q


def test_two_files_sharing_a_stem_are_refused_naming_both(examples_dir: Path, tmp_path: Path, run_cli, allow_examples: Path) -> None:
    folder = examples_dir / "data" / "stems"
    q = random_panda_q(examples_dir, 10, seed=3)
    for name in ("run_a.parquet", "run_a.v2.parquet", "run_b.parquet"):
        write_joint_parquet(folder / name, q)
    source = {"parquet": "data/stems/*.parquet", "column": "observation.state", "index": "frame_index", "names": PANDA_JOINTS}
    config = panda_config(examples_dir, "{stem}", source)
    result = run_cli("validate", str(config))
    assert result.code == 1
    assert "two files matched by 'data/stems/*.parquet' share the stem 'run_a'" in result.err, result.err
    assert "run_a.parquet and " in result.err and "run_a.v2.parquet); rename one" in result.err
