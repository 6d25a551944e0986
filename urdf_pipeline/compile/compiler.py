"""Config file -> frozen plan: parse, validate against the schema, then every check that needs the URDF.

One compile for every command; what varies is where the sources' value names come from (`NameSource`): their data
(`run`, `validate`: a `Plan`), the config alone (`validate --no-data`, for a repository that keeps its configs in git
and its datasets elsewhere: no plan), a live stream (`live --from`, `validate --live`) or, for the Python API's
`live`, the data of each source without `names:` (a `LivePlan`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Generic, Literal, TypeVar, cast

from ..config import Document, EdgeSpec, expand_edge_specs, load_document, require_schema_valid
from ..confine import confinement_for
from ..errors import Problems, UserError, UserErrors, Where, warn
from ..plan import DEFAULT_TIMELINE, EdgePlan, LivePlan, LiveSourceSpec, Plan, RobotPlan, ScenePlan, TemporalEdgePlan
from ..sources import KINDS, MCAP_TIMELINES, kind_of
from ..urdf import UrdfModel
from .comparisons import with_comparisons
from .context import CompileContext, SourceNames
from .edges import assumed_identity_edges, compile_edges, frame_edges, urdf_frames
from .frame_graph import check_frame_graph
from .qa import compile_qa
from .robots import compile_robot
from .segments import CompiledSources, compile_sources, expand_segments
from .trails import compile_trails, source_timelines, spec_timelines

P = TypeVar("P", bound=ScenePlan, covariant=True)


@dataclass(frozen=True)
class NameSource(Generic[P]):
    """Where the compile finds each source's value names, and so which plan it makes (`P`)."""

    origin: Literal["data", "config", "stream", "live data"]
    stream: Mapping[str, tuple[str, ...]] = field(default_factory=dict)  # a live stream's first messages, by source
    episodes: str | None = None  # `run --episodes`, over output.episodes
    episodes_option: str = "--episodes"  # how the user wrote it (`check --episode`), for the errors that locate it

    @property
    def live(self) -> bool:
        return self.origin in ("stream", "live data")


FROM_CONFIG = NameSource[Plan]("config")  # `validate --no-data`: `names:`, else a note; never a plan
FROM_STREAM = NameSource[LivePlan]("stream")  # `live --from`, `validate --live`: `names:`, else the first message's
FROM_LIVE_DATA = NameSource[LivePlan]("live data")  # the Python API's `live`: `names:`, else the source's metadata


@dataclass(frozen=True)
class DataNote:
    """What a check without the data could not check because only a source's data (or stream) holds it."""

    message: str
    where: Where


@dataclass(frozen=True)
class Compiled(Generic[P]):
    """What the compile found. `plan` None when there are errors or notes, and always for FROM_CONFIG: a plan made
    without reading the sources (their files, widths, episodes, segments) must never reach `run`."""

    errors: tuple[UserError, ...]
    notes: tuple[DataNote, ...]  # what only the data (or the stream) can check
    plan: P | None
    sources: tuple[LiveSourceSpec, ...] = ()  # live: the sources a live view reads, by name

    def checked(self) -> P:
        """The plan, or every error raised at once."""
        problems = Problems()
        problems.errors.extend(self.errors)
        problems.raise_if_any()
        assert self.plan is not None, "a plan is made once every source's names are known"
        return self.plan


def compile_config(config_path: Path, episodes: str | None = None, option: str = "--episodes") -> Plan:
    """`episodes` (from `run --episodes`, or `check --episode`: `option`) overrides output.episodes."""
    return check_config(config_path, NameSource[Plan]("data", episodes=episodes, episodes_option=option)).checked()


def compile_document(document: Document, episodes: str | None = None) -> Plan:
    return check_document(document, NameSource[Plan]("data", episodes=episodes)).checked()


def check_config(config_path: Path, names: NameSource[P]) -> Compiled[P]:
    """The config file parsed and checked against the schema (their errors raised), then `check_document`."""
    document = load_document(config_path)
    require_schema_valid(document)
    return check_document(document, names)


