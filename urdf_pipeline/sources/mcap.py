"""ROS 2 sensor_msgs/msg/JointState messages of one MCAP topic, decoded by Rerun's McapReader (ros2_reflection).

Every message carries its own names, in an order that may change from message to message: values are mapped by
name, row by row (`urdf_pipeline.sources.named_rows`), never by position. Validation reads the file's summary only (topic,
schema, message count); when the config gives no `names`, the first message of the topic is read for them.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..config import Document
from ..errors import UserError, Where, listing
from ..plan import McapSourcePlan
from .base import EntryField, SourceDescription, file_input, resolve_input
from .mcap_probe import MESSAGE_COMPONENT, probe, topic_entity, topic_messages
from .named_rows import NAME_FIELD, NAMED_COMPONENT, VALUE_FIELD, named_rows_column
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream

if TYPE_CHECKING:
    from rerun.chunk import Chunk, McapChannelInfo

PLAN_TYPE = McapSourcePlan
SPEC_FORM = "mcap:FILE[#TOPIC]"
SUFFIXES = (".mcap",)
JOINT_STATE = "sensor_msgs/msg/JointState"
TIMELINES = {"header": "ros2_timestamp", "log_time": "message_log_time", "publish_time": "message_publish_time"}
ALL_TIMELINES = tuple(TIMELINES.values())


def _first_message_names(path: Path, topic: str, where: Where) -> tuple[str, ...]:
    names = probe(path, topic, first_only=True, where=where)  # in a child: a corrupt file cannot hang this process
    if names is None:
        raise UserError(f"topic '{topic}' of {path} has no messages Rerun's MCAP reader can decode; a source with zero rows", where)
    if not names:
        raise UserError(f"the first message on '{topic}' names no joints; give the names with names: [...]", where)
    if len(set(names)) != len(names):
        raise UserError(f"the first message on '{topic}' names a joint twice: {', '.join(names)}", where)
    return names


def _channels(path: Path, where: Where | None) -> list[McapChannelInfo]:
    """The file's channels, from its summary."""
    from rerun.chunk import McapReader

    try:
        return list(McapReader(path).info().channels)
    except (ValueError, OSError, RuntimeError) as exc:
        raise UserError(f"cannot read MCAP file {path}: {exc}", where) from None


def _joint_state_topics(channels: list[McapChannelInfo]) -> list[str]:
    return sorted({c.topic for c in channels if c.schema is not None and c.schema.name == JOINT_STATE})


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> McapSourcePlan:
    here = ("sources", name)
    path = resolve_input(document, config_dir, spec["mcap"], *here, "mcap")
    all_channels = _channels(path, document.where(*here, "mcap"))
    topic = topic_entity(spec["topic"])
    channels = [c for c in all_channels if topic_entity(c.topic) == topic]
    if not channels:
        joint_topics = _joint_state_topics(all_channels)
        listed = (
            ", ".join(joint_topics) if joint_topics else f"none (topics: {', '.join(sorted({c.topic for c in all_channels})) or 'none'})"
        )
        raise UserError(f"topic '{spec['topic']}' not in {path.name}; its {JOINT_STATE} topics: {listed}", document.where(*here, "topic"))
    for channel in channels:
        schema = channel.schema.name if channel.schema is not None else "no schema"
        if schema != JOINT_STATE or channel.message_encoding != "cdr":
            raise UserError(
                f"topic '{channel.topic}' carries {schema} ({channel.message_encoding}), not ROS 2 {JOINT_STATE} (cdr)",
                document.where(*here, "topic"),
            )
    counts = [channel.message_count for channel in channels]
    if all(count is not None for count in counts) and sum(counts) == 0:  # type: ignore[arg-type]
        raise UserError(f"topic '{spec['topic']}' has no messages in {path}; a source with zero rows", document.where(*here, "topic"))
    timeline = TIMELINES[spec.get("timeline", "header")]
    names = tuple(spec["names"]) if "names" in spec else _first_message_names(path, topic, document.where(*here, "topic"))
    return with_duplicates(McapSourcePlan(name, path, topic, timeline, names, document.where(*here)), spec)


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the topic (PART, else the file's only JointState topic) and the names of its first message, as
    `validate` reads them. Names come in any order per message: the map follows the URDF's joint order."""
    given = file_input(path)
    file = given.file
    topic = part
    if topic is None:
        topics = _joint_state_topics(_channels(file, None))
        if len(topics) != 1:
            raise UserError(f"name the topic with mcap:FILE#TOPIC; its {JOINT_STATE} topics: {listing(topics, empty='none')}")
        topic = topics[0]
    plan = compile_source(name, {"mcap": str(file), "topic": topic}, document, file.parent)
    note = "names: read from the topic's first message by validate (every name must be mapped or ignored)"
    fields = (EntryField("topic", topic),)
    return SourceDescription("mcap", fields, plan.names, None, given.segment, pattern=given.pattern, urdf_order=True, notes=(note,))


def _named_rows(plan: McapSourcePlan, chunk: Chunk) -> list[Chunk]:
    """Keep the plan's timeline only and repack each message as {name, position}; refuse unset header stamps."""
    from rerun.chunk import Chunk

    batch = chunk.to_record_batch()
    index = batch.schema.get_field_index(MESSAGE_COMPONENT)
    if index < 0 or not batch.num_rows:
        return []
    if plan.timeline not in batch.schema.names:
        raise UserError(f"messages on '{plan.topic}' have no {plan.timeline} timeline", plan.where)
    if plan.timeline == "ros2_timestamp":
        stamps = batch.column(batch.schema.get_field_index(plan.timeline)).cast(pa.int64()).to_numpy(zero_copy_only=False)
        zero = int(np.count_nonzero(stamps == 0))
        if zero:
            raise UserError(
                f"messages on '{plan.topic}' have a zero header stamp ({zero} of {len(stamps)} rows in one batch), so they would all "
                f"sit at time 0; set sources.{plan.name}.timeline: log_time to use the time the messages were recorded",
                plan.where,
            )
    messages = batch.column(index)
    if not pc.all(pc.equal(messages.value_lengths(), 1)).as_py():
        raise UserError(f"rows on '{plan.topic}' do not hold exactly one message each", plan.where)
    structs = messages.flatten()
    column = named_rows_column(pc.struct_field(structs, NAME_FIELD), pc.struct_field(structs, VALUE_FIELD))
    field = pa.field(NAMED_COMPONENT, column.type, metadata={b"rerun:kind": b"data", b"rerun:component": NAMED_COMPONENT.encode()})
    batch = batch.set_column(index, field, column)
    batch = batch.drop_columns([name for name in ALL_TIMELINES if name != plan.timeline and name in batch.schema.names])
    return Chunk.from_record_batch(batch)


def open_stream(plan: McapSourcePlan) -> SourceStream:
    probe(plan.path, plan.topic, first_only=False, where=plan.where)  # the whole topic, in a child, before Rerun reads it here
    stream = in_time_order(topic_messages(plan.path, plan.topic).flat_map(partial(_named_rows, plan)), plan.timeline, plan, plan.path)
    return SourceStream(stream, plan.topic, NAMED_COMPONENT, len(plan.names), named=True)
