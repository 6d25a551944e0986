"""LeRobot datasets in both layouts the reader takes (v2.1: a data file per episode; v3: episodes sharing data files),
where teams keep them: a local Hugging Face Hub cache in the client's own layout (refs/, snapshots/COMMIT/, blobs/)
that the real `huggingface_hub` client reads offline, and a config driving the Panda from one."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import yaml

from urdf_pipeline.examples import write_lerobot_dataset

from .source_helpers import PANDA_JOINTS, panda_config


def write_v3_dataset(root: Path, episodes: list[np.ndarray], names: list[str], per_file: int = 2, fps: int = 30) -> None:
    """A LeRobot v3.0 dataset without videos: `per_file` episodes to a data file, meta/episodes naming each one's."""
    shutil.rmtree(root, ignore_errors=True)
    (root / "meta" / "episodes" / "chunk-000").mkdir(parents=True)
    (root / "data" / "chunk-000").mkdir(parents=True)
    rows: list[dict[str, Any]] = []
    start = 0
    width = episodes[0].shape[1]
    for file_index, first in enumerate(range(0, len(episodes), per_file)):
        tables = []
        for episode in range(first, min(first + per_file, len(episodes))):
            frames = len(episodes[episode])
            values = pa.array(episodes[episode].astype(np.float32).reshape(-1))
            tables.append(
                pa.table(
                    {
                        "observation.state": pa.FixedSizeListArray.from_arrays(values, width),
                        "timestamp": pa.array(np.arange(frames) / fps, pa.float32()),
                        "frame_index": pa.array(np.arange(frames), pa.int64()),
                        "episode_index": pa.array(np.full(frames, episode), pa.int64()),
                        "index": pa.array(start + np.arange(frames), pa.int64()),
                        "task_index": pa.array(np.zeros(frames), pa.int64()),
                    }
                )
            )
            rows.append(
                {
                    "episode_index": episode,
                    "tasks": ["wave"],
                    "length": frames,
                    "data/chunk_index": 0,
                    "data/file_index": file_index,
                    "dataset_from_index": start,
                    "dataset_to_index": start + frames,
                }
            )
            start += frames
        pq.write_table(pa.concat_tables(tables), root / "data" / "chunk-000" / f"file-{file_index:03d}.parquet")
    pq.write_table(pa.Table.from_pylist(rows), root / "meta" / "episodes" / "chunk-000" / "file-000.parquet")
    pq.write_table(pa.table({"task_index": [0], "task": ["wave"]}), root / "meta" / "tasks.parquet")
    scalar = {"dtype": "int64", "shape": [1], "names": None}
    info = {
        "codebase_version": "v3.0",
        "robot_type": "panda",
        "total_episodes": len(episodes),
        "total_frames": start,
        "total_tasks": 1,
        "chunks_size": 1000,
        "fps": fps,
        "splits": {"train": f"0:{len(episodes)}"},
        "data_path": "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet",
        "video_path": None,
        "features": {
            "observation.state": {"dtype": "float32", "shape": [width], "names": names},
            "timestamp": {"dtype": "float32", "shape": [1], "names": None},
            **{name: scalar for name in ("frame_index", "episode_index", "index", "task_index")},
        },
    }
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=2))
    (root / "meta" / "stats.json").write_text("{}")  # statistics: never needed, never downloaded


def write_dataset(root: Path, episodes: list[np.ndarray], layout: str) -> None:
    """A Panda dataset (values in PANDA_JOINTS order, radians and metres) in the v2.1 or v3 layout."""
    if layout == "v3":
        write_v3_dataset(root, episodes, PANDA_JOINTS)
    else:
        shutil.rmtree(root, ignore_errors=True)
        write_lerobot_dataset(root, episodes, PANDA_JOINTS)
        (root / "meta" / "episodes_stats.jsonl").write_text("{}\n")  # statistics: never needed, never downloaded


def dataset_files(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())


def hub_commit(cache: Path, repo: str, dataset: Path, sha: str, refs: tuple[str, ...] = ("main",), only: str = "") -> None:
    """The dataset's files (those under `only`, when given) as commit `sha` of `repo` in a Hub cache, in the client's
    own layout: blobs by content, snapshots/SHA/PATH a relative link to its blob, refs/NAME holding the sha."""
    folder = cache / f"datasets--{repo.replace('/', '--')}"
    for relative in dataset_files(dataset):
        if only and not relative.startswith(only):
            continue
        data = (dataset / relative).read_bytes()
        blob = folder / "blobs" / hashlib.sha256(data).hexdigest()
        blob.parent.mkdir(parents=True, exist_ok=True)
        blob.write_bytes(data)
        link = folder / "snapshots" / sha / relative
        link.parent.mkdir(parents=True, exist_ok=True)
        link.unlink(missing_ok=True)
        link.symlink_to(os.path.relpath(blob, link.parent))
    for ref in refs:
        (folder / "refs" / ref).parent.mkdir(parents=True, exist_ok=True)
        (folder / "refs" / ref).write_text(sha)


