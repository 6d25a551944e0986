"""Stage 3, one segment of a Plan -> one recording: lazy Rerun streams (model, FK, edges), provenance, blueprint,
viewer, atomic writing. May import: the top-level base, config, urdf, sources, compile.

The names below are the package's public surface; other packages import them from here, never from its modules.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .. import lazy_surface

if TYPE_CHECKING:
    from .blueprint import blueprint_key, blueprint_path, write_blueprint
    from .edges_stream import CALIBRATION_ENTITY, calibration_stream
    from .joint_fk import rotation_matrices
    from .kinematics import RobotKinematics, segment_kinematics
    from .live_viewer import send_to_viewer, viewer_binary
    from .model_stream import cached_tree, robot_model_stream
    from .provenance import stored_content_hash
    from .segment import Parts, RunResult, execute, log_segment
    from .segment_run import SegmentJob, SegmentResult, install_run_plan, run_segment
    from .writer import process_alive, remove_stale_partials, require_ours, require_writable, write_file_atomically

__all__ = [
    "RobotKinematics",
    "CALIBRATION_ENTITY",
    "Parts",
    "RunResult",
    "SegmentJob",
    "SegmentResult",
    "blueprint_key",
    "blueprint_path",
    "cached_tree",
    "calibration_stream",
    "execute",
    "install_run_plan",
    "log_segment",
    "robot_model_stream",
    "rotation_matrices",
    "process_alive",
    "remove_stale_partials",
    "require_ours",
    "require_writable",
    "run_segment",
    "segment_kinematics",
    "send_to_viewer",
    "viewer_binary",
    "stored_content_hash",
    "write_blueprint",
    "write_file_atomically",
]

__getattr__ = lazy_surface(
    __name__,
    {
        "Parts": "segment",
        "RunResult": "segment",
        "SegmentJob": "segment_run",
        "SegmentResult": "segment_run",
        "blueprint_key": "blueprint",
        "CALIBRATION_ENTITY": "edges_stream",
        "blueprint_path": "blueprint",
        "cached_tree": "model_stream",
        "calibration_stream": "edges_stream",
        "execute": "segment",
        "install_run_plan": "segment_run",
        "log_segment": "segment",
        "robot_model_stream": "model_stream",
        "rotation_matrices": "joint_fk",
        "process_alive": "writer",
        "remove_stale_partials": "writer",
        "require_ours": "writer",
        "require_writable": "writer",
        "run_segment": "segment_run",
        "RobotKinematics": "kinematics",
        "segment_kinematics": "kinematics",
        "send_to_viewer": "live_viewer",
        "viewer_binary": "live_viewer",
        "stored_content_hash": "provenance",
        "write_blueprint": "blueprint",
        "write_file_atomically": "writer",
    },
)
