"""The driven joints' values as Rerun time series (`output.joint_series`), from the FK's own value matrix.

The FK's compute lens returns the matrix's driven columns beside the transforms; a second lens copies them, one row
of K scalars per source row, to `<entity_path_prefix>/joint_values`. So the series are exactly what the FK used, on
its timelines, block by block (memory does not grow with the segment). One entity per robot, not per joint: one chunk
per block instead of K, and the TimeSeriesView plots each instance as its own series, named by `SeriesLines:names`.
Held and mimic joints are not plotted: the series are the values the source gave.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa

from ..plan import RobotPlan

if TYPE_CHECKING:
    from rerun.chunk import DeriveLens, LazyChunkStream

TRANSFORMS_FIELD = "transforms"  # the compute lens's struct: the joint transforms (what the scatter lens reads) ...
VALUES_FIELD = "values"  # ... and the driven joints' URDF values (what the series lens reads)
SERIES_NAME = "joint_values"


def series_entity(robot: RobotPlan) -> str:
    """Where a robot's series go: beside its FK entity (`<prefix>/joint_transforms`), under the robot's own prefix."""
    return f"{robot.entity_path_prefix}/{SERIES_NAME}"


def plotted_robots(robots: tuple[RobotPlan, ...]) -> tuple[RobotPlan, ...]:
    """The robots that get a series: those a source drives (a scene URDF without moving joints has none)."""
    return tuple(robot for robot in robots if robot.source is not None and robot.channels)


def with_values(
    batches: pa.Array, values: np.ndarray | None, left_out: np.ndarray | None, more: dict[str, pa.Array] | None = None
) -> pa.StructArray:
    """One struct per row: the row's transforms and its driven values (`values`: rows x driven joints, float64; None
    without `output.joint_series`), and `more` fields (the trails' positions, trail_stream.py). A row the NaN policy leaves
    out has a null list, as its transforms: nothing is plotted at that time."""
    arrays, names = [batches], [TRANSFORMS_FIELD]
    if values is not None:
        rows, count = values.shape
        offsets = pa.array(np.arange(rows + 1, dtype=np.int32) * count)
        flat = pa.array(np.ascontiguousarray(values, dtype=np.float64).reshape(-1))
        arrays.append(pa.ListArray.from_arrays(offsets, flat, mask=None if left_out is None else pa.array(left_out)))
        names.append(VALUES_FIELD)
    for name, array in (more or {}).items():
        arrays.append(array)
        names.append(name)
    return pa.StructArray.from_arrays(arrays, names=names)


def series_lens(component: str, robot: RobotPlan) -> DeriveLens:
    """The second stage's lens: the struct's values, one row of K scalars per source row, on the robot's series entity."""
    import rerun as rr
    from rerun.chunk import DeriveLens, Selector

    return DeriveLens(component, output_entity=series_entity(robot)).to_component(
        rr.Scalars.descriptor_scalars(), Selector(f".{VALUES_FIELD}[]")
    )


def series_names_stream(robots: tuple[RobotPlan, ...]) -> LazyChunkStream:
    """One static chunk per plotted robot: the series' names (the URDF joints), which the plot's legend shows."""
    import rerun as rr
    from rerun.chunk import Chunk, LazyChunkStream

    chunks = []
    for robot in plotted_robots(robots):
        names = [channel.joint for channel in robot.channels]  # the driven joints, in the order of the FK's value matrix
        columns = rr.SeriesLines.columns(names=names).partition([len(names)])
        chunks.append(Chunk.from_columns(series_entity(robot), indexes=[], columns=columns))
    return LazyChunkStream.from_iter(chunks)
