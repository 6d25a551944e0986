"""Forward kinematics as a lazy, columnar stream: two lenses per robot (compute batches, scatter to Transform3D)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import pyarrow as pa

from ..plan import RobotPlan
from ..sources import CallbackErrors, JointValueMapper, raw_matrix
from .joint_fk import ClosedFormJointTransforms
from .joint_series import TRANSFORMS_FIELD, series_lens, with_values
from .progress_meter import RowMeter
from .ranges_and_preview import ValuePreview
from .trail_stream import TrailPositions, trail_field, trail_lenses
from .transform_lenses import transform_lenses, transform_stream

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream
    from rerun.urdf import UrdfTree

    from ..sources import SourceStream


def _batch_component(robot_key: str) -> str:
    return f"urdf_pipeline:JointTransformBatch:{robot_key}"


class JointTransformBatches:
    """The first lens's function: joint vectors -> per-row batches of joint transforms (Rerun's URDF FK, in closed
    form over whole columns: see joint_fk.py)."""

    def __init__(
        self,
        mapper: JointValueMapper,
        tree: UrdfTree,
        progress: RowMeter | None = None,
        series: bool = False,
        preview: ValuePreview | None = None,
        trails: list[TrailPositions] | None = None,
    ) -> None:
        self.mapper = mapper
        self.progress = progress
        self.preview = preview  # the manifest's preview of the values (ranges_and_preview.py)
        self.transforms = ClosedFormJointTransforms(tree, list(mapper.joint_names))
        self.series = series  # output.joint_series: the driven values too, beside the transforms (joint_series.py)
        self.trails = trails or []  # `trails:`: each trail's positions too, beside the transforms (trail_stream.py)

    @property
    def within(self) -> str:
        """The field of the compute lens's struct holding the transforms; "" when it gives the transforms alone."""
        return TRANSFORMS_FIELD if self.series or self.trails else ""

    def __call__(self, vectors: pa.Array) -> pa.Array:
        # Rows that name their values (MCAP JointState) are mapped by name, row by row; vectors by position.
        raw = raw_matrix(self.mapper.source, vectors, self.mapper.columns, f"robot '{self.mapper.robot.key}'")
        values, left_out = self.mapper.urdf_values(raw)
        if self.preview is not None:
            self.preview.add(values, left_out)
        batches = self.transforms(values)
        if left_out is not None:  # a null batch scatters to a row with no transform: nothing logged at that time
            batches = pa.ListArray.from_arrays(batches.offsets, batches.values, mask=pa.array(left_out))
        if self.progress is not None:
            self.progress.add(len(values))
        if not self.within:
            return batches
        # the driven joints are the matrix's first columns (mapped, then held, then mimic)
        driven = values[:, : len(self.mapper.columns)] if self.series else None
        return with_values(
            batches, driven, left_out, {trail_field(i): trail.column(values, left_out) for i, trail in enumerate(self.trails)}
        )


def fk_stream(source: SourceStream, robots: list[tuple[RobotPlan, JointTransformBatches]], errors: CallbackErrors) -> LazyChunkStream:
    """All robots driven by one source, from one read of it: (robot, batch function) each; a robot whose batch
    function gives the values too gets its time series from the same pass."""
    pairs = [
        transform_lenses(
            source,
            f"/__urdf_pipeline/{robot.key}/joint_transform_batches",
            _batch_component(robot.key),
            robot.fk_entity,
            batches,
            errors,
            batches.within,
        )
        for robot, batches in robots
    ]
    series = [series_lens(_batch_component(robot.key), robot) for robot, batches in robots if batches.series]
    series += [lens for robot, batches in robots for lens in trail_lenses(_batch_component(robot.key), [t.trail for t in batches.trails])]
    return transform_stream(source, pairs, errors, series)
