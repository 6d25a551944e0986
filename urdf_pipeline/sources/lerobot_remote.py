"""A LeRobot dataset where a team keeps it: `lerobot: s3://BUCKET/PREFIX/DATASET`, or `hf://datasets/ORG/NAME@REV`
(or a `revision:` key), in the layouts the local reader takes (docs/remote.md: what each command reads). Compile checks
the metadata a reader needs through a local view of it, as a local dataset's; an S3 dataset's `data/` is listed once,
each episode's data files pinned to their ETags in its segment's plan (the Hub's commit pins every file).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..config import Document, Template
from ..errors import UserError, Where, shown, warn
from ..plan import LeRobotSourcePlan, RemoteDataset, RemoteObject
from ..remote import (
    RemoteUrl,
    check_allowed,
    check_relative,
    download_folder,
    fetched_folder,
    hub_commit,
    hub_files,
    hub_snapshot,
    listing,
    parse_url,
)
from .lerobot_meta import (
    V3_COLUMNS,
    checked_plan,
    data_path_template,
    episode_lengths,
    episode_table,
    metadata,
    read_info,
    v2_data_file,
    v3_data_files,
)
from .lerobot_numbers import jsonl_episode, jsonl_lines

META_FILES = ("meta/info.json", "meta/episodes.jsonl", "meta/tasks.jsonl", "meta/tasks.parquet")  # what a reader opens
META_PATTERNS = (*META_FILES, "meta/episodes/*.parquet")  # for the Hub client (fnmatch: `*` crosses folders)


def _needed(relative: str) -> bool:
    """A metadata file a reader needs: info.json, the episodes' and tasks' tables (v2 JSON lines, v3 parquet)."""
    return relative in META_FILES or (relative.startswith("meta/episodes/") and relative.endswith(".parquet"))


@dataclass(frozen=True)
class _Dataset:
    """What compile learned of a remote dataset, kept in this process for its segments' plans."""

    lengths: dict[int, int | None]  # episode -> frames (None: the metadata does not say)
    info: dict[str, Any]
    template: Template  # info.json's data_path, checked
    shared: dict[int, tuple[str, ...]] | None  # v3: episode -> its data files
    objects: dict[str, RemoteObject] | None  # S3: every object under data/, by its path in the dataset; None: the Hub


_KNOWN: dict[tuple[str, tuple[str, ...]], _Dataset] = {}  # by (dataset URL, its metadata's versions)
KNOWN_LIMIT = 16  # datasets kept (a long-lived process compiling again and again keeps the latest ones)


def _key(dataset: RemoteDataset) -> tuple[str, tuple[str, ...]]:
    return dataset.url, tuple(f"{o.url}@{o.version}" for o in dataset.meta)


def _location(name: str, spec: dict[str, Any], document: Document) -> RemoteUrl:
    """The dataset's URL with the config's revision, allowed by the environment, before any request."""
    where = document.where("sources", name, "lerobot")
    url = parse_url(spec["lerobot"], where, "lerobot dataset")
    url = RemoteUrl(url.scheme, url.bucket, url.repo, url.revision, url.key.rstrip("/"))
    if "revision" in spec:
        at = document.where("sources", name, "revision")
        if url.scheme != "hf":
            raise UserError("revision pins the commit of a dataset on the Hugging Face Hub; an S3 dataset has none: remove it", at)
        if url.revision:
            raise UserError(f"the revision is given twice (@{shown(url.revision)} in the URL and revision:): keep one", at)
        revision = str(spec["revision"])  # the schema's pattern: letters, digits, `._/-`
        if any(part in ("", ".", "..") for part in revision.split("/")):
            raise UserError(f"revision {shown(revision)} has an empty, '.' or '..' segment: name a branch, tag or commit", at)
        url = url.with_revision(revision)
    return check_allowed(url, where, "lerobot dataset")


