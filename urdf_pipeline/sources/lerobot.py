"""One episode of a LeRobot dataset (v2.x or v3), read with Rerun's LeRobotReader, video skipped. The dataset is a
local folder, or a remote one (`s3://BUCKET/PREFIX/DATASET`, `hf://datasets/ORG/NAME@REV`: lerobot_remote.py), whose
metadata compile reads and whose episode `run` reads from a local view of the files it needs."""

from __future__ import annotations

import functools
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa

from ..config import Document
from ..confine import file_state, is_remote
from ..errors import UserError, Where, shown
from ..plan import IndexPlan, LeRobotSourcePlan
from .base import EntryField, SourceDescription, resolve_input
from .integrity import check_parquet_pages
from .lerobot_meta import (
    FileStamp,
    checked_plan,
    data_path_template,
    episode_files,
    episode_lengths,
    episode_table,
    feature_names,
    metadata,
    read_info,
    stamped,
    v2_data_file,
    v3_data_files,
)
from .ordering import in_time_order
from .stream import SourceStream, component_field, per_row
from .time_range import NANOSECONDS, index_problem

if TYPE_CHECKING:
    from rerun.chunk import Chunk
    from rerun.experimental import LeRobotReader

PLAN_TYPE = LeRobotSourcePlan
SPEC_FORM = "lerobot:DIR[#FEATURE]"
SUFFIXES: tuple[str, ...] = ()  # a folder: `is_dataset` says it
VECTOR_COMPONENT = "urdf_pipeline:joint_values"
FRAME_INDEX = IndexPlan("frame_index", "sequence", None)  # the timeline of every LeRobot source
# LeRobot's `timestamp` column: float seconds since the episode's start (frame_index / fps as recorded). It becomes a
# *duration* timeline, not a timestamp one: it is no wall-clock instant (a timestamp timeline would show 1970-01-01),
# and durations let episodes be compared side by side from 0 s. Named `time`, so that no one reads it as Rerun's
# timestamp kind; it is kept alongside frame_index on every row (a trail's `window` in s applies to it, in rows to
# frame_index).
TIME = "time"
TIMESTAMP = IndexPlan("timestamp", "duration", "s")  # the column, as time_range.py checks it


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> LeRobotSourcePlan:
    here = ("sources", name)
    if is_remote(spec["lerobot"]):
        from .lerobot_remote import compile_remote  # here: the remote machinery only for a remote dataset

        return compile_remote(name, spec, document)
    if "revision" in spec:
        raise UserError(
            "revision pins the commit of a dataset on the Hugging Face Hub (lerobot: hf://datasets/ORG/NAME); "
            "a local folder has none: remove it",
            document.where(*here, "revision"),
        )
    root = resolve_input(document, config_dir, spec["lerobot"], *here, "lerobot", directory=True)
    plan = checked_plan(name, spec, document, root, str(root))
    if not plan.per_segment:
        check_episode_data(plan, document.where(*here, "episode"))
    return plan


def shown_root(plan: LeRobotSourcePlan) -> str:
    """The dataset as messages name it: its URL when remote (not the local view a run reads), else its folder."""
    return plan.remote.url if plan.remote is not None else str(plan.root)


def _shown_file(plan: LeRobotSourcePlan, file: Path) -> str:
    if plan.remote is None:
        return str(file)
    return f"{plan.remote.url}/{file.relative_to(plan.root).as_posix()}"


def is_dataset(path: Path) -> bool:
    """A folder holding meta/info.json: what `init` takes for a LeRobot dataset when `lerobot:` is left out."""
    try:
        return (path / "meta" / "info.json").is_file()
    except (OSError, ValueError):  # a name too long, no permission: not a dataset, `init` says what it cannot read
        return False


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the feature's (PART, default `observation.state`) names from meta/info.json, as `validate` reads
    them; a feature without names is described by its width (its values are then matched by position)."""
    feature = part or "observation.state"
    if is_remote(path):
        raise UserError(
            f"init describes a local LeRobot dataset, not {shown(path)}: name a local copy of it, then write the URL in the "
            "config's lerobot: yourself"
        )
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
        features = read_info(root).get("features", {})
    except UserError:
        return None
    spec = features.get(feature) if isinstance(features, dict) else None
    if not isinstance(spec, dict) or feature_names(spec) is not None:
        return None
    shape = spec.get("shape") or []
    return int(shape[0]) if len(shape) == 1 and isinstance(shape[0], int) else None


def episodes(plan: LeRobotSourcePlan) -> dict[int, int | None]:
    """Episode index -> its length in frames (None when the metadata does not say), from the dataset's metadata only."""
    if plan.remote is not None:
        from .lerobot_remote import remote_episodes

        return remote_episodes(plan)
    return _local_episodes(plan)


def _local_episodes(plan: LeRobotSourcePlan) -> dict[int, int | None]:
    """The same, read from the folder `plan.root` (the dataset, or the local view of a remote one a run reads)."""
    shown = shown_root(plan)
    return metadata(shown, plan.where, lambda: episode_lengths(plan.root, episode_table(plan.root), plan.where, shown))


