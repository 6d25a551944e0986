"""Generate the inputs and configs of bench_all.py into WORKDIR (run by bench_all.py in its own process, so the
measuring process stays small; see bench_all.py on ru_maxrss). Existing inputs of the same size are reused.

  demo       configs/demo.yaml on the 900-frame Panda episode of `python -m urdf_pipeline.examples`
  panda300k  / panda1m   one Panda parquet episode (configs/demo.yaml's units), config = demo.yaml on that file
  g1_1m      / g1_3m     one parquet episode of the example-robot-data G1, all 29 joints in radians
  dataset    the real G1 + Inspire recording of ../shared, every episode lengthened 40x (ping-pong tiled, so the
             motion stays continuous), frame_index/index/timestamp renumbered, meta/ lengths and stats updated;
             tests/configs/valid/g1_inspire_lerobot.yaml's mapping, one split-layout segment per episode

Frame counts are multiplied by --scale. Prints one JSON object on the last stdout line: per row its config, frame
count and what the hand-written script needs (or the reason the row is skipped).
Usage: python benchmarks/bench_inputs.py WORKDIR --rows demo,panda300k,... [--scale 1.0]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml
from hand_written import G1_JOINTS, G1_URDF

REPO = Path(__file__).resolve().parents[1]
G1_DATA = Path(os.environ.get("BENCH_G1_DATA", REPO.parent / "shared" / "data" / "lerobot_g1_inspire_v21"))  # override: another copy
G1_DATASET_CONFIG = REPO / "tests" / "configs" / "valid" / "g1_inspire_lerobot.yaml"
FRAMES = {"panda300k": 300_000, "panda1m": 1_000_000, "g1_1m": 1_000_000, "g1_3m": 3_000_000}
LENGTHEN = 40
ROW_GROUP = 1 << 20  # pyarrow's default row group length, as a user's `pq.write_table` makes it


def scaled(frames: int, scale: float) -> int:
    return max(1, round(frames * scale))


def single(workdir: Path, config: Path, frames: int, hand: dict, segment: str) -> dict:
    """A single-segment row: our config and output (its output.path is out/{segment}.rrd), the hand-written job's."""
    output = workdir / "out" / f"{segment}.rrd"
    hand = {**hand, "recording_id": segment, "output": str(workdir / "out" / f"hand_{segment}.rrd")}
    return {"config": str(config), "frames": frames, "output": str(output), "hand": hand}


def panda(workdir: Path, frames: int) -> dict:
    from urdf_pipeline.examples import panda_raw_values, write_joint_parquet
    from urdf_pipeline.urdf.model import read_urdf

    parquet = workdir / "data" / f"panda_{frames}.parquet"
    if not parquet.exists():
        _, model = read_urdf(workdir / "robots" / "panda.urdf")
        partial = parquet.with_name(parquet.name + ".partial")
        write_joint_parquet(partial, panda_raw_values(frames, model))
        partial.replace(parquet)
    text = (REPO / "configs" / "demo.yaml").read_text()
    replaced = text.replace("parquet: data/episode_000.parquet", f"parquet: data/{parquet.name}")
    replaced = replaced.replace("segment: episode_000", f"segment: panda_{frames}")
    if replaced.count(parquet.name) != 1 or f"segment: panda_{frames}" not in replaced:
        raise SystemExit("configs/demo.yaml changed: update bench_inputs.panda's substitutions")
    config = workdir / f"panda_{frames}.yaml"
    config.write_text(replaced)
    return single(workdir, config, frames, {"robot": "panda", "parquet": str(parquet), "application_id": "panda_demo"}, f"panda_{frames}")


