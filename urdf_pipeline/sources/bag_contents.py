"""What a ROS 2 bag (MCAP) says of itself: its robot description (`std_msgs/msg/String` on /robot_description) and
its static transforms (`tf2_msgs/msg/TFMessage` on /tf_static), so a bag is self-contained.

Both are read at compile, so `validate` refuses what `run` would: the summary here (topic, schema, the size of the
chunks holding the topic), the messages by Rerun's MCAP reader in a bounded child (`mcap_probe.in_child`), so that a
corrupt file or a decompression bomb cannot hang this process or take its memory.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pyarrow as pa

from ..errors import UserError, Where, listing, shown
from .mcap_chunks import McapRefused, read_summary
from .mcap_probe import child_main, in_child, message_rows, summary_info, topic_entity, topic_messages

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

STRING = "std_msgs/msg/String"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
DESCRIPTION_CAP = 16 * 2**20  # bytes of a robot description; real URDFs are at most a few MB
TF_STATIC_CAP = 64 * 2**20  # bytes of the chunks holding a /tf_static topic
MAX_FRAMES = 10_000  # distinct child frames a /tf_static topic may hold
MAX_FRAME_NAME = 512  # characters of one frame name
MAX_TF_ROWS = 100_000  # transforms of a /tf topic read at compile for its frames
TF_COMPONENT = "tf2_msgs.msg.TFMessage:message"
CHILD_MODULE = "urdf_pipeline.sources.bag_contents"  # run as the child that decodes the topic


@dataclass(frozen=True)
class BagTransform:
    """The last transform a bag's static topic gives for one child frame."""

    parent: str
    child: str
    translation: tuple[float, float, float]
    quaternion_xyzw: tuple[float, float, float, float]


def robot_description(path: Path, topic: str, where: Where) -> str:
    """The text of the topic's last `std_msgs/msg/String` message (a latched description is published once)."""
    _checked_channels(path, topic, STRING, DESCRIPTION_CAP, where)
    result = in_child(path, topic, "text", where, module=CHILD_MODULE)
    if "too_long" in result:
        raise UserError(
            f"the robot description on '{shown(topic)}' of {path.name} is {result['too_long']:,} bytes, over the cap of "
            f"{DESCRIPTION_CAP:,}; give the URDF as a file instead",
            where,
        )
    if result.get("text") is None:
        raise UserError(f"topic '{shown(topic)}' of {path.name} has no message Rerun's MCAP reader can decode", where)
    return str(result["text"])


def static_transforms(path: Path, topic: str, where: Where) -> dict[str, BagTransform]:
    """Every child frame of the topic's `tf2_msgs/msg/TFMessage`s, with its last transform (as tf2 keeps it)."""
    _checked_channels(path, topic, TF_MESSAGE, TF_STATIC_CAP, where)
    result = in_child(path, topic, "tf", where, module=CHILD_MODULE)
    if "too_many" in result:
        raise UserError(
            f"topic '{shown(topic)}' of {path.name} holds over {MAX_FRAMES:,} child frames; is it a static transform topic?", where
        )
    return {
        child: BagTransform(parent, child, tuple(translation), tuple(quaternion))
        for child, (parent, translation, quaternion) in result.get("transforms", {}).items()
    }


def tf_pairs(path: Path, topic: str, where: Where) -> tuple[dict[str, list[str]], bool]:
    """Each child frame of a /tf topic's first MAX_TF_ROWS transforms, with its parents, and whether that was the
    whole topic: a compile-time look, bounded whatever the bag's length."""
    _checked_channels(path, topic, TF_MESSAGE, None, where)
    result = in_child(path, topic, "pairs", where, module=CHILD_MODULE)
    return dict(result.get("pairs", {})), bool(result.get("complete"))


def tf_messages(path: Path, topic: str, where: Where, shown_as: str) -> LazyChunkStream:
    """The topic's TFMessages, one struct per row, after the whole topic decoded cleanly in a child (as a joint-state
    topic is before `run` reads it)."""
    in_child(path, topic, "all", where, shown_as)
    return topic_messages(path, topic, TF_COMPONENT)


