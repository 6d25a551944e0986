"""One episode of a LeRobot dataset (v2.x or v3), read with Rerun's LeRobotReader, video skipped."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..config import Document
from ..errors import UserError, Where
from ..plan import LeRobotSourcePlan
from .base import EntryField, SourceDescription, resolve_input
from .integrity import check_parquet_pages
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream

if TYPE_CHECKING:
    from rerun.chunk import Chunk

PLAN_TYPE = LeRobotSourcePlan
SPEC_FORM = "lerobot:DIR[#FEATURE]"
SUFFIXES: tuple[str, ...] = ()  # a folder: `is_dataset` says it
VECTOR_COMPONENT = "urdf_pipeline:joint_values"


def feature_names(feature: dict[str, Any]) -> list[str] | None:
    """LeRobot writes names as a list, a list holding one list, or {"motors": [...]}; accept all three."""
    names = feature.get("names")
    if isinstance(names, dict) and len(names) == 1:
        names = next(iter(names.values()))
    if isinstance(names, list) and len(names) == 1 and isinstance(names[0], list):
        names = names[0]
    if isinstance(names, list) and all(isinstance(n, str) for n in names):
        return names
    return None


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> LeRobotSourcePlan:
    here = ("sources", name)
    root = resolve_input(document, config_dir, spec["lerobot"], *here, "lerobot", directory=True)
    info_path = root / "meta" / "info.json"
    try:
        info = json.loads(info_path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{root} is not a LeRobot dataset: {info_path} is missing", document.where(*here, "lerobot")) from None
    except (OSError, json.JSONDecodeError) as exc:
        raise UserError(f"cannot read {info_path}: {exc}", document.where(*here, "lerobot")) from None
    version = str(info.get("codebase_version", ""))
    if not (version.startswith("v2") or version.startswith("v3")):
        raise UserError(f"LeRobot codebase_version '{version}' is not supported (v2.x or v3 only)", document.where(*here, "lerobot"))
    feature_key = spec.get("feature", "observation.state")
    features = info.get("features", {})
    if feature_key not in features:
        numeric = [k for k, f in features.items() if f.get("dtype") in ("float32", "float64")]
        raise UserError(
            f"feature '{feature_key}' not in {info_path}; numeric features: {', '.join(numeric)}", document.where(*here, "feature")
        )
    feature = features[feature_key]
    shape = feature.get("shape") or [None]
    width = shape[0] if len(shape) == 1 else None
    names = tuple(spec["names"]) if "names" in spec else tuple(feature_names(feature) or ())
    if not names:
        raise UserError(f"feature '{feature_key}' has no names in {info_path}; give them with names: [...]", document.where(*here))
    if width is not None and width != len(names):
        raise UserError(
            f"feature '{feature_key}' holds {width} values per row but {len(names)} names are given",
            document.where(*here, "names" if "names" in spec else "feature"),
        )
    if "episode" not in spec:  # one segment per episode; segments.py picks them and fills in `episode`
        return with_duplicates(LeRobotSourcePlan(name, root, feature_key, -1, names, document.where(*here), per_segment=True), spec)
    episode = int(spec["episode"])
    total = info.get("total_episodes")
    if isinstance(total, int) and episode >= total:
        raise UserError(
            f"episode {episode} does not exist: the dataset has {total} episodes (0..{total - 1})", document.where(*here, "episode")
        )
    plan = with_duplicates(LeRobotSourcePlan(name, root, feature_key, episode, names, document.where(*here)), spec)
    check_episode_data(plan, document.where(*here, "episode"))
    return plan


def _info(root: Path) -> dict[str, Any]:
    info: dict[str, Any] = json.loads((root / "meta" / "info.json").read_text(encoding="utf-8"))
    return info


def is_dataset(path: Path) -> bool:
    """A folder holding meta/info.json: what `init` takes for a LeRobot dataset when `lerobot:` is left out."""
    return (path / "meta" / "info.json").is_file()


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the feature's (PART, default `observation.state`) names from meta/info.json, as `validate` reads
    them; a feature without names is described by its width (its values are then matched by position)."""
    feature = part or "observation.state"
    root = Path(path).resolve()
    fields = (EntryField("feature", feature),)
    segment = "episode_{episode:06d}"
    notes = ("no episode: one segment per episode of the dataset (episode: N pins one)",)
    try:
        plan = compile_source(name, {"lerobot": str(root), "feature": feature}, document, root)
    except UserError:
        width = _unnamed_width(root, feature)
        if width is None:
            raise
        unnamed = "the feature has no names in meta/info.json"
        return SourceDescription("lerobot", fields, None, width, segment, unnamed=unnamed, notes=notes)
    return SourceDescription("lerobot", fields, plan.names, None, segment, notes=notes)


def _unnamed_width(root: Path, feature: str) -> int | None:
    """The width of a 1-D feature without names; None when the feature is missing, named or not 1-D."""
    try:
        features = _info(root).get("features", {})
    except (OSError, json.JSONDecodeError):
        return None
    spec = features.get(feature)
    if not isinstance(spec, dict) or feature_names(spec) is not None:
        return None
    shape = spec.get("shape") or []
    return int(shape[0]) if len(shape) == 1 and isinstance(shape[0], int) else None