def for_episode(plan: LeRobotSourcePlan, episode: int) -> LeRobotSourcePlan:
    """The plan of one segment of a dataset read per episode: its episode and, remote, that episode's data files."""
    if plan.remote is not None:
        from .lerobot_remote import for_episode as remote_episode

        return remote_episode(plan, episode)
    return replace(plan, episode=episode)


def episode_inputs(plan: LeRobotSourcePlan) -> tuple[Path, ...]:
    """The files one episode is read from (for its content hash): meta/info.json and the episode's data file(s), each a
    regular file (a FIFO would block pyarrow and Rerun's reader). compile/segments.py applies the read rule to them."""
    inputs = metadata(shown_root(plan), plan.where, lambda: _episode_inputs(plan))
    for file in inputs[1:]:  # one iteration per data file
        what = f"episode {plan.episode}: LeRobot data file"
        if file_state(file, what, plan.where) != "file":
            raise UserError(f"{what} {_shown_file(plan, file)} does not exist", plan.where)
    return inputs


def _episode_inputs(plan: LeRobotSourcePlan) -> tuple[Path, ...]:
    info = read_info(plan.root, plan.where, shown_root(plan))
    meta = plan.root / "meta" / "info.json"
    template = data_path_template(info, meta, plan.where)
    single = v2_data_file(info, template, plan.episode)
    if single is not None:  # v2: a file per episode, where data_path says (Rerun's reader looks there too)
        return (meta, _data_file(plan, plan.root / single))
    shared = v3_data_files(episode_table(plan.root), template, plan.episode)  # v3: episodes share files
    paths = [plan.root / file for file in (shared or {}).get(plan.episode, ())]
    if paths:
        return (meta, *(_data_file(plan, path) for path in paths))
    return (meta, *sorted((plan.root / "data").glob("**/*.parquet")))  # unknown layout: every data file, to be safe


def _data_file(plan: LeRobotSourcePlan, path: Path) -> Path:
    """A data file the dataset's metadata names for the episode: it must be there (else the run could only fail)."""
    if file_state(path, f"episode {plan.episode}: LeRobot data file", plan.where) == "missing":
        raise UserError(
            f"episode {plan.episode}: its data file {_shown_file(plan, path)} is missing (the dataset's meta/ names it): "
            "restore it, or leave the episode out (output.episodes or `run --episodes`)",
            plan.where,
        )
    return path


def check_episode_data(plan: LeRobotSourcePlan, where: Where | None) -> None:
    """The episode has rows (by the dataset's metadata) and its data files decode (pyarrow, before Rerun's reader)."""
    import pyarrow.parquet as pq

    length = _local_episodes(plan).get(plan.episode)
    files = episode_inputs(plan)[1:]
    if length == 0:
        raise UserError(
            f"episode {plan.episode} of LeRobot dataset {shown_root(plan)} has zero frames (meta says length 0); nothing would move",
            where,
        )
    for file in files:  # one iteration per data file
        try:
            present = set(pq.read_schema(file).names)
        except (pa.ArrowException, OSError) as exc:
            raise UserError(f"episode {plan.episode}: cannot read parquet file {_shown_file(plan, file)}: {exc}", where) from None
        columns = [c for c in (plan.feature, "frame_index", "episode_index") if c in present]
        try:
            # the timeline Rerun's reader makes, frame_index, checked in the same pass: values beyond int64 would wrap
            check_parquet_pages(file, columns, where, FRAME_INDEX if "frame_index" in present else None, where)
        except UserError as exc:
            raise UserError(f"episode {plan.episode}: {exc.message.replace(str(file), _shown_file(plan, file))}", where) from None


@functools.lru_cache(maxsize=4)
def _reader(root: Path, metadata: tuple[FileStamp, ...]) -> tuple[LeRobotReader, frozenset[int]]:
    """Rerun's reader of the dataset and its episodes, kept while `metadata` (info.json, the episode files) is
    unchanged: opening one reads the whole dataset's metadata."""
    from rerun.experimental import LeRobotReader

    reader = LeRobotReader(root)
    return reader, frozenset(reader.episodes())


