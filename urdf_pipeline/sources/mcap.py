"""ROS 2 sensor_msgs/msg/JointState messages of one MCAP topic, decoded by Rerun's McapReader (ros2_reflection).

Every message carries its own names, in an order that may change from message to message: values are mapped by name,
row by row (named_rows.py). Validation reads the file's summary only, and the topic's first message when the config
gives no `names`; of a remote file, by ranged GETs (mcap_remote.py).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from ..config import Document
from ..errors import UserError, Where, listing, shown
from ..plan import McapSourcePlan
from ..remote import is_remote
from .base import EntryField, SourceDescription, file_input, resolve_input, shown_file
from .mcap_chunks import McapRefused, refusal
from .mcap_probe import MESSAGE_COMPONENT, probe, summary_info, topic_entity, topic_messages
from .mcap_remote import late_messages, remote_mcap
from .named_rows import NAME_FIELD, NAMED_COMPONENT, VALUE_FIELD, named_rows_column
from .ordering import in_time_order, with_duplicates
from .stream import SourceStream, component_field
from .time_range import INT64_MAX

if TYPE_CHECKING:
    from rerun.chunk import Chunk

PLAN_TYPE = McapSourcePlan
SPEC_FORM = "mcap:FILE[#TOPIC]"
SUFFIXES = (".mcap",)
JOINT_STATE = "sensor_msgs/msg/JointState"
MCAP_TIMELINES = {"header": "ros2_timestamp", "log_time": "message_log_time", "publish_time": "message_publish_time"}
ALL_TIMELINES = tuple(MCAP_TIMELINES.values())


def checked_first_names(names: tuple[str, ...] | None, topic: str, file: str, where: Where | None) -> tuple[str, ...]:
    """The first message's names (of a bag's topic, or of a live stream's): there is one, it names joints, each once.
    `file` names where the topic is, for the message without any."""
    if names is None:
        raise UserError(f"topic '{shown(topic)}' of {file} has no messages Rerun's MCAP reader can decode; a source with zero rows", where)
    if not names:
        raise UserError(f"the first message on '{shown(topic)}' names no joints; give the names with names: [...]", where)
    if len(set(names)) != len(names):
        raise UserError(f"the first message on '{shown(topic)}' names a joint twice: {', '.join(map(shown, names))}", where)
    return names


def _check_log_times(late: Callable[[str, int], int], file_name: str, topic: str, info: Any, where: Where) -> None:
    """MCAP log times are uint64 nanoseconds; a timeline holds at most 2^63 - 1 (Rerun clamps what is beyond, so the
    late messages would all sit at one time in 2262). Refused from the summary's last log time; the row (in log-time
    order) is counted from the late chunks alone (`late(topic, start)`, the mcap library), when the file allows it."""
    end = info.message_end_time_ns
    if end is None or end <= INT64_MAX:
        return
    row = ""
    try:
        beyond = late(topic, INT64_MAX + 1)  # the messages at or after 2^63 only: a few late chunks
        total = sum(c.message_count or 0 for c in info.channels if topic_entity(c.topic) == topic_entity(topic))
        if not beyond:
            return  # another topic's messages are the late ones
        row = f" at row {total - beyond} (counting from 0, in log-time order) and after"
    except UserError:
        raise  # a chunk refused on the way (mcap_chunks): that is the file's first fault
    except Exception:  # the mcap library's errors on a damaged file: the summary's value is refused anyway
        pass
    raise UserError(
        f"messages of {file_name} are logged at up to {end} ns{row}: beyond a timeline's range ({INT64_MAX} ns, in 2262); "
        "MCAP log times are uint64, a timeline's int64. Fix the recorder's clock, or use timeline: header",
        where,
    )


def _local_late(path: Path, where: Where) -> Callable[[str, int], int]:
    def late(topic: str, start: int) -> int:
        try:
            with path.open("rb") as stream:
                return late_messages(stream, topic, start)
        except McapRefused as error:
            raise refusal(str(path), error, where) from None

    return late


def _joint_state_topics(channels: Sequence[Any]) -> list[str]:
    return sorted({c.topic for c in channels if c.schema is not None and c.schema.name == JOINT_STATE})


def _checked_topic(spec: dict[str, Any], info: Any, shown: str, document: Document, here: tuple[str, str]) -> list[Any]:
    """The topic's channels, from the summary: they exist, carry ROS 2 JointState (cdr), and hold messages. `shown`
    names the file: its path, or its URL."""
    file_name = shown.rsplit("/", 1)[-1]
    all_channels = list(info.channels)
    topic = topic_entity(spec["topic"])
    channels = [c for c in all_channels if topic_entity(c.topic) == topic]
    if not channels:
        joint_topics = _joint_state_topics(all_channels)
        listed = (
            ", ".join(joint_topics) if joint_topics else f"none (topics: {', '.join(sorted({c.topic for c in all_channels})) or 'none'})"
        )
        raise UserError(f"topic '{spec['topic']}' not in {file_name}; its {JOINT_STATE} topics: {listed}", document.where(*here, "topic"))
    for channel in channels:
        schema = channel.schema.name if channel.schema is not None else "no schema"
        if schema != JOINT_STATE or channel.message_encoding != "cdr":
            raise UserError(
                f"topic '{channel.topic}' carries {schema} ({channel.message_encoding}), not ROS 2 {JOINT_STATE} (cdr)",
                document.where(*here, "topic"),
            )
    counts = [channel.message_count for channel in channels]
    if all(count is not None for count in counts) and sum(counts) == 0:
        raise UserError(f"topic '{spec['topic']}' has no messages in {shown}; a source with zero rows", document.where(*here, "topic"))
    return channels


def compile_source(name: str, spec: dict[str, Any], document: Document, config_dir: Path) -> McapSourcePlan:
    here = ("sources", name)
    if is_remote(spec["mcap"]):
        return _compile_remote(name, spec, document)
    path = resolve_input(document, config_dir, spec["mcap"], *here, "mcap")
    topic_at = document.where(*here, "topic")  # in a child: a corrupt file cannot hang this process

    def first_names(channels: list[Any]) -> tuple[str, ...] | None:
        return probe(path, topic_entity(spec["topic"]), first_only=True, where=topic_at)

    info = summary_info(path, document.where(*here, "mcap"))
    return _plan(name, spec, document, info, str(path), path, _local_late(path, document.where(*here, "mcap")), first_names)


def _compile_remote(name: str, spec: dict[str, Any], document: Document) -> McapSourcePlan:
    """`mcap: s3://BUCKET/KEY`: the summary and (without `names`) the topic's first message, by ranged GETs
    (mcap_remote.py); the file is downloaded by `run`, whose stream probes the whole topic first, as for a local file."""
    from ..remote import cached_path, remote_file

    remote = remote_file(spec["mcap"], document.where("sources", name, "mcap"), "mcap file")
    with remote_mcap(remote, document.where("sources", name, "mcap")) as file:

        def first_names(channels: list[Any]) -> tuple[str, ...] | None:
            return file.first_names(sorted({c.topic for c in channels}))

        plan = _plan(name, spec, document, file.info(), remote.url, cached_path(remote), file.late_messages, first_names)
    return replace(plan, remote=remote)


def _plan(
    name: str,
    spec: dict[str, Any],
    document: Document,
    info: Any,
    shown: str,
    path: Path,
    late: Callable[[str, int], int],
    first_names: Callable[[list[Any]], tuple[str, ...] | None],
) -> McapSourcePlan:
    """The plan from the file's summary (`info`), `late` counting late messages, `first_names` reading the first
    message's names of the topic's channels (a local file's or a remote one's ways); `shown` names the file."""
    here = ("sources", name)
    channels = _checked_topic(spec, info, shown, document, here)
    topic = topic_entity(spec["topic"])
    timeline = MCAP_TIMELINES[spec.get("timeline", "header")]
    if timeline == MCAP_TIMELINES["log_time"]:
        _check_log_times(late, shown.rsplit("/", 1)[-1], topic, info, document.where(*here, "timeline"))
    if "names" in spec:
        names = tuple(spec["names"])
    else:
        names = checked_first_names(first_names(channels), topic, shown, document.where(*here, "topic"))
    return with_duplicates(McapSourcePlan(name, path, topic, timeline, names, document.where(*here)), spec)


def check_download(plan: McapSourcePlan) -> None:
    """Nothing more once `run` has downloaded a remote MCAP file: its stream probes the whole topic in a child
    process before Rerun's reader reads it here (`open_stream`), as for a local file."""


