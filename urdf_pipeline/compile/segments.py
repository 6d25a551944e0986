"""Which segments a run writes: one per LeRobot episode or per globbed input file, each with its own sources and output.

A config names its segments with a template (`output.segment: episode_{episode:06d}`); two segments with the same
id would overwrite each other's recording, so that is refused here, before anything runs.
"""

from __future__ import annotations

import glob
import itertools
import os
import re
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..config import Placeholder, checked_template
from ..confine import Unresolvable, file_state, resolved
from ..errors import UserError, Where, listing, quoted, shown
from ..plan import DatasetPlan, LeRobotSourcePlan, Segment, SourcePlan
from ..remote import is_remote, remote_glob
from ..sources import GLOB, KINDS, kind_of, refuse_control_characters
from .context import CompileContext
from .output_paths import dataset_plan, output_paths

REMOTE_METADATA_THREADS = 16  # objects of an s3:// glob whose metadata is read at once
EPISODES_RANGE = re.compile(r"^(\d*):(\d*)$")


@dataclass(frozen=True)
class CompiledSources:
    """The config's sources: one plan each (the first file of a glob), and every file of each globbed source by stem."""

    plans: dict[str, SourcePlan]
    files: dict[str, dict[str, SourcePlan]]  # globbed source name -> stem -> plan of that file


def compile_sources(ctx: CompileContext) -> CompiledSources:
    plans: dict[str, SourcePlan] = {}
    files: dict[str, dict[str, SourcePlan]] = {}
    for name, spec in ctx.data["sources"].items():
        kind = kind_of(spec)
        try:
            if kind != "lerobot" and GLOB.search(spec[kind]):
                files[name] = _compile_glob(ctx, name, kind, spec)
                if files[name]:
                    plans[name] = next(iter(files[name].values()))
            else:
                plans[name] = KINDS[kind].compile_source(name, spec, ctx.document, ctx.config_dir)
        except UserError as exc:
            ctx.problems.extend(exc)
    return CompiledSources(plans, files)


def _compile_glob(ctx: CompileContext, name: str, kind: str, spec: dict[str, Any]) -> dict[str, SourcePlan]:
    """Every file a source's glob matches, each checked like a single file (metadata only), keyed by stem."""
    where = ctx.where("sources", name, kind)
    if is_remote(spec[kind]):
        return _compile_remote_glob(ctx, name, kind, spec, where)
    pattern = spec[kind] if Path(spec[kind]).is_absolute() else str(ctx.config_dir / spec[kind])
    # The folder the glob walks from must be readable; each match is checked again, as a file, by compile_source.
    fixed = itertools.takewhile(lambda part: not GLOB.search(part), Path(pattern).parts)
    ctx.confinement.check_read(Path(*fixed), f"{kind} glob folder", where)
    paths = _glob_files(ctx, pattern, kind, where)
    if not paths:
        raise UserError(f"'{spec[kind]}' matches no file (paths are relative to the config file: {ctx.config_dir})", where)
    # each stem is the name as matched: a symlink is named by its own name, not its target's
    return _compile_matches(ctx, name, kind, spec, where, [str(path) for path in paths], "files", threads=1)


def _compile_remote_glob(ctx: CompileContext, name: str, kind: str, spec: dict[str, Any], where: Where) -> dict[str, SourcePlan]:
    """An `s3://BUCKET/PREFIX/*.parquet` source (any file kind): one listing, then each object's metadata (a parquet
    footer, a CSV's first block, an MCAP summary, an HDF5 file's structure: ranged GETs; an .rrd is downloaded), by stem."""
    objects = remote_glob(spec[kind], where, f"{kind} glob")
    if not objects:
        raise UserError(f"'{shown(spec[kind])}' matches no object", where)
    # each object's metadata costs a few ranged GETs of network latency: REMOTE_METADATA_THREADS objects at a time
    return _compile_matches(ctx, name, kind, spec, where, [o.url for o in objects], "objects", REMOTE_METADATA_THREADS)