def g1(workdir: Path, frames: int) -> dict:
    """Sinusoids inside each joint's limits (as urdf_pipeline.examples.smooth_trajectory), written a row group at a
    time so that 3M frames do not need gigabytes here."""
    from urdf_pipeline.urdf.model import read_urdf

    parquet = workdir / "data" / f"g1_{frames}.parquet"
    if not parquet.exists():
        _, model = read_urdf(workdir / G1_URDF)
        lower = np.array([model.joint(j).lower for j in G1_JOINTS])  # type: ignore[union-attr]
        upper = np.array([model.joint(j).upper for j in G1_JOINTS])  # type: ignore[union-attr]
        middle, half = (lower + upper) / 2, (upper - lower) / 2 * 0.8
        rng = np.random.default_rng(9)
        phase, speed = rng.uniform(0, 2 * math.pi, len(G1_JOINTS)), rng.uniform(0.2, 0.6, len(G1_JOINTS))
        schema = pa.schema(
            [("frame_index", pa.int64()), ("timestamp", pa.float64()), ("observation.state", pa.list_(pa.float32(), len(G1_JOINTS)))]
        )
        partial = parquet.with_name(parquet.name + ".partial")
        parquet.parent.mkdir(parents=True, exist_ok=True)
        with pq.ParquetWriter(partial, schema) as writer:
            for start in range(0, frames, ROW_GROUP):
                index = np.arange(start, min(frames, start + ROW_GROUP))
                q = middle + half * np.sin(2 * math.pi * speed * (index[:, None] / 30.0) + phase)
                state = pa.FixedSizeListArray.from_arrays(pa.array(q.astype(np.float32).reshape(-1)), len(G1_JOINTS))
                writer.write_table(pa.table([pa.array(index), pa.array(index / 30.0), state], schema=schema), row_group_size=ROW_GROUP)
        partial.replace(parquet)
    spec = {
        "version": 1,
        "sources": {
            "g1_state": {"parquet": f"data/{parquet.name}", "column": "observation.state", "index": "frame_index", "names": G1_JOINTS}
        },
        "robots": {
            "g1": {
                "urdf": G1_URDF,
                "package_paths": {"example-robot-data": "robots/share/example-robot-data"},
                "joints": {"source": "g1_state", "unit": "rad", "map": {j: j for j in G1_JOINTS}},
            }
        },
        "output": {"path": "out/{segment}.rrd", "application_id": "g1_bench", "segment": f"g1_{frames}"},
    }
    config = workdir / f"g1_{frames}.yaml"
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    return single(workdir, config, frames, {"robot": "g1", "parquet": str(parquet), "application_id": "g1_bench"}, f"g1_{frames}")


def column_stats(column: pa.ChunkedArray) -> dict:
    values = np.asarray(column.combine_chunks().flatten() if pa.types.is_fixed_size_list(column.type) else column, np.float64)
    values = values.reshape(len(column), -1)
    return {
        "min": values.min(axis=0).tolist(),
        "max": values.max(axis=0).tolist(),
        "mean": values.mean(axis=0).tolist(),
        "std": values.std(axis=0).tolist(),
        "count": [len(column)],
    }