def _episode_table(root: Path) -> pa.Table | None:
    """The dataset's per-episode metadata: v2's meta/episodes.jsonl or v3's meta/episodes/**/*.parquet."""
    import pyarrow.parquet as pq

    jsonl = root / "meta" / "episodes.jsonl"
    if jsonl.is_file():
        rows = [json.loads(line) for line in jsonl.read_text(encoding="utf-8").splitlines() if line.strip()]
        return pa.table({"episode_index": [int(r["episode_index"]) for r in rows], "length": [r.get("length") for r in rows]})
    files = sorted((root / "meta" / "episodes").glob("**/*.parquet"))
    if not files:
        return None
    wanted = ["episode_index", "length", "data/chunk_index", "data/file_index"]
    tables = [pq.read_table(f, columns=[c for c in wanted if c in pq.read_schema(f).names]) for f in files]
    return pa.concat_tables(tables, promote_options="default")


def episodes(plan: LeRobotSourcePlan) -> dict[int, int | None]:
    """Episode index -> its length in frames (None when the metadata does not say), from the dataset's metadata only."""
    table = _episode_table(plan.root)
    if table is None:
        total = int(_info(plan.root).get("total_episodes", 0))
        return dict.fromkeys(range(total))
    lengths = table.column("length").to_pylist() if "length" in table.column_names else [None] * table.num_rows
    return dict(zip(table.column("episode_index").to_pylist(), lengths, strict=True))


def episode_inputs(plan: LeRobotSourcePlan) -> tuple[Path, ...]:
    """The files one episode is read from (for its content hash): meta/info.json and the episode's data file(s)."""
    info = _info(plan.root)
    template = str(info.get("data_path", ""))
    meta = plan.root / "meta" / "info.json"
    if "{episode_index" in template:  # v2: one file per episode
        chunk = plan.episode // int(info.get("chunks_size", 1000))
        path = plan.root / template.format(episode_chunk=chunk, episode_index=plan.episode)
        if path.is_file():
            return (meta, path)
    table = _episode_table(plan.root)
    if table is not None and {"data/chunk_index", "data/file_index"} <= set(table.column_names):  # v3: episodes share files
        import pyarrow.compute as pc  # here: 50 ms of every command otherwise, and only v3 datasets need it

        rows = table.filter(pc.equal(table.column("episode_index"), plan.episode)).to_pylist()
        paths = {plan.root / template.format(chunk_index=r["data/chunk_index"], file_index=r["data/file_index"]) for r in rows}
        if paths and all(p.is_file() for p in paths):
            return (meta, *sorted(paths))
    return (meta, *sorted((plan.root / "data").glob("**/*.parquet")))  # unknown layout: every data file, to be safe


def check_episode_data(plan: LeRobotSourcePlan, where: Where | None) -> None:
    """The episode has rows (by the dataset's metadata) and its data files decode (pyarrow, before Rerun's reader)."""
    import pyarrow.parquet as pq

    try:
        length = episodes(plan).get(plan.episode)
        files = episode_inputs(plan)[1:]
    except (OSError, ValueError, KeyError, TypeError, pa.ArrowException) as exc:
        raise UserError(f"cannot read the episode metadata of LeRobot dataset {plan.root}: {exc}", where) from None
    if length == 0:
        raise UserError(
            f"episode {plan.episode} of LeRobot dataset {plan.root} has zero frames (meta says length 0); nothing would move", where
        )
    for file in files:  # one iteration per data file
        try:
            present = set(pq.read_schema(file).names)
        except (pa.ArrowException, OSError) as exc:
            raise UserError(f"episode {plan.episode}: cannot read parquet file {file}: {exc}", where) from None
        columns = [c for c in (plan.feature, "frame_index", "episode_index") if c in present]
        try:
            check_parquet_pages(file, columns, where)
        except UserError as exc:
            raise UserError(f"episode {plan.episode}: {exc.message}", where) from None


def _one_vector_per_row(chunk: Chunk) -> list[Chunk]:
    """Scalars:scalars holds a row's values as instances; repack them as one list instance per row.

    Rerun's lenses hand a selector the row values flattened, so per-row FK needs one vector instance per row.
    """
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    index = batch.schema.get_field_index("Scalars:scalars")
    values = batch.column(index)
    wrapped = pa.ListArray.from_arrays(pa.array(np.arange(len(values) + 1, dtype=np.int32)), values)
    field = pa.field(VECTOR_COMPONENT, wrapped.type, metadata={b"rerun:kind": b"data", b"rerun:component": VECTOR_COMPONENT.encode()})
    return Chunk.from_record_batch(batch.set_column(index, field, wrapped))


def open_stream(plan: LeRobotSourcePlan) -> SourceStream:
    from rerun.experimental import LeRobotReader

    reader = LeRobotReader(plan.root)
    if plan.episode not in reader.episodes():
        raise UserError(f"episode {plan.episode} is not in {plan.root}", plan.where)
    if plan.per_segment:  # a pinned episode was checked when the config compiled
        check_episode_data(plan, plan.where)
    entity = f"/{plan.feature}"
    stream = (
        reader.stream(plan.episode, video_mode="skip")
        .filter(content=entity, is_static=False, components="Scalars:scalars")
        .flat_map(_one_vector_per_row)
    )
    stream = in_time_order(stream, "frame_index", plan, plan.root)
    return SourceStream(stream, entity, VECTOR_COMPONENT, len(plan.names))
