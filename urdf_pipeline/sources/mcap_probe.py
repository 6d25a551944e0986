"""An MCAP topic is first read in a child process, bounded in memory, CPU and wall-clock time (security.md#mcap-files),
and killed at Rerun's first read error.

Rerun's MCAP reader (native code) logs "Failed to read message from MCAP file" for a chunk that does not decompress
and then spins at 100% CPU forever, deaf to Ctrl-C; for a chunk whose CRC fails it logs the same line and decodes
garbage. The file's summary does not show either. So every chunk is first inflated here within its bounds
(`mcap_chunks.check_chunks`), then a child decodes the topic exactly as a run does, the parent stops it at the first
such line, and only a file the child read cleanly reaches Rerun in this process. Run as a module, this file is the child.
"""

from __future__ import annotations

import json
import os
import re
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import UserError, Where, shown
from ..process import bound_from_environment, limit_this_process, run_bounded_child
from .mcap_chunks import McapRefused, check_chunks, read_summary, refusal, require_library

if TYPE_CHECKING:
    import pyarrow as pa
    from rerun.chunk import LazyChunkStream

BASE_SECONDS = 60.0
SECONDS_PER_BYTE = 1 / 10e6  # 10 MB/s: far below Rerun's decoding speed, so a slow machine is not mistaken for a loop
READ_ERROR = re.compile(r"\bERROR\b.*\b(re_mcap|mcap)\b", re.IGNORECASE)
MEMORY_ENV = "URDF_PIPELINE_MCAP_MEMORY_MB"  # the runner may change the child's bounds for a huge bag; a config cannot
TIMEOUT_ENV = "URDF_PIPELINE_MCAP_TIMEOUT"
DEFAULT_MEMORY_MB = 1024  # address space, as xacro's: Rerun's reader needs about 600 MB of it with CHILD_ENVIRONMENT
OUTPUT_BYTES = 256 << 20  # of the child's answer, and of any file it writes: it writes none
CHILD_ENVIRONMENT = {
    "RUST_LOG": "warn",  # the read errors are what the parent watches for
    "MIMALLOC_ARENA_RESERVE": "64MiB",  # Rerun's allocator reserves 1 GiB of address space up front by default
    "MALLOC_ARENA_MAX": "2",  # each thread's malloc arena reserves 64 MB of it
    "TOKIO_WORKER_THREADS": "2",  # one runtime thread per core otherwise: address space that grows with the machine
    "OPENBLAS_NUM_THREADS": "1",
}


MESSAGE_COMPONENT = "sensor_msgs.msg.JointState:message"  # what the ros2_reflection decoder emits per message


def topic_entity(topic: str) -> str:
    return topic if topic.startswith("/") else f"/{topic}"


def summary_info(path: Path, where: Where | None, name: str | None = None) -> Any:
    """Rerun's view of the file's summary (its channels and statistics), once the summary section has been read here
    and holds no chunk (Rerun's reader would spin on one for minutes). `name` names the file in messages."""
    from rerun.chunk import McapReader

    name = name or str(path)
    require_library(where)
    try:
        with path.open("rb") as stream:
            read_summary(stream)
    except McapRefused as error:
        raise refusal(name, error, where) from None
    except OSError as exc:
        raise UserError(f"cannot read MCAP file {shown(name)}: {shown(exc.strerror or exc)}", where) from None
    try:
        return McapReader(path).info()
    except (ValueError, OSError, RuntimeError) as exc:
        raise UserError(f"cannot read MCAP file {shown(name)}: {shown(str(exc))}", where) from None


def topic_messages(path: Path, topic: str, component: str = MESSAGE_COMPONENT) -> LazyChunkStream:
    """The topic's messages, one struct per row; nothing else of the file is decoded."""
    from rerun.chunk import McapReader

    entity = topic_entity(topic)
    reader = McapReader(path, decoders=["ros2_reflection"], include_topic_regex=[f"^{re.escape(entity)}$"])
    return reader.stream().filter(content=entity, is_static=False, components=component)


def message_rows(path: Path, topic: str, component: str = MESSAGE_COMPONENT) -> Iterator[pa.Array]:
    """The topic's messages as struct arrays, a chunk's at a time (in the child)."""
    for chunk in topic_messages(path, topic, component):
        batch = chunk.to_record_batch()
        yield batch.column(batch.schema.get_field_index(component)).flatten()


