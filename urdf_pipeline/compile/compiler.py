"""Config file -> frozen plan: parse, validate against the schema, then every check that needs the URDF."""

from __future__ import annotations

from pathlib import Path

from ..config import Document, expand_edge_specs, load_document, require_schema_valid
from ..plan import OutputPlan, Plan, RobotPlan, SourcePlan
from ..urdf import UrdfModel
from .context import CompileContext
from .edges import assumed_identity_edges, compile_edges, frame_edges, urdf_frames
from .frame_graph import check_frame_graph
from .robots import compile_robot
from .segments import compile_sources, expand_segments


def compile_config(config_path: Path, episodes: str | None = None) -> Plan:
    """`episodes` (from `run --episodes`) overrides output.episodes."""
    document = load_document(config_path)
    require_schema_valid(document)
    return compile_document(document, episodes)


def compile_document(document: Document, episodes: str | None = None) -> Plan:
    ctx = CompileContext.for_document(document)
    data = ctx.data
    problems = ctx.problems

    compiled_sources = compile_sources(ctx)
    sources: dict[str, SourcePlan] = compiled_sources.plans

    robots: list[RobotPlan] = []
    models: dict[str, UrdfModel] = {}  # parsed once, for the edges that walk a URDF (fixed_chain)
    for key, spec in data["robots"].items():
        compiled = compile_robot(ctx, key, spec, sources)
        if compiled is not None:
            robots.append(compiled.plan)
            models[key] = compiled.model

    edge_specs = expand_edge_specs(data.get("edges", []), document, problems)  # inline edges and sidecar files, in order
    used = {spec["joints"]["source"] for spec in data["robots"].values() if "joints" in spec}
    used |= {edge.spec["source"] for edge in edge_specs if "source" in edge.spec}  # temporal edges read sources too
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
    dataset = expand_segments(ctx, compiled_sources, episodes) if len(sources) == len(data["sources"]) else None
    problems.raise_if_any()
    assert root is not None and dataset is not None
    first = dataset.segments[0]
    output = OutputPlan(first.output, data["output"]["application_id"], first.id, ctx.where("output"))
    return Plan(document.file, first.sources, tuple(robots), tuple(edges), root, output, tuple(temporal), dataset)


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
