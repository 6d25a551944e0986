"""A config compiled for live use: the robots, joint mappings, edges and frame graph a run would use, with the sources'
value names but none of their data (a live view's samples come from a control loop or a robot's stream).

`check_live_config` (`validate --live`, and `live` before it subscribes) checks what it can from the config alone;
`compile_live` makes the frozen `LivePlan` once every source's names are known: from `names:`, from the stream's first
message (`live --from`), or from the source's own data as a run reads it (the Python API's `live`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..config import expand_edge_specs, load_document, require_schema_valid
from ..errors import Problems, UserError, UserErrors, Where
from ..plan import ScenePlan, TemporalEdgePlan
from ..sources import KINDS, kind_of
from .compiler import DataNote, _compile_model
from .context import CompileContext

MCAP_TIMELINES = {"header": "ros2_timestamp", "log_time": "message_log_time", "publish_time": "message_publish_time"}
DEFAULT_TIMELINE = "time"  # the live timeline of a source that is not a ROS topic: a timestamp, the push's time


@dataclass(frozen=True)
class LiveSource:
    """A config source as a live view reads it: its value names, and for an MCAP source the topic and which of a
    message's times places it (the timeline a run of the same bag would use)."""

    name: str
    kind: str  # the config's kind: parquet, lerobot, mcap, ...
    names: tuple[str, ...]
    where: Where
    topic: str | None = None  # mcap sources: the topic a live feed subscribes to
    stamp: str = "header"  # mcap sources: header, log_time or publish_time
    timeline: str = DEFAULT_TIMELINE


@dataclass(frozen=True)
class LiveSourceSpec:
    """What the config alone says of a source a live view reads; `names` None when only data or a stream holds them."""

    name: str
    kind: str
    names: tuple[str, ...] | None
    where: Where
    topic: str | None
    stamp: str

    def with_names(self, names: tuple[str, ...]) -> LiveSource:
        timeline = MCAP_TIMELINES[self.stamp] if self.kind == "mcap" else DEFAULT_TIMELINE
        return LiveSource(self.name, self.kind, names, self.where, self.topic, self.stamp, timeline)


@dataclass(frozen=True)
class LivePlan(ScenePlan):
    """The config for live views, frozen: what `LiveView` applies to each sample."""

    application_id: str = ""
    sources: tuple[LiveSource, ...] = ()

    def source_named(self, name: str) -> LiveSource:
        return next(source for source in self.sources if source.name == name)

    def robot_named(self, key: str | None) -> Any:
        """The robot `key` names; without one, the only robot driven by a source (several: an error listing them)."""
        driven = [robot for robot in self.robots if robot.source is not None]
        if key is None and len(driven) == 1:
            return driven[0]
        for robot in self.robots:
            if robot.key == key:
                return robot
        keys = ", ".join(f"'{robot.key}'" for robot in driven) or "none"
        said = "no robot given" if key is None else f"no robot '{key}'"
        raise UserError(f"{said}; say which with robot= one of the robots driven by a source: {keys}", self.robots[0].where)


@dataclass(frozen=True)
class LiveCheck:
    """What `check_live_config` found: errors, notes (names a stream will give), the sources live views read."""

    errors: tuple[UserError, ...]
    notes: tuple[DataNote, ...]
    sources: tuple[LiveSourceSpec, ...]


def _specs(ctx: CompileContext) -> dict[str, LiveSourceSpec]:
    specs: dict[str, LiveSourceSpec] = {}
    for name, spec in ctx.data["sources"].items():
        kind = kind_of(spec)
        names = tuple(spec["names"]) if "names" in spec else None
        topic = spec.get("topic") if kind == "mcap" else None
        specs[name] = LiveSourceSpec(name, kind, names, ctx.where("sources", name), topic, spec.get("timeline", "header"))
    return specs