def probe(path: Path, topic: str, first_only: bool, where: Where | None, shown_as: str | None = None) -> tuple[str, ...] | None:
    """Read `topic` in a child: the first message's names (`first_only`), else None once every message decoded.
    `shown_as` names the file in messages (a remote file's URL; its path by default)."""
    names = in_child(path, topic, "first" if first_only else "all", where, shown_as).get("names")
    return tuple(names) if names is not None else None


def in_child(
    path: Path, topic: str, mode: str, where: Where | None, shown_as: str | None = None, module: str = "urdf_pipeline.sources.mcap_probe"
) -> dict[str, Any]:
    """Read `topic` in a child process (`python -m MODULE PATH TOPIC MODE LIMITS`, which calls `child_main`) and return
    the JSON it printed: this module's modes are "first" and "all" (JointState names); `bag_contents` has its own. Every
    chunk of the file is inflated here first, within its bounds (`check_chunks`)."""
    name = shown_as or str(path)
    require_library(where)
    try:
        check_chunks(path)
    except McapRefused as error:
        raise refusal(name, error, where) from None
    memory_mb = int(bound_from_environment(MEMORY_ENV, DEFAULT_MEMORY_MB, where))  # the child's address space and seconds
    budget = bound_from_environment(TIMEOUT_ENV, BASE_SECONDS + path.stat().st_size * SECONDS_PER_BYTE, where)
    limits = {"memory_bytes": memory_mb << 20, "cpu_seconds": int(budget) + 1, "output_bytes": OUTPUT_BYTES}
    command = [sys.executable, "-m", module, str(path), topic, mode, json.dumps(limits)]
    outcome = run_bounded_child(
        command, None, timeout_s=budget, env={**os.environ, **CHILD_ENVIRONMENT}, answer_bytes=OUTPUT_BYTES, stop_on=READ_ERROR
    )
    if outcome.answer is not None:
        return outcome.answer
    line, cannot = outcome.stopped_by or "", f"cannot read MCAP file {shown(name)} (topic '{shown(topic)}')"
    cause = line.split(":", 3)[-1].strip() if "Failed" not in line else line[line.index("Failed") :]
    reading, raise_it = f"reading topic '{shown(topic)}' of MCAP file {shown(name)}", "the person running the tool can raise the bound with"
    slow = f"{reading} did not finish within {budget:.4g} s and was stopped; the file is probably corrupt ({raise_it} {TIMEOUT_ENV})"
    messages = {
        "stopped": f"MCAP file {shown(name)} is corrupt: {shown(cause)} (reading topic '{shown(topic)}'); repair or re-record the file",
        "time": slow,
        "cpu": slow,
        "memory": f"{reading} needs more than {memory_mb} MB of memory and was stopped ({raise_it} {MEMORY_ENV})",
        "failed": f"{cannot}: {shown(outcome.last or outcome.status)}",
    }  # else an answer over OUTPUT_BYTES, or no answer at all
    raise UserError(messages.get(outcome.kind, f"{cannot}: its reader gave no readable answer"), where)


def child_main(read: Callable[[Path, str, str], dict[str, Any]]) -> None:
    """The child: bound this process (`limit_this_process`; Rerun's reader runs threads of its own), then print what
    `read(PATH, TOPIC, MODE)` answers, as one JSON line."""
    path, topic, mode, limits = sys.argv[1:5]
    limit_this_process(json.loads(limits), threads=True)
    print(json.dumps(read(Path(path), topic, mode)))


def _names(path: Path, topic: str, mode: str) -> dict[str, Any]:
    """The first message's names (`first`), after every message decoded (`all`)."""
    import pyarrow.compute as pc

    from .named_rows import NAME_FIELD

    names: list[str] | None = None
    for rows in message_rows(path, topic):
        if len(rows) and names is None:
            names = [str(n) for n in (pc.struct_field(rows, NAME_FIELD)[0].as_py() or [])]
            if mode == "first":
                break
    return {"names": names}


if __name__ == "__main__":
    child_main(_names)