def describe(name: str, path: str, part: str | None, document: Document) -> SourceDescription:
    """For `init`: the topic (PART, else the file's only JointState topic) and the names of its first message, as
    `validate` reads them. Names come in any order per message: the map follows the URDF's joint order."""
    given = file_input(path)
    file = given.file
    topic = part
    if topic is None:
        topics = _joint_state_topics(summary_info(file, None).channels)
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
    stamps = batch.column(batch.schema.get_field_index(plan.timeline)).cast(pa.int64()).to_numpy(zero_copy_only=False)
    if plan.timeline != "ros2_timestamp":  # uint64 log or publish times: Rerun clamps those beyond int64 to its largest
        clamped = stamps == INT64_MAX
        if clamped.any():
            raise UserError(
                f"{int(np.count_nonzero(clamped))} messages on '{plan.topic}' have a {plan.timeline} at or beyond 2^63 ns, beyond a "
                f"timeline's range ({INT64_MAX} ns, in 2262): MCAP times are uint64, a timeline's int64. Fix the recorder's clock, or use "
                "timeline: header",
                plan.where,
            )
    else:
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
    batch = batch.set_column(index, component_field(NAMED_COMPONENT, column.type), column)
    batch = batch.drop_columns([name for name in ALL_TIMELINES if name != plan.timeline and name in batch.schema.names])
    return Chunk.from_record_batch(batch)


def open_stream(plan: McapSourcePlan) -> SourceStream:
    # the whole topic, in a child, before Rerun reads it here
    probe(plan.path, plan.topic, first_only=False, where=plan.where, shown_as=shown_file(plan))
    stream = in_time_order(
        topic_messages(plan.path, plan.topic).flat_map(partial(_named_rows, plan)), plan.timeline, plan, shown_file(plan)
    )
    return SourceStream(stream, plan.topic, NAMED_COMPONENT, len(plan.names), named=True)