def _compile_matches(
    ctx: CompileContext, name: str, kind: str, spec: dict[str, Any], where: Where, matches: list[str], what: str, threads: int
) -> dict[str, SourcePlan]:
    """Each file (path or URL) a glob matched, compiled like a single one (metadata only), keyed by stem; two matches
    sharing a stem are refused. `threads` compile at once (remote files: their latency, not their CPU)."""
    seen: dict[str, str] = {}
    for match in matches:
        stem = match.rsplit("/", 1)[-1].split(".", 1)[0]
        if stem in seen:
            ctx.problems.add(
                f"two {what} matched by '{shown(spec[kind])}' share the stem {quoted(stem)} ({shown(seen[stem])} and {shown(match)}); rename one",
                where,
            )
            continue
        seen[stem] = match

    def compiled(text: str) -> SourcePlan | UserError:
        try:
            plan: SourcePlan = KINDS[kind].compile_source(name, {**spec, kind: text}, ctx.document, ctx.config_dir)
            return plan
        except UserError as exc:
            return exc

    if threads > 1:
        with ThreadPoolExecutor(threads, thread_name_prefix="remote-metadata") as pool:
            plans = dict(zip(seen, pool.map(compiled, seen.values()), strict=True))
    else:
        plans = {stem: compiled(text) for stem, text in seen.items()}
    by_stem: dict[str, SourcePlan] = {}
    for stem, plan in plans.items():
        if isinstance(plan, UserError):
            ctx.problems.extend(plan)
        else:
            by_stem[stem] = plan
    return by_stem


def _glob_files(ctx: CompileContext, pattern: str, kind: str, where: Where) -> list[Path]:
    """The files the glob matches, sorted; folders it matches are passed over. A match that is no readable file (a
    symlink loop, a dangling link, a FIFO) or whose name holds a control character is refused, never skipped: a
    segment would silently be missing. Each match is confined again, as a file, by compile_source."""
    paths = []
    for match in sorted(glob.glob(pattern, recursive=True)):
        refuse_control_characters(match, f"{kind} file matched by the glob", where)
        path = Path(os.path.abspath(match))
        try:
            real = resolved(path)
        except Unresolvable as exc:
            raise UserError(f"{kind} file {path}, matched by the glob, cannot be read: {exc.cause}", where) from None
        if ctx.confinement.may_read(real):  # outside the roots: compile_source refuses it by the rule, learning nothing
            state = file_state(real, f"{kind} file {path}, matched by the glob,", where)
            if state == "folder":
                continue
            if state == "missing":
                raise UserError(f"{kind} file {path}, matched by the glob, is a symbolic link to nothing ({real}); fix or remove it", where)
        paths.append(path)
    return paths


Selection = str | list[int] | tuple[int | None, int | None]  # "all", episode numbers, or a range (A, B)


def parse_episodes(spec: str | list[int], where: Where | None) -> Selection:
    """`all`, a list of indices, or `A:B` (either side may be empty) -> "all", the list, or (A, B)."""
    if isinstance(spec, list) or spec == "all":
        return spec
    match = EPISODES_RANGE.match(spec.strip())
    if match is None:
        numbers = [part.strip() for part in spec.split(",")]
        if all(part.isdigit() for part in numbers):
            return [int(part) for part in numbers]
        raise UserError(f"episodes '{spec}' is not all, a list of indices (0,3,7) or a range A:B (10:20)", where)
    start, stop = (int(g) if g else None for g in match.groups())
    return (start, stop)


def _select(available: list[int], selection: Selection, what: str, where: Where) -> list[int]:
    if selection == "all":
        return available
    if isinstance(selection, tuple):
        start, stop = selection
        chosen = [e for e in available if (start is None or e >= start) and (stop is None or e < stop)]
        if not chosen:
            raise UserError(
                f"episodes {start if start is not None else ''}:{stop if stop is not None else ''} selects none of {what} ({_span(available)})",
                where,
            )
        return chosen
    assert isinstance(selection, list)
    missing = sorted(set(selection) - set(available))
    if missing:
        raise UserError(f"episode(s) {listing([str(m) for m in missing])} do not exist ({what}: {_span(available)})", where)
    return sorted(set(selection))