def check_document(document: Document, names: NameSource[P]) -> Compiled[P]:
    """The one compile: each source's names (`names`), the robots, edges and frame graph (`_compile_model`), then a
    run's segments and trails or a live view's sources. Without the data (FROM_CONFIG) no source file is opened and
    no data path is globbed or even looked at; the segments and trails are checked from the config alone."""
    ctx = CompileContext(document, Problems(), document.file.parent, confinement_for(document.file), opens_sources=names.origin != "config")
    data = ctx.data
    compiled = compile_sources(ctx) if names.origin == "data" else None
    needed = list(data["sources"])  # the sources whose names are needed, in config order: a live view reads only some
    if names.live:
        read = _read_sources(ctx, expand_edge_specs(data.get("edges", []), document, Problems()))
        needed = [name for name in needed if name in read]
    found, notes = _source_names(ctx, names, compiled, needed)
    model = _compile_model(ctx, found)
    qa = compile_qa(ctx)
    specs: dict[str, LiveSourceSpec] = {}
    if names.live:
        specs = {name: _live_spec(ctx, name) for name in sorted(needed)}
        _refuse_what_live_cannot_read(ctx, names, model.temporal, specs)
    else:
        all_compiled = compiled is None or len(compiled.plans) == len(data["sources"])
        dataset = expand_segments(ctx, compiled, names.episodes, names.episodes_option) if all_compiled else None
        timelines = (  # each source's (timeline, kind), for the trails' windows: from its plan, else its config entry
            {name: source_timelines(source) for name, source in compiled.plans.items()}
            if compiled is not None
            else {name: spec_timelines(spec) for name, spec in data["sources"].items()}
        )
        trails = compile_trails(ctx, model.robots, model.edges, model.temporal, model.root, timelines) if model.root is not None else ()
    plan: ScenePlan | None = None
    if not ctx.problems.errors and not notes and names.origin != "config":
        assert model.root is not None
        scene = (document.file, model.robots, model.edges, model.root, model.temporal)
        application_id = data["output"]["application_id"]
        if names.live:
            plan = LivePlan(*scene, application_id, tuple(specs[name].with_names(found[name] or ()) for name in needed))
        else:
            assert dataset is not None
            plan = Plan(*scene, dataset, application_id, ctx.where("output"), trails, qa)
    compiled_plan = Compiled(tuple(ctx.problems.errors), tuple(notes), plan, tuple(specs.values()))
    return cast(Compiled[P], compiled_plan)  # the plan's type is the one `names` says


def _source_names(
    ctx: CompileContext, names: NameSource[ScenePlan], compiled: CompiledSources | None, needed: list[str]
) -> tuple[dict[str, tuple[str, ...] | None], list[DataNote]]:
    """Each source's value names (None: unknown), and a note for each source `needed` whose names only its data (or
    stream) holds."""
    if compiled is not None:
        return {name: plan.names for name, plan in compiled.plans.items()}, []
    found = {name: names.stream.get(name) or _live_spec(ctx, name).names for name in ctx.data["sources"]}
    notes: list[DataNote] = []
    for name in sorted(needed) if names.origin == "stream" else needed:
        if found[name] is None and names.origin == "live data":
            found[name] = _data_names(ctx, name)
        elif found[name] is None:
            notes.append(DataNote(_names_unknown(names, name, kind_of(ctx.data["sources"][name])), ctx.where("sources", name)))
    return found, notes


NAMES_HELD_BY = {  # where a source without `names:` gets them
    "parquet": "the parquet file's columns",
    "csv": "the CSV header",
    "lerobot": "the dataset's meta/info.json",
    "mcap": "the topic's first message",
    "hdf5": "the dataset's width, 0 .. K-1",
    "rrd": "the recording's SeriesLines:names",
}


def _names_unknown(names: NameSource[ScenePlan], name: str, kind: str) -> str:
    if names.live:
        return f"source '{name}': names unknown without data; live takes them from the first message on its topic, and checks the map against them then"
    holder = NAMES_HELD_BY.get(kind, "its data")
    return (
        f"names unknown without data (they come from {holder}): the map keys, ignore and temporal edge values naming "
        "them are checked at run (and by validate without --no-data); give names: [...] to check them here"
    )


def _live_spec(ctx: CompileContext, name: str) -> LiveSourceSpec:
    spec = ctx.data["sources"][name]
    kind = kind_of(spec)
    names = tuple(spec["names"]) if "names" in spec else None
    topic, stamp = spec.get("topic") if kind == "mcap" else None, spec.get("timeline", "header")
    timeline = MCAP_TIMELINES[stamp] if kind == "mcap" else DEFAULT_TIMELINE  # the timeline a run of the same bag uses
    return LiveSourceSpec(name, kind, names, ctx.where("sources", name), topic, stamp, timeline)


def _read_sources(ctx: CompileContext, edges: list[EdgeSpec]) -> set[str]:
    """The sources whose values robots and temporal edges read (not a bag's /tf edges: those read its file). The edges'
    problems (a sidecar file's) are the model's, said once."""
    used = {spec["joints"]["source"] for spec in ctx.data["robots"].values() if "joints" in spec}
    return used | {edge.spec["source"] for edge in edges if "source" in edge.spec}


def _data_names(ctx: CompileContext, name: str) -> tuple[str, ...] | None:
    """A source's names as a run reads them (its metadata); a source whose data cannot be read gets an error saying
    that live use without data needs `names:`."""
    spec = ctx.data["sources"][name]
    try:
        return KINDS[kind_of(spec)].compile_source(name, spec, ctx.document, ctx.config_dir).names
    except UserError as exc:
        for error in exc.errors if isinstance(exc, UserErrors) else [exc]:
            ctx.problems.add(f"{error.message}; a live view without the data needs the names: give names: [...]", error.where)
        return None


