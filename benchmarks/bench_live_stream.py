"""Part 2 of bench_live.py: `urdf-pipeline live --from ws://...` against a real Foxglove WebSocket server.

A foxglove-sdk server (tests/live_views/foxglove_server.py, a child process) publishes the G1's 29 joints as ROS 2
JointState at 100 Hz and at 1 kHz, then stops. Two clients, each a process of its own, alternated:
  live   `urdf-pipeline live g1_live.yaml --from ws://... --save out.rrd` (the whole command, interpreter start included)
  hand   the same feed (`FoxgloveFeed`, so the network path is equal), then per sample, as Rerun's animated-URDF
         example does: `rec.set_time(...)` and per joint `rec.log(entity, joint.compute_transform(q_j))`, to a file
Each is stopped with SIGTERM once the server has gone. Reported: samples sent, latency from a frame's arrival to it
being handed to Rerun (median, 99th percentile: the command's own last line; the hand-written client measures the same
with the same bins), and the client's CPU seconds.
"""

from __future__ import annotations

import json
import os
import resource
import signal
import statistics
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
RATES = {100: 1000, 1000: 10000}  # messages per second -> messages published (10 s each)


G1 = "robots/share/example-robot-data/robots/g1_description/urdf/g1_29dof_rev_1_0.urdf"


def g1_joints(urdf: Path) -> list[str]:
    import xml.etree.ElementTree as ET

    root = ET.parse(urdf).getroot()
    return [j.get("name", "") for j in root.iter("joint") if j.get("type") in ("revolute", "continuous", "prismatic")]


def _server(names: list[str], rate: int, count: int) -> tuple[subprocess.Popen[bytes], str]:
    sys.path.insert(0, str(REPO))
    from tests.local_processes import free_port

    port = free_port()
    command = [sys.executable, "-m", "tests.live_views.foxglove_server", "--port", str(port), "--rate", str(rate)]
    command += [
        "--count",
        str(count),
        "--names",
        ",".join(names),
        "--exit-when-done",
        "--range=-0.05,0.2",
    ]  # within every G1 joint's limits
    server = subprocess.Popen(command, cwd=REPO, stdout=subprocess.PIPE, env={**os.environ, "PYTHONPATH": str(REPO)})
    assert server.stdout is not None
    assert server.stdout.readline().decode().strip() == f"ready {port}"
    return server, f"ws://127.0.0.1:{port}"


def _client(variant: str, config: Path, url: str, out: Path) -> tuple[list[str], float]:
    """The client until the server has gone (its 'reconnecting' line), then SIGTERM; its stderr lines and CPU s."""
    if variant == "live":
        command = [sys.executable, "-m", "urdf_pipeline", "live", str(config), "--from", url, "--save", str(out)]
    else:
        command = [sys.executable, __file__, "--hand", str(config), url, str(out)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    child = subprocess.Popen(command, stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": str(REPO)})
    assert child.stderr is not None
    lines = []
    for line in child.stderr:
        lines.append(line)
        if "reconnecting in" in line:
            break
    child.send_signal(signal.SIGTERM)
    lines += child.stderr.read().splitlines()
    child.wait()
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return lines, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _figures(lines: list[str]) -> dict[str, float]:
    """From `live`'s last line (or the hand-written client's, in the same words)."""
    last = next((line for line in reversed(lines) if "from arrival to sent" in line), None)
    if last is None:
        raise SystemExit("the client ended without its last line:\n" + "".join(lines[-30:]))
    sent = int(last.split(" sent (")[0].rsplit(", ", 1)[1])
    median = float(last.split("median ")[1].split(" ms")[0])
    p99 = float(last.split("99th percentile ")[1].split(" ms")[0])
    return {"sent": sent, "median_ms": median, "p99_ms": p99}


def part_stream(config: Path, repeat: int, workdir: Path) -> None:

    names = g1_joints(config.parent / G1)
    print("\nlive --from ws:// (foxglove-sdk server, 29 joints), medians of", repeat)
    print(f"{'rate':>6} {'client':<6} {'sent':>6} {'median ms':>10} {'p99 ms':>8} {'CPU s':>7} {'CPU µs/sample':>14}")
    for rate, count in RATES.items():
        results: dict[str, list[dict[str, float]]] = {"live": [], "hand": []}
        for _ in range(repeat):
            for variant in results:
                server, url = _server(names, rate, count)
                try:
                    lines, cpu = _client(variant, config, url, workdir / f"stream_{variant}.rrd")
                finally:
                    server.kill()
                    server.wait()
                figures = _figures(lines)
                figures["cpu_s"] = cpu
                results[variant].append(figures)
        for variant, rows in results.items():
            med = {key: statistics.median(r[key] for r in rows) for key in rows[0]}
            per = med["cpu_s"] / max(med["sent"], 1) * 1e6
            print(
                f"{rate:>5}Hz {variant:<6} {med['sent']:>6.0f} {med['median_ms']:>10.2f} {med['p99_ms']:>8.2f} "
                f"{med['cpu_s']:>7.2f} {per:>14.0f}"
            )


def hand_written(config: Path, url: str, out: Path) -> None:
    """The hand-written client: the same feed, then Rerun's animated-URDF way per sample."""
    import numpy as np
    import rerun as rr
    from rerun.urdf import UrdfTree

    from urdf_pipeline.live_views import FoxgloveFeed, Latencies

    feed = FoxgloveFeed(url, {"/joint_states": None}, reconnects=100)
    signal.signal(signal.SIGTERM, lambda signum, frame: feed.close())
    rec = rr.RecordingStream("g1_hand")
    rec.save(out)
    urdf = config.parent / G1
    rec.log_file_from_path(urdf, static=True)
    tree = UrdfTree.from_file_path(urdf)
    latencies, sent, started = Latencies(), 0, time.monotonic()
    for batch in feed.batches():
        for sample in batch:
            rec.set_time("ros2_timestamp", timestamp=np.datetime64(sample.header_ns, "ns"))
            for name, value in zip(sample.names, sample.positions, strict=True):
                joint = tree.get_joint_by_name(name)
                if joint is not None:
                    rec.log("transforms", joint.compute_transform(float(value)))
            latencies.add(np.array([time.monotonic_ns() - sample.received_ns]))
            sent += 1
    rec.flush()
    seconds = time.monotonic() - started
    print(f"live: {sent} samples in {seconds:.1f} s, {sent} sent (hand); from arrival to sent: {latencies.text()}", file=sys.stderr)


if __name__ == "__main__" and sys.argv[1] == "--hand":
    sys.path.insert(0, str(REPO))
    import logging

    logging.basicConfig(level=logging.INFO, format="%(message)s")
    hand_written(Path(sys.argv[2]), sys.argv[3], Path(sys.argv[4]))
    print(json.dumps({}), file=sys.stdout)