def _span(indices: list[int]) -> str:
    if not indices:
        return "none"
    return f"{indices[0]}..{indices[-1]}" if indices == list(range(indices[0], indices[-1] + 1)) else listing([str(i) for i in indices])


def expand_segments(
    ctx: CompileContext, sources: CompiledSources | None, episodes_override: str | None, option: str = "--episodes"
) -> DatasetPlan | None:
    """The run's segments, each with its sources, id and output path; None (with problems added) when they cannot be
    named. Without the data (`sources` None: `validate --no-data`) one stand-in segment (episode 0, file stem `stem`)
    checks the templates, the layout and where the outputs go; what depends on the segments' number or names waits."""
    problems, output, specs = ctx.problems, ctx.data["output"], ctx.data["sources"]
    where_segment = ctx.where("output", "segment")
    episodic = [name for name, spec in specs.items() if kind_of(spec) == "lerobot" and "episode" not in spec]
    globbed = [name for name, spec in specs.items() if kind_of(spec) != "lerobot" and GLOB.search(spec[kind_of(spec)])]
    if episodes_override is not None:
        text, where_selection = episodes_override, Where(Path(option), 0)
    else:
        text, where_selection = output.get("episodes", "all"), ctx.where("output", "episodes") if "episodes" in output else where_segment
    try:
        selection = parse_episodes(text, where_selection)
    except UserError as error:
        problems.extend(error)
        return None
    if episodic and globbed:
        problems.add(
            f"segments come either from LeRobot episodes ({listing(sorted(episodic))}) or from globbed files "
            f"({listing(sorted(globbed))}), not both; pin the LeRobot episode with `episode:` or list one file",
            ctx.where("sources"),
        )
        return None

    keys: list[tuple[int | None, str | None]]  # (episode, stem) per segment
    frames: dict[int, int | None] = {}  # rows per episode, when the dataset's metadata says
    if episodic or globbed:
        chosen = _chosen(ctx, sources, episodic, selection, where_selection)
        if chosen is None:
            return None
        keys, frames = chosen
    elif episodes_override is not None or "episodes" in output:
        problems.add(NOTHING_TO_SELECT, where_selection)
        return None
    else:
        pinned = [spec["episode"] for spec in specs.values() if kind_of(spec) == "lerobot"]
        keys = [(pinned[0] if len(pinned) == 1 else None, None)]

    ids = _segment_ids(ctx, output["segment"], keys, where_segment)
    paths = output_paths(ctx, output["path"], ids) if ids is not None else None
    if ids is None or paths is None:
        return None
    segments = []
    for (episode, stem), segment_id, path in zip(keys, ids, paths, strict=True):
        own = tuple(_source_for(plan, sources, episode, stem) for plan in sources.plans.values()) if sources is not None else ()
        inputs = tuple(dict.fromkeys(p for plan in own for p in _inputs_of(ctx, plan)))
        rows = frames.get(episode) if episodic and episode is not None else None
        segments.append(Segment(segment_id, episode, stem, own, path, rows, inputs))
    return dataset_plan(ctx, tuple(segments))


def _chosen(
    ctx: CompileContext, sources: CompiledSources | None, episodic: list[str], selection: Selection, where: Where
) -> tuple[list[tuple[int | None, str | None]], dict[int, int | None]] | None:
    """The (episode, stem) of each segment `selection` picks among a LeRobot dataset's episodes or the globbed files'
    stems, and the episodes' rows; without the data one stand-in, episode 0 or the file stem `stem`."""
    from ..sources import lerobot

    if sources is None:
        return [(0, None if episodic else "stem")], {}
    if not episodic:
        stems = _common_stems(ctx, sources.files)
        if stems is None:
            return None
        return [(i, stems[i]) for i in _select(list(range(len(stems))), selection, f"{len(stems)} files", where)], {}
    frames: dict[int, int | None] = {}
    available: set[int] | None = None
    for plan in (sources.plans[name] for name in episodic):
        assert isinstance(plan, LeRobotSourcePlan)
        try:
            known = lerobot.episodes(plan)
        except UserError as error:  # broken metadata: this config's problem, reported with the others
            ctx.problems.extend(error)
            return None
        frames = frames or known
        available = set(known) if available is None else available & set(known)
    return [(e, None) for e in _select(sorted(available or ()), selection, "the dataset's episodes", where)], frames


