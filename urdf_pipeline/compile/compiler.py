"""Config file -> frozen plan: parse, validate against the schema, then every check that needs the URDF.

`check_config_without_data` (`validate --no-data`) makes the same checks except those that need the source files:
for a repository that keeps its configs in git and its datasets elsewhere."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from ..config import Document, expand_edge_specs, load_document, require_schema_valid
from ..errors import UserError, UserErrors, Where, warn
from ..plan import EdgePlan, Plan, RobotPlan, SourcePlan, TemporalEdgePlan
from ..sources import kind_of
from ..urdf import UrdfModel
from .comparisons import with_comparisons
from .context import CompileContext, SourceNames
from .edges import assumed_identity_edges, compile_edges, frame_edges, urdf_frames
from .frame_graph import check_frame_graph
from .robots import compile_robot
from .segments import check_segments_without_data, compile_sources, expand_segments
from .trails import compile_trails, source_timelines, spec_timelines


def compile_config(config_path: Path, episodes: str | None = None) -> Plan:
    """`episodes` (from `run --episodes`) overrides output.episodes."""
    document = load_document(config_path)
    require_schema_valid(document)
    return compile_document(document, episodes)


def compile_document(document: Document, episodes: str | None = None) -> Plan:
    ctx = CompileContext.for_document(document)
    compiled_sources = compile_sources(ctx)
    sources: dict[str, SourcePlan] = compiled_sources.plans
    model = _compile_model(ctx, {name: plan.names for name, plan in sources.items()})
    dataset = expand_segments(ctx, compiled_sources, episodes) if len(sources) == len(ctx.data["sources"]) else None
    timelines = {name: source_timelines(plan) for name, plan in sources.items()}
    trails = compile_trails(ctx, model.robots, model.edges, model.temporal, model.root, timelines) if model.root is not None else ()
    ctx.problems.raise_if_any()
    assert model.root is not None and dataset is not None
    return Plan(
        config_path=document.file,
        robots=model.robots,
        edges=model.edges,
        root_frame=model.root,
        temporal_edges=model.temporal,
        dataset=dataset,
        application_id=ctx.data["output"]["application_id"],
        output_where=ctx.where("output"),
        trails=trails,
    )


@dataclass(frozen=True)
class DataNote:
    """What `validate --no-data` could not check because only a source's data holds it."""

    message: str
    where: Where


@dataclass(frozen=True)
class DatalessCheck:
    """What checking a config without its data found. It holds no Plan on purpose: a plan made without reading the
    sources (their files, widths, episodes, segments) must never reach `run`."""

    errors: tuple[UserError, ...]
    notes: tuple[DataNote, ...]


def check_config_without_data(config_path: Path) -> DatalessCheck:
    """`validate --no-data`: the schema, URDFs, meshes, joint coverage, the frame graph and the output templates,
    checked from the config alone; no source file is opened, no data path is globbed or even looked at. Source names
    come from `names:`; a source without them gets a note, and what needs them (map keys, ignore, temporal edge
    values) is left to the checks that read the data (`validate`, `run`), as are the segments' number and names."""
    try:
        document = load_document(config_path)
        require_schema_valid(document)
    except UserError as exc:
        return DatalessCheck(tuple(exc.errors if isinstance(exc, UserErrors) else [exc]), ())
    ctx = replace(CompileContext.for_document(document), opens_sources=False)
    names: dict[str, tuple[str, ...] | None] = {}
    notes: list[DataNote] = []
    for name, spec in ctx.data["sources"].items():
        names[name] = tuple(spec["names"]) if "names" in spec else None
        if names[name] is None:
            notes.append(DataNote(_names_unknown(kind_of(spec)), ctx.where("sources", name)))
    model = _compile_model(ctx, names)
    if model.root is not None:
        timelines = {name: spec_timelines(spec) for name, spec in ctx.data["sources"].items()}
        compile_trails(ctx, model.robots, model.edges, model.temporal, model.root, timelines)
    check_segments_without_data(ctx)
    return DatalessCheck(tuple(ctx.problems.errors), tuple(notes))


NAMES_HELD_BY = {  # where a source without `names:` gets them
    "parquet": "the parquet file's columns",
    "csv": "the CSV header",
    "lerobot": "the dataset's meta/info.json",
    "mcap": "the topic's first message",
    "hdf5": "the dataset's width, 0 .. K-1",
    "rrd": "the recording's SeriesLines:names",
}


def _names_unknown(kind: str) -> str:
    holder = NAMES_HELD_BY.get(kind, "its data")
    return (
        f"names unknown without data (they come from {holder}): the map keys, ignore and temporal edge values naming "
        "them are checked at run (and by validate without --no-data); give names: [...] to check them here"
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
    used = {spec["joints"]["source"] for spec in data["robots"].values() if "joints" in spec}
    used |= {edge.spec["source"] for edge in edge_specs if "source" in edge.spec}  # temporal edges read sources too
    used |= {edge.spec["tf"] for edge in edge_specs if "tf" in edge.spec}  # and a bag's /tf edges
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
