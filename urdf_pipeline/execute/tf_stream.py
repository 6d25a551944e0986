"""A bag's /tf edges as a lazy stream: each TFMessage's transforms (several per message) picked by child frame, whole
columns at a time, into one Transform3D chunk per edge on `/calibration/temporal/CHILD`, on the source's timeline
(the transform's own header stamp for `timeline: header`, else the message's log or publish time)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import partial
from typing import TYPE_CHECKING

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..errors import UserError, quoted
from ..plan import McapSourcePlan, RecordingPlan, TemporalEdgePlan
from ..sources import tf_messages
from .temporal_stream import TemporalEdgeStats, placed_poses

if TYPE_CHECKING:
    from rerun.chunk import Chunk, LazyChunkStream

TF_COMPONENT = "tf2_msgs.msg.TFMessage:message"
HEADER_TIMELINE = "ros2_timestamp"


@dataclass
class TfEdgeValues:
    """One /tf edge and what the pass found of it (the statistics `check_temporal_edges` reads)."""

    edge: TemporalEdgePlan
    stats: TemporalEdgeStats = field(default_factory=TemporalEdgeStats)


def _columns(source: McapSourcePlan, batch: pa.RecordBatch) -> tuple[pa.Array, pa.Array, np.ndarray, np.ndarray, np.ndarray]:
    """Every transform of the batch's messages: child and parent frames, times (int64 ns), translations, quaternions."""
    messages = batch.column(batch.schema.get_field_index(TF_COMPONENT)).flatten()
    lists = pc.struct_field(messages, "transforms")
    flat = pc.list_flatten(lists)
    if source.timeline == HEADER_TIMELINE:
        sec = pc.struct_field(flat, [0, 0, 0]).to_numpy(zero_copy_only=False).astype(np.int64)
        nanosec = pc.struct_field(flat, [0, 0, 1]).to_numpy(zero_copy_only=False).astype(np.int64)
        times = sec * 1_000_000_000 + nanosec
    else:
        if source.timeline not in batch.schema.names:
            raise UserError(f"messages on the /tf topic of source '{source.name}' have no {source.timeline} timeline", source.where)
        per_message = batch.column(batch.schema.get_field_index(source.timeline)).cast(pa.int64()).to_numpy(zero_copy_only=False)
        times = np.repeat(per_message, pc.list_value_length(lists).fill_null(0).to_numpy(zero_copy_only=False))
    moved = pc.struct_field(flat, "transform")
    translation = np.stack([pc.struct_field(moved, [0, i]).to_numpy(zero_copy_only=False) for i in range(3)], axis=1)
    quaternion = np.stack([pc.struct_field(moved, [1, i]).to_numpy(zero_copy_only=False) for i in range(4)], axis=1)
    return pc.struct_field(flat, "child_frame_id"), pc.struct_field(flat, [0, 1]), times, translation, quaternion


def _edge_chunks(source: McapSourcePlan, values: list[TfEdgeValues], chunk: Chunk) -> list[Chunk]:
    import rerun as rr
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    if batch.schema.get_field_index(TF_COMPONENT) < 0 or not batch.num_rows:
        return []
    children, parents, times, translation, quaternion = _columns(source, batch)
    result = []
    for edge_values in values:
        edge = edge_values.edge
        named = pc.equal(children, edge.child).to_numpy(zero_copy_only=False)
        picked = named & pc.equal(parents, edge.parent).to_numpy(zero_copy_only=False)
        if (named & ~picked).any():  # tf2 keeps one parent per frame: a bag that moves it is refused, not half-drawn
            other = parents.filter(pa.array(named & ~picked))[0].as_py()
            raise UserError(
                f"{edge.tf_topic} of source '{source.name}''s bag places {quoted(edge.child)} in {quoted(other)} in "
                f"{int((named & ~picked).sum())} transforms of one batch, not in {quoted(edge.parent)}; a frame has one parent",
                edge.where,
            )
        rows = int(picked.sum())
        if not rows:
            continue
        if source.timeline == HEADER_TIMELINE and not times[picked].all():
            raise UserError(
                f"transforms of {edge.child} on {edge.tf_topic} of source '{source.name}''s bag have a zero header stamp "
                f"({int((times[picked] == 0).sum())} of {rows} in one batch), so they would all sit at time 0; set "
                f"sources.{source.name}.timeline: log_time to use the time the messages were recorded",
                edge.where,
            )
        t, q, usable = placed_poses(translation[picked], quaternion[picked])
        finite = np.isfinite(translation[picked]).all(axis=1) & np.isfinite(quaternion[picked]).all(axis=1)
        edge_values.stats.add(finite[:, None], (edge.tf_topic or "/tf",), usable)  # counted per topic, not per value
        result.append(
            Chunk.from_columns(
                edge.entity,
                indexes=[rr.TimeColumn(source.timeline, timestamp=times[picked].astype("datetime64[ns]"))],
                columns=rr.Transform3D.columns(
                    translation=t, quaternion=q, parent_frame=[edge.parent] * rows, child_frame=[edge.child] * rows
                ),
            )
        )
    return result


def bag_edge_streams(plan: RecordingPlan) -> tuple[list[LazyChunkStream], list[TfEdgeValues]]:
    """Every /tf edge of the segment (compile/bag_edges.py: always of an MCAP source): one read of each /tf topic the
    edges name, in the segment's bag (the source's file)."""
    streams: list[LazyChunkStream] = []
    all_values: list[TfEdgeValues] = []
    for source in plan.sources:
        edges = [edge for edge in plan.temporal_edges if edge.source == source.name and edge.tf_topic is not None]
        if not edges or not isinstance(source, McapSourcePlan):
            continue
        for topic in dict.fromkeys(edge.tf_topic or "/tf" for edge in edges):
            values = [TfEdgeValues(edge) for edge in edges if (edge.tf_topic or "/tf") == topic]
            messages = tf_messages(source.path, topic, source.where, str(source.path))
            streams.append(messages.flat_map(partial(_edge_chunks, source, values)))
            all_values += values
    return streams, all_values