NOTHING_TO_SELECT = "episodes selects LeRobot episodes (a lerobot source without `episode:`) or globbed files; this config has neither"


def _common_stems(ctx: CompileContext, files: dict[str, dict[str, SourcePlan]]) -> list[str] | None:
    """Globbed sources pair up by file stem: every one must match the same stems."""
    names = sorted(files)
    reference = set(files[names[0]])
    for name in names[1:]:
        if set(files[name]) != reference:
            only_first = sorted(reference - set(files[name]))
            only_this = sorted(set(files[name]) - reference)
            ctx.problems.add(
                f"globbed sources '{names[0]}' and '{name}' must match files with the same stems (one segment per stem); "
                f"only in '{names[0]}': {listing(only_first, empty='none')}; only in '{name}': {listing(only_this, empty='none')}",
                ctx.where("sources", name),
            )
            return None
    return sorted(reference)


SEGMENT = {"episode": Placeholder(int), "stem": Placeholder(str)}  # output.segment's placeholders


def _segment_ids(ctx: CompileContext, template: str, keys: list[tuple[int | None, str | None]], where: Where) -> list[str] | None:
    problems = ctx.problems
    try:
        checked = checked_template(template, SEGMENT, "output.segment", where)
    except UserError as error:
        problems.extend(error)
        return None
    fields = checked.fields
    known = {"episode": any(e is not None for e, _ in keys), "stem": any(s is not None for _, s in keys)}
    unavailable = sorted(f for f in fields if not known[f])
    if unavailable:
        problems.add(
            f"output.segment uses {listing(['{' + n + '}' for n in unavailable])}, which this config does not give: "
            "{episode} needs a LeRobot source (or globbed files), {stem} globbed files",
            where,
        )
        return None
    ids = [checked.format(**{k: v for k, v in (("episode", e), ("stem", s)) if v is not None}) for e, s in keys]
    duplicated = sorted(i for i, count in Counter(ids).items() if count > 1)
    if duplicated:
        problems.add(
            f"{len(ids)} segments but output.segment {quoted(template)} names several of them {listing(duplicated)}: two segments with "
            "the same id would overwrite each other; put {episode} or {stem} in it",
            where,
        )
        return None
    for segment_id in ids:  # a newline in an id would forge a line of review output and name an output file
        try:
            refuse_control_characters(segment_id, "segment id", where, "take it out of output.segment")
        except UserError as error:
            problems.extend(error)
            return None
    bad = [i for i in ids if "/" in i or "\\" in i or i in (".", "..")]
    if bad:
        problems.add(f"segment id(s) {listing(bad)} contain a path separator; a segment id is a recording_id, not a path", where)
        return None
    return ids


def _source_for(plan: SourcePlan, sources: CompiledSources, episode: int | None, stem: str | None) -> SourcePlan:
    from ..sources import lerobot

    if isinstance(plan, LeRobotSourcePlan) and plan.per_segment:
        assert episode is not None  # segments of per-episode sources are keyed by episode
        return lerobot.for_episode(plan, episode)  # a remote dataset's plan holds the episode's data files
    if plan.name in sources.files and stem is not None:
        return sources.files[plan.name][stem]
    return plan


def _inputs_of(ctx: CompileContext, plan: SourcePlan) -> tuple[Path, ...]:
    """The files a segment's source reads. A LeRobot episode's data files come from the dataset's metadata: each obeys
    the read rule here (a data file linked out of the dataset, or a data_path leading out of it, is refused)."""
    from ..sources import lerobot

    if getattr(plan, "remote", None) is not None:
        return ()  # a remote file: its URL and version are part of the plan, and so of the content hash; no bytes here
    if not isinstance(plan, LeRobotSourcePlan):
        return (plan.path,)
    inputs = lerobot.episode_inputs(plan)
    for file in inputs[1:]:  # one iteration per data file
        ctx.confinement.check_read(file, f"episode {plan.episode}: LeRobot data file", plan.where)
    return inputs