def _checked_channels(path: Path, topic: str, schema: str, cap: int | None, where: Where) -> None:
    """From the summary: the topic exists, carries `schema` in CDR, holds messages, and the chunks that hold it are
    within `cap` bytes uncompressed (so no message beyond the cap is ever decoded; each chunk's size is checked on
    the bytes it inflates to, before the child reads it)."""
    info = summary_info(path, where)
    entity = topic_entity(topic)
    channels = [c for c in info.channels if topic_entity(c.topic) == entity]
    if not channels:
        same = sorted({c.topic for c in info.channels if c.schema is not None and c.schema.name == schema})
        raise UserError(
            f"topic '{shown(topic)}' not in {path.name}; its {schema} topics: {listing([shown(t) for t in same], empty='none')}", where
        )
    for channel in channels:
        found = channel.schema.name if channel.schema is not None else "no schema"
        if found != schema or channel.message_encoding != "cdr":
            raise UserError(
                f"topic '{shown(channel.topic)}' of {path.name} carries {shown(found)} ({shown(channel.message_encoding)}), "
                f"not ROS 2 {schema} (cdr)",
                where,
            )
    if all(c.message_count is not None for c in channels) and sum(c.message_count or 0 for c in channels) == 0:
        raise UserError(f"topic '{shown(topic)}' of {path.name} has no messages", where)
    size = _topic_bytes(path, {c.id for c in channels}) if cap is not None else 0
    if cap is not None and size > cap:
        raise UserError(
            f"topic '{shown(topic)}' of {path.name} is held in {size:,} bytes of chunks, over the cap of {cap:,} for it; "
            "is it the right topic?",
            where,
        )


def _topic_bytes(path: Path, channel_ids: set[int]) -> int:
    """The uncompressed size of the chunks holding these channels (the summary's chunk index, read by `summary_info`
    already), else the file's size."""
    try:
        with path.open("rb") as stream:
            summary = read_summary(stream)
    except (McapRefused, OSError):  # summary_info said so already; bound by the file itself
        summary = None
    if summary is None or not summary.chunk_indexes:
        return path.stat().st_size
    return sum(c.uncompressed_size for c in summary.chunk_indexes if channel_ids & set(c.message_index_offsets))


# --- in the child process (`python -m urdf_pipeline.sources.bag_contents PATH TOPIC MODE`) -------------------------------------------------------------------


def child_read(path: Path, topic: str, mode: str) -> dict[str, Any]:
    """`text`: the last String's data (its size only, beyond the cap); `tf`: the last transform per child frame."""
    if mode == "text":
        return _last_text(path, topic)
    if mode == "pairs":
        return _pairs(path, topic)
    return _transforms(path, topic)


def _last_text(path: Path, topic: str) -> dict[str, Any]:
    import pyarrow.compute as pc

    text: str | None = None
    for messages in message_rows(path, topic, "std_msgs.msg.String:message"):
        if len(messages):
            text = pc.struct_field(messages, "data")[-1].as_py()
    if text is not None and len(text.encode("utf-8")) > DESCRIPTION_CAP:
        return {"too_long": len(text.encode("utf-8"))}
    return {"text": text}


def _transforms(path: Path, topic: str) -> dict[str, Any]:
    """Last wins per child frame, in the bag's order; frame names cut to MAX_FRAME_NAME characters."""
    import pyarrow.compute as pc

    found: dict[str, tuple[str, list[float], list[float]]] = {}
    for messages in message_rows(path, topic, TF_COMPONENT):
        transforms = pc.list_flatten(pc.struct_field(messages, "transforms"))
        if not len(transforms):
            continue
        parents = pc.struct_field(transforms, [0, 1]).to_pylist()  # header.frame_id
        children = pc.struct_field(transforms, "child_frame_id").to_pylist()
        moved = pc.struct_field(transforms, "transform")
        xyz = [pc.struct_field(moved, [0, i]).to_pylist() for i in range(3)]
        xyzw = [pc.struct_field(moved, [1, i]).to_pylist() for i in range(4)]
        for row, child in enumerate(children):  # a static topic: metadata-sized, bounded by MAX_FRAMES
            found[child[:MAX_FRAME_NAME]] = (parents[row][:MAX_FRAME_NAME], [v[row] for v in xyz], [v[row] for v in xyzw])
            if len(found) > MAX_FRAMES:
                return {"too_many": True}
    return {"transforms": found}


def _pairs(path: Path, topic: str) -> dict[str, Any]:
    """child -> its parents over the first MAX_TF_ROWS transforms (names cut to MAX_FRAME_NAME), and whether that was all."""
    import pyarrow.compute as pc

    pairs: dict[str, list[str]] = {}
    rows = 0
    for messages in message_rows(path, topic, TF_COMPONENT):
        transforms = pc.list_flatten(pc.struct_field(messages, "transforms"))
        rows += len(transforms)
        table = pa.table({"child": pc.struct_field(transforms, "child_frame_id"), "parent": pc.struct_field(transforms, [0, 1])})
        for pair in table.group_by(["child", "parent"]).aggregate([]).to_pylist():  # distinct pairs only
            parents = pairs.setdefault(pair["child"][:MAX_FRAME_NAME], [])
            if pair["parent"][:MAX_FRAME_NAME] not in parents:
                parents.append(pair["parent"][:MAX_FRAME_NAME])
        if rows >= MAX_TF_ROWS or len(pairs) > MAX_FRAMES:
            return {"pairs": pairs, "complete": False}
    return {"pairs": pairs, "complete": True}


if __name__ == "__main__":
    child_main(child_read)
