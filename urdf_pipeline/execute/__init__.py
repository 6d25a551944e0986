"""One segment of a Plan -> one recording: lazy Rerun streams (model, FK, edges), provenance, blueprint,
viewer, atomic writing.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..package import lazy_surface

if TYPE_CHECKING:  # the package's public surface, the one list (lazy_surface reads it)
    from .blueprint import blueprint_key, blueprint_path, write_blueprint
    from .edges_stream import calibration_stream
    from .joint_fk import ClosedFormJointTransforms, Pose, compose, rotation_matrices
    from .kinematics import RobotKinematics, ValueBlock, segment_kinematics, segment_value_blocks, value_blocks
    from .limits_report import check_joint_statistics
    from .manifest_entry import JointDifferences, JointPreview, SegmentSummary, TimeRange
    from .model_stream import cached_tree, robot_model_stream
    from .provenance import provenance_stream, stored_content_hash
    from .qa_metrics import JointMetrics, SegmentMetrics, SegmentQa, TimingMetrics, by_joint, segment_flags
    from .qa_pass import QaReport, dataset_qa, qa_timeline
    from .segment import Parts, RunResult, execute, log_segment
    from .segment_run import CONTENT_METADATA, SegmentJob, SegmentResult, install_run_plan, run_segment
    from .temporal_stream import TemporalEdgeStats, TemporalEdgeValues, check_temporal_edges
    from .transform_lenses import transform_fields
    from .viewer_delivery import send_to_viewer
    from .writer import (
        folders_removed_if_left_empty,
        foreign_reason,
        process_alive,
        remove_stale_partials,
        require_ours,
        require_writable,
        write_file_atomically,
    )

if not TYPE_CHECKING:  # the names above, imported when first used
    __all__, __getattr__ = lazy_surface(__name__, __file__)