def lengthen(source: Path, target: Path, factor: float) -> int:
    """Copy a LeRobot v2.1 dataset with every episode `factor` times as long: rows tiled forward, backward, forward...
    (continuous motion, values within the recorded range), frame_index, index and timestamp renumbered."""
    partial = target.with_name(target.name + ".partial")
    shutil.rmtree(partial, ignore_errors=True)
    (partial / "meta").mkdir(parents=True)
    info = json.loads((source / "meta" / "info.json").read_text())
    episodes = [json.loads(line) for line in (source / "meta" / "episodes.jsonl").read_text().splitlines() if line.strip()]
    old_stats = {}
    if (source / "meta" / "episodes_stats.jsonl").exists():
        lines = (source / "meta" / "episodes_stats.jsonl").read_text().splitlines()
        old_stats = {entry["episode_index"]: entry for entry in map(json.loads, filter(str.strip, lines))}
    fps, first_index, stats_lines = info["fps"], 0, []
    for episode in episodes:
        number = episode["episode_index"]
        relative = info["data_path"].format(episode_chunk=number // info["chunks_size"], episode_index=number)
        table = pq.read_table(source / relative)
        rows, frames = table.num_rows, max(1, round(table.num_rows * factor))
        order = np.concatenate([np.arange(rows)[:: 1 if k % 2 == 0 else -1] for k in range(math.ceil(frames / rows))])[:frames]
        table = table.take(pa.array(order))
        renumbered = {
            "frame_index": pa.array(np.arange(frames), table.schema.field("frame_index").type),
            "index": pa.array(first_index + np.arange(frames), table.schema.field("index").type),
            "timestamp": pa.array((np.arange(frames) / fps).astype(table.schema.field("timestamp").type.to_pandas_dtype())),
        }
        for name, array in renumbered.items():
            table = table.set_column(table.schema.get_field_index(name), table.schema.field(name), array)
        (partial / relative).parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(table, partial / relative)
        first_index += frames
        episode["length"] = frames
        stats = old_stats.get(number, {"episode_index": number, "stats": {}})
        stats["stats"].update({name: column_stats(table.column(name)) for name in table.column_names})
        stats_lines.append(json.dumps(stats))
    info["total_frames"] = first_index
    (partial / "meta" / "episodes.jsonl").write_text("".join(json.dumps(e) + "\n" for e in episodes))
    if old_stats:
        (partial / "meta" / "episodes_stats.jsonl").write_text("".join(line + "\n" for line in stats_lines))
    for name in ("tasks.jsonl",):
        shutil.copyfile(source / "meta" / name, partial / "meta" / name)
    (partial / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    partial.rename(target)
    return first_index


def dataset(workdir: Path, scale: float) -> dict:
    if not (G1_DATA / "meta" / "info.json").is_file():
        return {"skipped": f"{G1_DATA} is absent (the real G1 recording of ../shared)"}
    factor = LENGTHEN * scale
    target = workdir / "data" / f"g1_inspire_x{factor:g}"
    frames = (
        json.loads((target / "meta" / "info.json").read_text())["total_frames"] if target.is_dir() else lengthen(G1_DATA, target, factor)
    )
    spec = yaml.safe_load(G1_DATASET_CONFIG.read_text())
    source = spec["sources"]["g1_state"]
    source["lerobot"] = f"data/{target.name}"
    del source["episode"]  # one segment per episode
    spec["output"] = {
        "layout": "split",
        "path": "out/g1_dataset/{segment}.rrd",
        "model": "out/g1_dataset/model.rrd",
        "segment": "episode_{episode:06d}",
        "application_id": "g1_inspire",
    }
    config = workdir / "g1_dataset.yaml"
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    episodes = len((target / "meta" / "episodes.jsonl").read_text().split("\n")) - 1
    return {"config": str(config), "frames": frames, "episodes": episodes, "outputs": str(workdir / "out" / "g1_dataset")}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("workdir", type=Path)
    parser.add_argument("--rows", required=True)
    parser.add_argument("--scale", type=float, default=1.0)
    args = parser.parse_args()
    workdir = args.workdir.resolve()
    from urdf_pipeline.examples import prepare

    prepare(workdir, frames=900)  # robots/ and the demo's data/episode_000.parquet, as `make demo` makes them
    shutil.copyfile(REPO / "configs" / "demo.yaml", workdir / "demo.yaml")
    made: dict[str, dict] = {}
    for row in args.rows.split(","):
        if row == "demo":
            made[row] = {"config": str(workdir / "demo.yaml"), "frames": 900}
        elif row.startswith("panda"):
            made[row] = panda(workdir, scaled(FRAMES[row], args.scale))
        elif row.startswith("g1_"):
            made[row] = g1(workdir, scaled(FRAMES[row], args.scale))
        elif row == "dataset":
            made[row] = dataset(workdir, args.scale)
        print(f"bench_inputs: {row} ready", file=sys.stderr, flush=True)
    print(json.dumps(made))


if __name__ == "__main__":
    main()