def _refuse_what_live_cannot_read(
    ctx: CompileContext, names: NameSource[ScenePlan], temporal: tuple[TemporalEdgePlan, ...], read: dict[str, LiveSourceSpec]
) -> None:
    """A bag's /tf edges are read from the bag's file by `run`; a live view reads joint values only. A stream
    (`live --from`) gives JointState topics: every source read must be an MCAP source (its topic)."""
    for edge in temporal:
        if edge.tf_topic is not None:
            ctx.problems.add(
                f"edge {edge.parent} -> {edge.child} reads {edge.tf_topic} of source '{edge.source}''s bag, which run reads and a live "
                "view does not; drop the edge for live use",
                edge.where,
            )
    for spec in read.values() if names.origin == "stream" else ():
        if spec.kind != "mcap":
            ctx.problems.add(
                f"live --from streams ROS 2 JointState topics; source '{spec.name}' is a {spec.kind} source. Make it "
                "an mcap source naming the robot's topic (mcap: FILE, topic: /joint_states), or push its values from Python "
                "with urdf_pipeline.live(...)",
                spec.where,
            )


@dataclass(frozen=True)
class _Model:
    """Robots, edges and the root: everything the Plan holds that needs no source file beyond its value names."""

    robots: tuple[RobotPlan, ...]
    edges: tuple[EdgePlan, ...]
    temporal: tuple[TemporalEdgePlan, ...]
    root: str | None


def _compile_model(ctx: CompileContext, sources: SourceNames) -> _Model:
    """Every check between the sources and the segments, problems added to ctx: robots (URDF, meshes, joint
    coverage), unused sources, edges (sidecars included) and the frame graph. `sources`: the names of each source
    that compiled."""
    data, problems = ctx.data, ctx.problems
    robots: list[RobotPlan] = []
    models: dict[str, UrdfModel] = {}  # parsed once, for the edges that walk a URDF (fixed_chain)
    for key, spec in data["robots"].items():
        compiled = compile_robot(ctx, key, spec, sources)
        if compiled is not None:
            robots.append(compiled.plan)
            models[key] = compiled.model
    robots = with_comparisons(ctx, robots, models)
    if data["output"].get("joint_series") and len(robots) == len(data["robots"]) and not any(r.channels for r in robots):
        warn("no robot of this config is driven by a source: joint_series plots nothing", ctx.where("output", "joint_series"))

    edge_specs = expand_edge_specs(data.get("edges", []), ctx.document, problems)  # inline edges and sidecar files, in order
    used = _read_sources(ctx, edge_specs) | {edge.spec["tf"] for edge in edge_specs if "tf" in edge.spec}  # and a bag's /tf edges
    for name in data["sources"]:
        if name not in used:
            problems.add(
                f"source '{name}' is used by no robot and no temporal edge; remove it, or name it in a robot's joints.source "
                "or a temporal edge's source",
                ctx.where("sources", name),
            )

    prefixes_unique = _check_unique_prefixes(ctx)
    # Frame names can be traced to robots only when every robot compiled and their frame prefixes differ.
    frames_known = prefixes_unique and len(robots) == len(data["robots"])
    compiled_edges = compile_edges(ctx, edge_specs, robots if frames_known else None, models, sources)
    edges, temporal = list(compiled_edges.static), list(compiled_edges.temporal)
    root = _root_frame(ctx, robots)
    if root is not None and frames_known:
        graph = frame_edges(robots, edges, temporal, models, compiled_edges.broken)
        identity = assumed_identity_edges(ctx, robots, graph, root)
        edges += identity
        graph += frame_edges([], identity, [], models)
        check_frame_graph(ctx, graph, urdf_frames(robots), root, ctx.where("frames", "root"))
    return _Model(tuple(robots), tuple(edges), tuple(temporal), root)


def _check_unique_prefixes(ctx: CompileContext) -> bool:
    before = len(ctx.problems.errors)
    frame_prefixes: dict[str, str] = {}
    entity_prefixes: dict[str, str] = {}
    for key, spec in ctx.data["robots"].items():
        frame_prefix = spec.get("frame_prefix", "")
        if frame_prefix in frame_prefixes:
            ctx.problems.add(
                f"robots '{frame_prefixes[frame_prefix]}' and '{key}' share frame_prefix '{frame_prefix}'; their frames would cross-wire. Give each robot its own frame_prefix",
                ctx.where("robots", key, "frame_prefix") if "frame_prefix" in spec else ctx.where("robots", key),
            )
        frame_prefixes.setdefault(frame_prefix, key)
        entity_prefix = spec.get("entity_path_prefix", key).strip("/")
        if entity_prefix in entity_prefixes:
            ctx.problems.add(
                f"robots '{entity_prefixes[entity_prefix]}' and '{key}' share entity_path_prefix '{entity_prefix}'",
                ctx.where("robots", key, "entity_path_prefix"),
            )
        entity_prefixes.setdefault(entity_prefix, key)
    return len(ctx.problems.errors) == before


def _root_frame(ctx: CompileContext, robots: list[RobotPlan]) -> str | None:
    data = ctx.data
    root = data.get("frames", {}).get("root")
    if root is not None:
        return str(root)
    if len(data["robots"]) > 1:
        ctx.problems.add(
            "frames.root is required with more than one robot: name the frame every robot's calibration edge hangs from",
            ctx.where("frames"),
        )
        return None
    return robots[0].frame_prefix + robots[0].root_link if robots else None