def episode_times(plan: LeRobotSourcePlan) -> tuple[np.ndarray, np.ndarray] | None:
    """The episode's frame_index values, sorted, and the `time` (int64 nanoseconds) of each, from the `timestamp`
    column of its data files, checked on whole columns (finite, within a timeline: time_range.py); None when
    meta/info.json declares no timestamp. One episode's two columns are held (16 bytes a frame), not its values."""
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    if not plan.timed:
        return None
    frames: list[np.ndarray] = []
    nanos: list[np.ndarray] = []
    for file in episode_inputs(plan)[1:]:  # one iteration per data file
        named = _shown_file(plan, file)
        try:
            present = set(pq.read_schema(file).names)
            missing = [c for c in (TIMESTAMP.column, "frame_index") if c not in present]
            if missing:
                raise UserError(f"{named} has no {' or '.join(missing)} column, which meta/info.json's features declare", plan.where)
            table = pq.read_table(file, columns=[c for c in (TIMESTAMP.column, "frame_index", "episode_index") if c in present])
        except (pa.ArrowException, OSError) as exc:
            raise UserError(f"episode {plan.episode}: cannot read parquet file {named}: {exc}", plan.where) from None
        if "episode_index" in present:  # v3: episodes share a file
            table = table.filter(pc.equal(table.column("episode_index"), plan.episode))
        seconds = table.column(TIMESTAMP.column)
        if not (pa.types.is_floating(seconds.type) or pa.types.is_integer(seconds.type)):
            raise UserError(f"column 'timestamp' of {named} holds {seconds.type}, not seconds", plan.where)
        problem = index_problem(seconds, TIMESTAMP, 0, f"episode {plan.episode}: column 'timestamp' of {named}")
        if problem is not None:
            raise UserError(problem, plan.where)
        frames.append(np.asarray(table.column("frame_index").to_numpy(), dtype=np.int64))
        nanos.append(np.round(np.asarray(seconds.to_numpy(), dtype=np.float64) * NANOSECONDS["s"]).astype(np.int64))
    if not frames:
        return None
    every_frame, every_time = np.concatenate(frames), np.concatenate(nanos)
    order = np.argsort(every_frame, kind="stable")  # a repeated frame_index: its last row's time (as keep_last keeps)
    return every_frame[order], every_time[order]


def _one_vector_per_row(plan: LeRobotSourcePlan, times: tuple[np.ndarray, np.ndarray] | None, chunk: Chunk) -> list[Chunk]:
    """Scalars:scalars holds a row's values as instances; repack them as one list instance per row (per-row FK). With
    `times` (episode_times), each row also gets its `time`, looked up by its frame_index over the whole chunk."""
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    index = batch.schema.get_field_index("Scalars:scalars")
    wrapped = per_row(batch.column(index))
    batch = batch.set_column(index, component_field(VECTOR_COMPONENT, wrapped.type), wrapped)
    if times is not None:
        known, nanos = times
        wanted = np.asarray(batch.column(batch.schema.get_field_index(FRAME_INDEX.column)).to_numpy(), dtype=np.int64)
        at = np.searchsorted(known, wanted, side="right") - 1
        found = (at >= 0) & (known[np.maximum(at, 0)] == wanted)
        if not found.all():
            lost = int(wanted[int(np.argmin(found))])
            raise UserError(f"episode {plan.episode}: frame_index {lost} has no timestamp in its data files", plan.where)
        field = pa.field(TIME, pa.duration("ns"), metadata={b"rerun:kind": b"index", b"rerun:index_name": TIME.encode()})
        batch = batch.add_column(index, field, pa.array(nanos[at], pa.int64()).cast(pa.duration("ns")))  # indices first
    return Chunk.from_record_batch(batch)


def open_stream(plan: LeRobotSourcePlan) -> SourceStream:
    try:  # what Rerun's reader refuses in the metadata that compile's checks let through: the dataset's fault
        reader, known = _reader(plan.root, (stamped(plan.root / "meta" / "info.json"), *episode_files(plan.root)))
    except ValueError as exc:
        raise UserError(
            f"Rerun's LeRobot reader cannot read {shown_root(plan)}: {shown(str(exc).splitlines()[0] if str(exc) else exc)}", plan.where
        ) from None
    if plan.episode not in known:
        raise UserError(f"episode {plan.episode} is not in {shown_root(plan)}", plan.where)
    if plan.per_segment:  # a pinned episode was checked when the config compiled
        check_episode_data(plan, plan.where)
    entity = f"/{plan.feature}"
    stream = (
        reader.stream(plan.episode, video_mode="skip")
        .filter(content=entity, is_static=False, components="Scalars:scalars")
        .flat_map(functools.partial(_one_vector_per_row, plan, episode_times(plan)))
    )
    stream = in_time_order(stream, "frame_index", plan, plan.root)
    return SourceStream(stream, entity, VECTOR_COMPONENT, len(plan.names))


def check_download(plan: LeRobotSourcePlan) -> None:
    """A remote dataset's episode, once `run` has made its local view (`plan.root`): a pinned episode's data checks,
    which compile could not run without downloading data (an episode per segment is checked as its stream opens)."""
    if plan.remote is not None and not plan.per_segment:
        check_episode_data(plan, plan.where)


@contextmanager
def local_dataset(plan: LeRobotSourcePlan) -> Iterator[LeRobotSourcePlan]:
    """`plan` reading a local folder: itself for a local dataset; for a remote one, a view of the files its episode
    needs (fetched as planned), removed when the block ends."""
    if plan.remote is None:
        yield plan
        return
    from .lerobot_remote import episode_view

    with episode_view(plan) as root:
        yield replace(plan, root=root)
