"""An MCAP topic is first read in a child process, which is killed at Rerun's first read error or past a time limit.

Rerun's MCAP reader (native code) logs "Failed to read message from MCAP file" for a chunk that does not decompress
and then spins at 100% CPU forever, deaf to Ctrl-C; for a chunk whose CRC fails it logs the same line and decodes
garbage. The file's summary does not show either. So the child decodes the topic exactly as a run does, the parent
watches the child's log and stops it at the first such line (or after BASE_SECONDS plus SECONDS_PER_BYTE per byte),
and only a file the child read cleanly reaches Rerun in this process. Run as a module, this file is the child.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..errors import UserError, Where

if TYPE_CHECKING:
    from rerun.chunk import LazyChunkStream

BASE_SECONDS = 60.0
SECONDS_PER_BYTE = 1 / 10e6  # 10 MB/s: far below Rerun's decoding speed, so a slow machine is not mistaken for a loop
ANSI = re.compile(r"\x1b\[[0-9;]*m")
READ_ERROR = re.compile(r"\bERROR\b.*\b(re_mcap|mcap)\b", re.IGNORECASE)


MESSAGE_COMPONENT = "sensor_msgs.msg.JointState:message"  # what the ros2_reflection decoder emits per message


def topic_entity(topic: str) -> str:
    return topic if topic.startswith("/") else f"/{topic}"


def topic_messages(path: Path, topic: str, component: str = MESSAGE_COMPONENT) -> LazyChunkStream:
    """The topic's messages, one struct per row; nothing else of the file is decoded."""
    from rerun.chunk import McapReader

    entity = topic_entity(topic)
    reader = McapReader(path, decoders=["ros2_reflection"], include_topic_regex=[f"^{re.escape(entity)}$"])
    return reader.stream().filter(content=entity, is_static=False, components=component)


def _watch(stream: object, errors: list[str], others: list[str], failed: threading.Event) -> None:
    for raw in stream:  # type: ignore[attr-defined]
        line = ANSI.sub("", raw.decode("utf-8", errors="replace")).strip()
        if READ_ERROR.search(line):
            errors.append(line.split(":", 3)[-1].strip() if "Failed" not in line else line[line.index("Failed") :])
            failed.set()
        elif line:
            others.append(line)


def probe(path: Path, topic: str, first_only: bool, where: Where | None, shown: str | None = None) -> tuple[str, ...] | None:
    """Read `topic` in a child: the first message's names (`first_only`), else None once every message decoded.
    `shown` names the file in messages (a remote file's URL; its path by default)."""
    names = in_child(path, topic, "first" if first_only else "all", where, shown).get("names")
    return tuple(names) if names is not None else None


def in_child(
    path: Path, topic: str, mode: str, where: Where | None, shown: str | None = None, module: str = "urdf_pipeline.sources.mcap_probe"
) -> dict[str, Any]:
    """Read `topic` in a child process (`python -m MODULE PATH TOPIC MODE`) and return the JSON it printed: this
    module's modes are "first" and "all" (JointState names); `bag_contents` has its own."""
    shown = shown or str(path)
    budget = BASE_SECONDS + path.stat().st_size * SECONDS_PER_BYTE
    command = [sys.executable, "-m", module, str(path), topic, mode]
    env = {**os.environ, "RUST_LOG": "warn"}  # the read errors are what the parent watches for
    child = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    errors: list[str] = []
    others: list[str] = []
    failed = threading.Event()
    watcher = threading.Thread(target=_watch, args=(child.stderr, errors, others, failed), daemon=True)
    watcher.start()
    deadline = time.monotonic() + budget
    timed_out = False
    try:
        while child.poll() is None and not failed.wait(0.05):
            if time.monotonic() > deadline:
                timed_out = True
                break
    finally:
        if child.poll() is None:
            child.kill()
        child.wait()
        watcher.join(timeout=5)
    output = child.stdout.read().decode("utf-8", errors="replace") if child.stdout else ""
    if child.stdout:
        child.stdout.close()
    if errors:
        raise UserError(f"MCAP file {shown} is corrupt: {errors[0]} (reading topic '{topic}'); repair or re-record the file", where)
    if timed_out:
        raise UserError(
            f"reading topic '{topic}' of MCAP file {shown} did not finish within {budget:.0f} s; the file is probably corrupt", where
        )
    if child.returncode != 0:
        reason = others[-1] if others else f"exit status {child.returncode}"
        raise UserError(f"cannot read MCAP file {shown} (topic '{topic}'): {reason}", where)
    result: dict[str, Any] = json.loads(output.strip().splitlines()[-1]) if output.strip() else {}
    return result


def _child(path: str, topic: str, mode: str) -> None:
    import pyarrow.compute as pc

    from .named_rows import NAME_FIELD

    names: list[str] | None = None
    for chunk in topic_messages(Path(path), topic):
        batch = chunk.to_record_batch()
        rows = batch.column(batch.schema.get_field_index(MESSAGE_COMPONENT)).flatten()
        if len(rows) and names is None:
            names = [str(n) for n in (pc.struct_field(rows, NAME_FIELD)[0].as_py() or [])]
            if mode == "first":
                break
    print(json.dumps({"names": names}))


if __name__ == "__main__":
    _child(*sys.argv[1:4])
