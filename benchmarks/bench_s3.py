"""Benchmark: a dataset read from S3 against the same dataset read from local disk (issue 24's bound: within 1.3x).

The dataset: EPISODES Panda episodes of FRAMES frames each (default 100 x 14,400 = 1.44M frames), one parquet file
per episode, globbed (a segment per file), split layout, outputs on local disk in both variants. The S3 endpoint is
a real `moto_server` on 127.0.0.1 started here (its CPU counts: it is the server the run waits for).

Each variant is the real command in its own process, alternated in one session, `--repeat` times:
  local     `urdf-pipeline run local.yaml --force --jobs 2`
  s3        `urdf-pipeline run s3.yaml --force --jobs 2`, an empty download cache each time (every episode downloaded)
  s3 warm   the same with the cache kept (the ETags unchanged: nothing downloaded again)
and the re-runs with nothing changed (`run` without --force: every output up to date), local and s3.
Reported: wall seconds and CPU seconds (the command's own, and the server's for s3), medians, and the ratios.
Usage: python benchmarks/bench_s3.py [--episodes 100] [--frames 14400] [--repeat 3] [--workdir DIR]
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.s3_server import CREDENTIALS, s3_endpoint  # noqa: E402  (the same real server the tests start)

PANDA_JOINTS = [*(f"panda_joint{i}" for i in range(1, 8)), "panda_finger_joint1"]


def prepare(workdir: Path, episodes: int, frames: int) -> None:
    import numpy as np

    from urdf_pipeline.examples import prepare as prepare_examples
    from urdf_pipeline.examples import write_joint_parquet

    prepare_examples(workdir, frames=10)  # robots/ (the Panda URDF and meshes)
    rng = np.random.default_rng(0)
    lower = np.array([-2.8973, -1.7628, -2.8973, -3.0718, -2.8973, -0.0175, -2.8973, 0.0])  # the Panda's limits
    upper = np.array([2.8973, 1.7628, 2.8973, -0.0698, 2.8973, 3.7525, 2.8973, 0.04])
    for episode in range(episodes):
        t = np.linspace(0, 20 * np.pi, frames)[:, None]
        q = (lower + upper) / 2 + 0.4 * (upper - lower) * np.sin(t * (1 + rng.random((1, 8))))
        write_joint_parquet(workdir / "episodes" / f"episode_{episode:04d}.parquet", q)


def config(workdir: Path, name: str, pattern: str) -> Path:
    spec = {
        "version": 1,
        "sources": {"state": {"parquet": pattern, "column": "observation.state", "index": "frame_index", "names": PANDA_JOINTS}},
        "robots": {
            "arm": {
                "urdf": "robots/panda.urdf",
                "package_paths": {"example-robot-data": "robots/share/example-robot-data"},
                "joints": {
                    "source": "state",
                    "map": {j: j for j in PANDA_JOINTS[:7]} | {"panda_finger_joint1": {"joint": "panda_finger_joint1", "unit": "m"}},
                },
            }
        },
        "output": {
            "layout": "split",
            "model": f"out/{name}/model.rrd",
            "path": f"out/{name}/{{segment}}.rrd",
            "segment": "{stem}",
            "application_id": "bench_s3",
        },
    }
    path = workdir / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec, sort_keys=False))
    return path


def timed(command: list[str], env: dict[str, str]) -> tuple[float, float]:
    """Wall seconds and CPU seconds (user + system) of the command, interpreter start and imports included."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, env=env)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-3000:]}")
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def server_cpu(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--frames", type=int, default=14_400)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workdir", type=Path)
    args = parser.parse_args()
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="bench-s3-"))
    prepare(workdir, args.episodes, args.frames)
    with s3_endpoint() as (endpoint, server):
        import boto3

        env = os.environ | CREDENTIALS | {"AWS_ENDPOINT_URL": endpoint, "URDF_PIPELINE_ALLOW_URLS": "s3://bench/"}
        env["URDF_PIPELINE_CACHE"] = str(workdir / "cache")
        os.environ.update({k: v for k, v in env.items() if k.startswith("AWS_")})
        s3 = boto3.session.Session().client("s3", endpoint_url=endpoint)
        s3.create_bucket(Bucket="bench")
        for file in sorted((workdir / "episodes").glob("*.parquet")):
            s3.upload_file(str(file), "bench", f"episodes/{file.name}")
        local, remote = config(workdir, "local", "episodes/*.parquet"), config(workdir, "s3", "s3://bench/episodes/*.parquet")
        base = [sys.executable, "-m", "urdf_pipeline", "run"]
        figures: dict[str, list[tuple[float, float, float]]] = {}

        def measure(name: str, command: list[str], clear_cache: bool = False) -> None:
            if clear_cache:
                shutil.rmtree(workdir / "cache", ignore_errors=True)
            served = server_cpu(server.pid)
            wall, cpu = timed(command, env)
            figures.setdefault(name, []).append((wall, cpu, server_cpu(server.pid) - served))

        for _ in range(args.repeat):
            measure("local", [*base, str(local), "--force", "--jobs", "2", "-q"])
            measure("s3 (cold cache)", [*base, str(remote), "--force", "--jobs", "2", "-q"], clear_cache=True)
            measure("s3 (warm cache)", [*base, str(remote), "--force", "--jobs", "2", "-q"])
            measure("local re-run", [*base, str(local), "--jobs", "2", "-q"])
            measure("s3 re-run", [*base, str(remote), "--jobs", "2", "-q"])
    frames = args.episodes * args.frames
    print(f"{args.episodes} episodes x {args.frames} frames = {frames:,} frames; {args.repeat} alternated runs, medians")
    print(f"{'variant':<18} {'wall s':>8} {'cpu s':>8} {'server cpu s':>13} {'wall/local':>11}")
    reference = {
        "local": statistics.median(w for w, _, _ in figures["local"]),
        "local re-run": statistics.median(w for w, _, _ in figures["local re-run"]),
    }
    for name, runs in figures.items():
        wall = statistics.median(w for w, _, _ in runs)
        cpu = statistics.median(c for _, c, _ in runs)
        served = statistics.median(s for _, _, s in runs)
        against = reference["local re-run" if "re-run" in name else "local"]
        print(f"{name:<18} {wall:8.2f} {cpu:8.2f} {served:13.2f} {wall / against:10.2f}x")


if __name__ == "__main__":
    main()