def _read_sources(ctx: CompileContext) -> set[str]:
    """The sources robots and temporal edges read (sidecar edge files included; their problems are the model's)."""
    used = {spec["joints"]["source"] for spec in ctx.data["robots"].values() if "joints" in spec}
    edges = expand_edge_specs(ctx.data.get("edges", []), ctx.document, Problems())
    return used | {edge.spec["source"] for edge in edges if "source" in edge.spec}


def check_live_config(config_path: Path, stream_only: bool = False) -> LiveCheck:
    """The schema, URDFs, meshes, joint coverage and the frame graph, from the config alone (no source file is opened).
    `stream_only` (`live --from`): every source a robot or temporal edge reads must be an MCAP source (its topic)."""
    try:
        document = load_document(config_path)
        require_schema_valid(document)
    except UserError as exc:
        return LiveCheck(tuple(exc.errors if isinstance(exc, UserErrors) else [exc]), (), ())
    ctx = CompileContext.for_document(document)
    specs = _specs(ctx)
    _refuse_bag_edges(ctx, _compile_model(ctx, {name: spec.names for name, spec in specs.items()}).temporal)
    read = sorted(_read_sources(ctx) & set(specs))
    notes = [
        DataNote(f"source '{name}': names unknown without data; {_names_from(specs[name], stream_only)}", specs[name].where)
        for name in read
        if specs[name].names is None
    ]
    if stream_only:
        for name in read:
            if specs[name].kind != "mcap":
                ctx.problems.add(
                    f"live --from streams ROS 2 JointState topics; source '{name}' is a {specs[name].kind} source. Make it "
                    "an mcap source naming the robot's topic (mcap: FILE, topic: /joint_states), or push its values from Python "
                    "with urdf_pipeline.live(...)",
                    specs[name].where,
                )
    return LiveCheck(tuple(ctx.problems.errors), tuple(notes), tuple(specs[name] for name in read))


def _refuse_bag_edges(ctx: CompileContext, temporal: tuple[TemporalEdgePlan, ...]) -> None:
    """A bag's /tf edges are read from the bag's file by `run`; a live view reads joint values only."""
    for edge in temporal:
        if edge.tf_topic is not None:
            ctx.problems.add(
                f"edge {edge.parent} -> {edge.child} reads {edge.tf_topic} of source '{edge.source}''s bag, which run reads and a live "
                "view does not; drop the edge for live use",
                edge.where,
            )


def _names_from(spec: LiveSourceSpec, stream_only: bool) -> str:
    if stream_only or spec.kind == "mcap":
        return "live takes them from the first message on its topic, and checks the map against them then"
    return "urdf_pipeline.live reads them from the source's data as a run does; give names: [...] for use without data"


def compile_live(config_path: Path, stream_names: Mapping[str, tuple[str, ...]] | None = None, names_from_data: bool = False) -> LivePlan:
    """The `LivePlan`, every problem raised at once. Each source's names: `stream_names` (the stream's first message),
    else `names:`, else (`names_from_data`) the source's metadata as a run reads it (its file must then exist)."""
    document = load_document(config_path)
    require_schema_valid(document)
    ctx = CompileContext.for_document(document)
    specs = _specs(ctx)
    read = _read_sources(ctx) & set(specs)
    names: dict[str, tuple[str, ...] | None] = {}
    for name, spec in specs.items():
        names[name] = (stream_names or {}).get(name) or spec.names
        if names[name] is None and name in read:
            names[name] = _data_names(ctx, name) if names_from_data else None
            if names[name] is None and not names_from_data:
                ctx.problems.add(f"source '{name}': its names are unknown; give names: [...]", spec.where)
    model = _compile_model(ctx, names)
    _refuse_bag_edges(ctx, model.temporal)
    ctx.problems.raise_if_any()
    assert model.root is not None
    sources = tuple(specs[name].with_names(found) for name, found in names.items() if found is not None and name in read)
    return LivePlan(
        config_path=document.file,
        robots=model.robots,
        edges=model.edges,
        root_frame=model.root,
        temporal_edges=model.temporal,
        application_id=ctx.data["output"]["application_id"],
        sources=sources,
    )


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