def lerobot_panda_config(examples_dir: Path, stem: str, source: dict[str, Any]) -> Path:
    """A config `STEM.yaml` in the examples folder driving the Panda from a LeRobot source, one segment per episode,
    its recordings in out/STEM/."""
    made = panda_config(examples_dir, stem, source)
    data = yaml.safe_load(made.read_text())
    data["output"].update(path=f"out/{stem}/{{segment}}.rrd", segment="episode_{episode:06d}")
    made.write_text(yaml.safe_dump(data, sort_keys=False))
    return made


def cached_names(folder: Path) -> list[str]:
    """The files a cache folder holds (their names), its own lock and ledger files left out."""
    return sorted(p.name for p in folder.rglob("*") if p.is_file() and not p.name.startswith(".")) if folder.exists() else []


def _edited_info(root: Path, **changes: Any) -> None:
    """meta/info.json with `changes` (a value of None removes its key); NaN and Infinity written as Python's json
    writes them, which LeRobot's own reader (json.load) accepts."""
    path = root / "meta" / "info.json"
    info = json.loads(path.read_text(encoding="utf-8"))
    info.update(changes)
    path.write_text(json.dumps({k: v for k, v in info.items() if v is not None}), encoding="utf-8")


def _edited_jsonl(root: Path, row: int, **changes: Any) -> None:
    path = root / "meta" / "episodes.jsonl"
    rows = [json.loads(line) for line in path.read_text(encoding="utf-8").splitlines()]
    rows[row].update(changes)
    path.write_text("\n".join(json.dumps(r) for r in rows) + "\n", encoding="utf-8")


def _edited_episodes(root: Path, row: int, **changes: Any) -> None:
    """v3: meta/episodes' file with row `row`'s columns changed (a new column is added, null in the other rows)."""
    path = root / "meta" / "episodes" / "chunk-000" / "file-000.parquet"
    rows = [{**dict.fromkeys(changes), **r} for r in pq.read_table(path).to_pylist()]
    rows[row].update(changes)
    pq.write_table(pa.Table.from_pylist(rows), path)


def _v3_copy(source: Path, root: Path) -> None:
    """`source` (a v2.1 dataset without videos) again in the v3 layout, two episodes a data file."""
    files = sorted((source / "data").glob("*/*.parquet"))
    episodes = [np.asarray(pq.read_table(f).column("observation.state").to_pylist(), dtype=np.float64) for f in files]
    names = json.loads((source / "meta" / "info.json").read_text())["features"]["observation.state"]["names"]
    write_v3_dataset(root, episodes, names)


# data/hostile_lerobot/NAME: a copy of the examples' so101 dataset (v2.1), or of it in the v3 layout, with one hostile
# edit to its metadata each; the invalid cases metadata_* and template_*_path_* read them
HOSTILE_LEROBOT: dict[str, tuple[str, Any]] = {
    "chunks_size_zero": ("v2", lambda d: _edited_info(d, chunks_size=0)),
    "total_episodes_huge": ("v2", lambda d: (_edited_info(d, total_episodes=10**30), (d / "meta" / "episodes.jsonl").unlink())),
    "fps_nan": ("v2", lambda d: _edited_info(d, fps=float("nan"))),
    "episode_index_huge": ("v2", lambda d: _edited_jsonl(d, 1, episode_index=1e30)),
    "row_range_reversed": ("v3", lambda d: _edited_episodes(d, 2, dataset_to_index=0)),
    "video_time_infinite": ("v3", lambda d: _edited_episodes(d, 1, **{"videos/cam/from_timestamp": float("inf")})),
    "data_path_width": (
        "v2",
        lambda d: _edited_info(d, data_path="data/chunk-{episode_chunk:03d}/episode_{episode_index:999999999d}.parquet"),
    ),
    "video_path_attribute": ("v2", lambda d: _edited_info(d, video_path="videos/{video_key.__class__.__mro__}/{episode_index:06d}.mp4")),
}


def write_hostile_lerobot(data: Path, source: Path) -> None:
    """Every dataset of HOSTILE_LEROBOT under data/hostile_lerobot/, made from `source` (a v2.1 dataset)."""
    for name, (layout, edit) in HOSTILE_LEROBOT.items():
        root = data / "hostile_lerobot" / name
        shutil.rmtree(root, ignore_errors=True)
        if layout == "v3":
            _v3_copy(source, root)
        else:
            shutil.copytree(source, root)
        edit(root)
