"""The frozen, typed plan: everything decided before any joint value is read (its two levels, `Plan` and
`RecordingPlan`, are ARCHITECTURE.md's seam), one module per part: sources, robots and edges, scenes, live views, trails.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .live_plans import DEFAULT_TIMELINE, LivePlan, LiveSource, LiveSourceSpec
    from .qa_plans import QA_FLAGS, ByKind, QaFlag, QaPlan
    from .robot_plans import Comparison, EdgeKind, EdgePlan, FixedChain, HeldJoint, JointChannel, MimicJoint, RobotPlan, TemporalEdgePlan
    from .scene_plans import DatasetPlan, Layout, OutputPlan, Plan, RecordingPlan, RemoteOutputs, ScenePlan, Segment
    from .source_plans import (
        CsvSourcePlan,
        FileSourcePlan,
        Hdf5SourcePlan,
        IndexPlan,
        LeRobotSourcePlan,
        McapSourcePlan,
        NamedSource,
        NanPolicy,
        OnViolation,
        ParquetSourcePlan,
        RemoteDataset,
        RemoteObject,
        RrdSourcePlan,
        SourcePlan,
        TimelineKind,
        remote_of,
        with_local_path,
    )
    from .trail_plans import TrailPlan, TrailStyle, WindowUnit

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