def compile_remote(name: str, spec: dict[str, Any], document: Document) -> LeRobotSourcePlan:
    """The plan of a remote dataset from its metadata: nothing of `data/` is downloaded."""
    where = document.where("sources", name, "lerobot")
    url = _location(name, spec, document)
    if url.scheme == "hf":
        if not url.revision:
            warn(
                f"{url.url} pins no revision: the dataset can change under this config from one run to the next (each plan "
                f"reads the commit its main branch is at then); pin a commit or tag: {url.url}@REV, or revision: REV",
                where,
            )
        url = url.with_revision(hub_commit(url, where))
        inside = f"{url.key}/" if url.key else ""
        snapshot = hub_snapshot(url, [inside + pattern for pattern in META_PATTERNS], where)
        meta, objects, root = hub_files(url, snapshot, inside + "meta"), None, snapshot / url.key
    else:
        meta, objects, root = list(_listed(url, "meta", where).values()), _listed(url, "data", where), download_folder()
    dataset = RemoteDataset(url.url, tuple(o for o in meta if _needed(o.url[len(url.url) + 1 :])))
    if not any(dataset.relative(o) == "meta/info.json" for o in dataset.meta):
        raise UserError(f"{url.url} is not a LeRobot dataset: {url.url}/meta/info.json is missing", where)
    with fetched_folder({dataset.relative(o): o for o in dataset.meta}, where) as view:
        plan = checked_plan(name, spec, document, view, url.url)
        _remember(dataset, _learn(view, plan.where, url.url, objects))
    plan = replace(plan, root=root, remote=dataset)
    return plan if plan.per_segment else for_episode(plan, plan.episode)


def _listed(url: RemoteUrl, folder: str, where: Where | None) -> dict[str, RemoteObject]:
    """The S3 objects under the dataset's `folder`, by their paths in the dataset."""
    return {o.url[len(url.url) + 1 :]: o for o in listing(url.child_prefix(f"{url.key}/{folder}" if url.key else folder), where)}


def _learn(view: Path, where: Where | None, shown_url: str, objects: dict[str, RemoteObject] | None) -> _Dataset:
    """The dataset's episodes and where their data is, from the local view of its metadata."""

    def read() -> _Dataset:
        info = read_info(view, where, shown_url)
        template = data_path_template(info, f"{shown_url}/meta/info.json", where)
        table = episode_table(view)
        shared = None if "episode_index" in template.fields else v3_data_files(table, template)
        return _Dataset(episode_lengths(view, table, where, shown_url), info, template, shared, objects)

    return metadata(shown_url, where, read)


def _remember(dataset: RemoteDataset, known: _Dataset) -> _Dataset:
    while len(_KNOWN) >= KNOWN_LIMIT:
        del _KNOWN[next(iter(_KNOWN))]
    _KNOWN[_key(dataset)] = known
    return known


def _dataset(plan: LeRobotSourcePlan) -> _Dataset:
    """What compile learned of the plan's dataset; learned again when this process did not compile it."""
    assert plan.remote is not None
    known = _KNOWN.get(_key(plan.remote))
    if known is None:
        url = parse_url(plan.remote.url, plan.where)
        objects = _listed(url, "data", plan.where) if url.scheme == "s3" else None
        with fetched_folder({plan.remote.relative(o): o for o in plan.remote.meta}, plan.where) as view:
            known = _remember(plan.remote, _learn(view, plan.where, plan.remote.url, objects))
    return known


def remote_episodes(plan: LeRobotSourcePlan) -> dict[int, int | None]:
    """Episode index -> its length in frames, from the dataset's metadata as compile read it."""
    return _dataset(plan).lengths


def for_episode(plan: LeRobotSourcePlan, episode: int) -> LeRobotSourcePlan:
    """The plan of `episode`, holding its data file(s), pinned: S3 objects as the listing found them (a missing one
    is refused here), Hub files at the planned commit."""
    assert plan.remote is not None
    known = _dataset(plan)
    single = v2_data_file(known.info, known.template, episode)
    files = (single,) if single is not None else (known.shared or {}).get(episode, ())
    if not files:
        raise UserError(
            f"episode {episode}: the metadata of {shown(plan.remote.url)} does not say which data file holds it (no "
            "{episode_index} in data_path, no data/chunk_index and data/file_index in meta/episodes)",
            plan.where,
        )
    for file in files:  # one iteration per data file of the episode
        check_relative(file, plan.where, f"episode {episode}: data file")
    if known.objects is None:  # the Hub: the dataset's commit pins every file
        version = plan.remote.meta[0].version
        data = tuple(RemoteObject(f"{plan.remote.url}/{file}", version, 0) for file in files)
    else:
        missing = [file for file in files if file not in known.objects]
        if missing:
            raise UserError(f"episode {episode}: LeRobot data file {shown(plan.remote.url + '/' + missing[0])} does not exist", plan.where)
        data = tuple(known.objects[file] for file in files)
    return replace(plan, episode=episode, remote=replace(plan.remote, data=data))


@contextmanager
def episode_view(plan: LeRobotSourcePlan) -> Iterator[Path]:
    """The dataset's folder as Rerun's reader takes it, holding only what the plan's episode needs, each file fetched
    as planned (a changed S3 object is refused by name); removed when the block ends."""
    assert plan.remote is not None
    name = parse_url(plan.remote.url, plan.where).name
    files = {f"{name}/{plan.remote.relative(o)}": o for o in (*plan.remote.meta, *plan.remote.data)}
    with fetched_folder(files, plan.where) as folder:
        _present_episodes_only(folder / name, plan)
        yield folder / name


def _present_episodes_only(root: Path, plan: LeRobotSourcePlan) -> None:
    """The view's episode tables cut to what it holds, written in place of their links (the cache's copies stay as they
    were). v3: the episodes sharing the plan's episode's data files (Rerun's reader would try every data file the tables
    name); v2: the episode's own line of episodes.jsonl (else every segment parsed the whole table: a quadratic run)."""
    assert plan.remote is not None
    jsonl = root / "meta" / "episodes.jsonl"
    if jsonl.is_symlink():
        real = os.path.realpath(jsonl)
        status = os.stat(real)
        lines = metadata(plan.remote.url, plan.where, lambda: _jsonl_lines(real, status.st_size, status.st_mtime_ns))
        jsonl.unlink()  # the link into the cache, never written through
        jsonl.write_text(lines.get(plan.episode, "") + "\n", encoding="utf-8")
    tables = [root / plan.remote.relative(o) for o in plan.remote.meta if plan.remote.relative(o).startswith("meta/episodes/")]
    tables = [path for path in tables if path.suffix == ".parquet"]

    def cut() -> None:
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        read = {path: pq.read_table(path) for path in tables}
        if not all(set(V3_COLUMNS) <= set(table.column_names) for table in read.values()):
            return
        own: set[tuple[int, int]] = set()  # the (chunk, file) of the episode's data files
        for table in read.values():  # one iteration per episode table
            mine = table.filter(pc.equal(table["episode_index"], plan.episode))
            own |= set(zip(mine[V3_COLUMNS[0]].to_pylist(), mine[V3_COLUMNS[1]].to_pylist(), strict=True))
        for path, table in read.items():  # one iteration per episode table (a v3 dataset has one per 1000 episodes or so)
            keep = pc.equal(table["episode_index"], -1)
            for chunk, file in own:  # the episode's data files: one, or two when it straddles a file boundary
                keep = pc.or_(keep, pc.and_(pc.equal(table[V3_COLUMNS[0]], chunk), pc.equal(table[V3_COLUMNS[1]], file)))
            path.unlink()  # the link into the cache, never written through
            pq.write_table(table.filter(keep), path)

    if tables:
        metadata(plan.remote.url, plan.where, cut)


@functools.lru_cache(maxsize=4)
def _jsonl_lines(real: str, size: int, mtime_ns: int) -> dict[int, str]:
    """A v2 episodes.jsonl of the download cache, as episode index -> its line (kept while the file is unchanged),
    read and checked as a local one is."""
    found: dict[int, str] = {}
    for number, line in jsonl_lines(Path(real)):  # one iteration per episode of the dataset, once
        found[jsonl_episode(number, line)[0]] = line
    return found
