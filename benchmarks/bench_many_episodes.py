"""Per-episode overhead of the whole tool on a dataset of many tiny episodes (issues 23 and 24).

A LeRobot v2.1 dataset of N episodes of --frames frames each (default 20) for the SO-101 arm, run in the split layout
(configs/so101_dataset.yaml with its data path changed). Each command is the real one, in its own process, in this
order: `validate CONFIG`, `plan CONFIG`, `run CONFIG --jobs J` (first run: every segment written), the same `run`
again (re-run: every output up to date, nothing written), `browse CONFIG -o SITE`. Per command and size: wall
seconds (until the command's own process exits), CPU seconds (user + sys of all its processes: the driver, and for
`run --jobs 2` the fork server and the workers, which the driver does not wait for: this process is their subreaper
and waits for them, with os.wait4), wall and CPU ms per episode, the driver's peak RSS (VmHWM of the command's own
process, read from /proc while it runs) and the largest process's (ru_maxrss). Between two sizes the marginal cost
(extra wall ms per extra episode) says whether a command is linear: it should stay the same from one pair of sizes
to the next, once the fixed start-up (interpreter, imports, URDF) is amortised. Also the site's `segments.json` size.

The inputs are made in a child process (this one imports nothing heavy: Linux starts a child's ru_maxrss at its
parent's) and are not measured; `--workdir` keeps them for the next time (and the logs of every command). Where the
episodes live is a `Storage`: `local` (files beside the config) today; a variant whose sources are read from a URL
(`--source-url`, S3) adds a class that uploads the dataset and gives the config's `lerobot:` value.
Usage: python benchmarks/bench_many_episodes.py [--episodes 100,1000] [--frames 20] [--jobs 2] [--repeat 1]
       [--workdir DIR] [--json PATH]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import resource
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Protocol

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
COMMANDS = ("validate", "plan", "run", "rerun", "browse")
POLL_SECONDS = 0.02


# ---------------------------------------------------------------------------------------------------------------
# Inputs (made in a child process: `--prepare DIR`)
# ---------------------------------------------------------------------------------------------------------------


class Storage(Protocol):
    """Where the dataset's episodes are read from; gives the value of the config's `sources.so101.lerobot`."""

    name: str

    def place(self, dataset: Path, config_dir: Path) -> str: ...


class LocalStorage:
    """The dataset in the config's folder, as a path relative to it."""

    name = "local"

    def place(self, dataset: Path, config_dir: Path) -> str:
        return str(dataset.relative_to(config_dir))


class S3Storage:
    """The dataset uploaded to the benchmark's own S3 endpoint (a moto_server on 127.0.0.1, started by `main`, as the
    tests start one), read as `lerobot: s3://bench/...`; the download cache is emptied before each first run."""

    name = "s3"
    bucket = "bench"

    def place(self, dataset: Path, config_dir: Path) -> str:
        from concurrent.futures import ThreadPoolExecutor

        import boto3

        client = boto3.session.Session().client("s3")  # AWS_ENDPOINT_URL and the credentials: main's environment
        if self.bucket not in [b["Name"] for b in client.list_buckets().get("Buckets", [])]:
            client.create_bucket(Bucket=self.bucket)
        prefix = f"{config_dir.name}/{dataset.name}"
        files = [f for f in sorted(dataset.rglob("*")) if f.is_file()]
        with ThreadPoolExecutor(16) as pool:
            list(pool.map(lambda f: client.upload_file(str(f), self.bucket, f"{prefix}/{f.relative_to(dataset).as_posix()}"), files))
        return f"s3://{self.bucket}/{prefix}"


STORAGES: dict[str, Storage] = {"local": LocalStorage(), "s3": S3Storage()}


def prepare(directory: Path, episodes: int, frames: int, storage: Storage) -> Path:
    """The dataset, the robot description (linked) and the config in `directory`; the dataset is kept when its
    meta/info.json already says `episodes` episodes of `frames` frames."""
    import numpy as np
    import yaml

    from urdf_pipeline.examples import LEROBOT_CHUNK_SIZE, SO101_NAMES, example_robot_data_share, smooth_trajectory, write_lerobot_dataset
    from urdf_pipeline.urdf import read_urdf

    share = example_robot_data_share()
    link = directory / "robots" / "share" / "example-robot-data"
    if not link.is_symlink():
        link.parent.mkdir(parents=True, exist_ok=True)
        link.symlink_to(share, target_is_directory=True)
    dataset = directory / "data" / "so101_lerobot"
    info = dataset / "meta" / "info.json"
    wanted = {"total_episodes": episodes, "total_frames": episodes * frames, "total_chunks": -(-episodes // LEROBOT_CHUNK_SIZE)}
    if not info.is_file() or {k: json.loads(info.read_text()).get(k) for k in wanted} != wanted:
        shutil.rmtree(dataset, ignore_errors=True)
        _, so101 = read_urdf(share / "robots" / "so_arm_description" / "urdf" / "so101.urdf")
        # one long trajectory cut into episodes: each starts elsewhere on it, and N calls are not needed
        long = np.degrees(smooth_trajectory(so101, SO101_NAMES, episodes * frames, seed=3))
        write_lerobot_dataset(dataset, list(long.reshape(episodes, frames, len(SO101_NAMES))), SO101_NAMES)
    spec = yaml.safe_load((REPO / "configs" / "so101_dataset.yaml").read_text())
    spec["sources"]["so101"]["lerobot"] = storage.place(dataset, directory)
    config = directory / "so101_many.yaml"
    config.write_text(yaml.safe_dump(spec, sort_keys=False))
    return config


# ---------------------------------------------------------------------------------------------------------------
# Measuring
# ---------------------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Sample:
    """One command as measured from outside. MB are 10^6 bytes."""

    seconds: float  # until the command's own process exited
    cpu: float  # user + sys of every process of the command: the driver, the fork server, the workers
    driver_cpu: float  # user + sys of the command's own process (and the children it waited for itself)
    driver_mb: float  # VmHWM of the command's own process, last read before it exited
    largest_mb: float  # the largest ru_maxrss of the command's processes


def become_subreaper() -> None:
    """Orphans of the commands become our children: `run --jobs 2`'s workers are forked by multiprocessing's fork
    server, which outlives the driver, so neither is waited for by the command; here they are, with their rusage."""
    import ctypes

    PR_SET_CHILD_SUBREAPER = 36
    if ctypes.CDLL(None, use_errno=True).prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) != 0:
        raise SystemExit(f"prctl(PR_SET_CHILD_SUBREAPER) failed (errno {ctypes.get_errno()}): this benchmark needs Linux")


def driver_hwm_kb(pid: int) -> int | None:
    try:
        with open(f"/proc/{pid}/status", encoding="ascii") as status:
            for line in status:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1])
    except (OSError, ValueError):
        pass
    return None


def measure(command: list[str], cwd: Path, log: Path, timeout: float) -> Sample:
    """Run `command`, polling its own process's peak RSS until it exits, then reap what it left (workers, the fork
    server: they end with it); a failure, or a command still running after `timeout` seconds, stops the benchmark."""
    with log.open("wb") as out:
        started = time.perf_counter()
        # a session of its own: on a timeout the whole command (workers included) is killed, and nothing else
        process = subprocess.Popen(command, stdout=out, stderr=subprocess.STDOUT, cwd=cwd, env=this_checkout(), start_new_session=True)
        hwm_kb = 0
        while True:
            pid, status, usage = os.wait4(process.pid, os.WNOHANG)
            if pid:
                break
            hwm_kb = max(hwm_kb, driver_hwm_kb(process.pid) or 0)
            if time.perf_counter() - started > timeout:
                os.killpg(process.pid, signal.SIGKILL)
                os.wait4(process.pid, 0)
                raise SystemExit(f"{' '.join(command)}: still running after {timeout:.0f} s (peak RSS {hwm_kb / 1e3:.0f} MB), killed")
            time.sleep(POLL_SECONDS)
        seconds = time.perf_counter() - started
    process.returncode = os.waitstatus_to_exitcode(status)
    driver_cpu = usage.ru_utime + usage.ru_stime
    cpu, largest_kb = driver_cpu, usage.ru_maxrss
    while _children() - KEPT_CHILDREN:  # the orphans, reparented to us (become_subreaper); not the S3 server we keep
        pid, _, orphan = os.wait4(-1, os.WNOHANG)
        if not pid:
            time.sleep(POLL_SECONDS)
            continue
        cpu += orphan.ru_utime + orphan.ru_stime
        largest_kb = max(largest_kb, orphan.ru_maxrss)
    if process.returncode != 0:
        tail = "\n".join(log.read_text(errors="replace").splitlines()[-30:])
        raise SystemExit(f"{' '.join(command)} exited with {process.returncode}; end of {log}:\n{tail}")
    # a command shorter than one poll: its own peak is its ru_maxrss (it waited for no child of its own)
    driver_mb = (hwm_kb or usage.ru_maxrss) * 1024 / 1e6
    return Sample(seconds, cpu, driver_cpu, driver_mb, largest_kb * 1024 / 1e6)


KEPT_CHILDREN: set[int] = set()  # children of this process that outlive every command (the S3 endpoint)


def _children() -> set[int]:
    """This process's living children (reparented orphans included), from /proc."""
    found: set[int] = set()
    for task in Path("/proc/self/task").iterdir():
        found.update(int(pid) for pid in (task / "children").read_text().split())
    return found


def cli() -> list[str]:
    script = Path(sys.executable).parent / "urdf-pipeline"
    return [str(script)] if script.exists() else [sys.executable, "-m", "urdf_pipeline"]


def this_checkout() -> dict[str, str]:
    """The environment of every child: the package of this checkout first (the venv's editable install may be
    another checkout's)."""
    path = os.environ.get("PYTHONPATH")
    return {**os.environ, "PYTHONPATH": str(REPO) + (os.pathsep + path if path else "")}


def one_round(directory: Path, config: Path, jobs: int, logs: Path, label: str, timeout: float) -> dict[str, Sample]:
    """The five commands once, on outputs and a site removed first: the first run writes every segment."""
    shutil.rmtree(directory / "out", ignore_errors=True)
    shutil.rmtree(directory / "site", ignore_errors=True)
    if os.environ.get("URDF_PIPELINE_CACHE"):  # S3: the first run downloads every episode
        shutil.rmtree(os.environ["URDF_PIPELINE_CACHE"], ignore_errors=True)
    commands = {
        "validate": ["validate", str(config)],
        "plan": ["plan", str(config)],
        "run": ["run", str(config), "--jobs", str(jobs)],
        "rerun": ["run", str(config), "--jobs", str(jobs)],
        "browse": ["browse", str(config), "-o", str(directory / "site")],
    }
    samples, written = {}, {}
    for name, arguments in commands.items():
        samples[name] = measure([*cli(), *arguments], directory, logs / f"{label}-{name}.log", timeout)
        s = samples[name]
        print(
            f"  {label} {name}: {s.seconds:.2f} s, CPU {s.cpu:.2f} s (driver {s.driver_cpu:.2f} s), driver {s.driver_mb:.0f} MB, "
            f"largest {s.largest_mb:.0f} MB",
            file=sys.stderr,
            flush=True,
        )
        if name in ("run", "rerun"):
            written[name] = {path: path.stat().st_mtime_ns for path in (directory / "out").rglob("*.rrd")}
    if len(written["run"]) <= 1 or written["rerun"] != written["run"]:
        raise SystemExit(f"{label}: the first run wrote {len(written['run'])} recordings and the re-run changed some: not up to date")
    return samples


# ---------------------------------------------------------------------------------------------------------------
# Report
# ---------------------------------------------------------------------------------------------------------------


def median_sample(samples: list[Sample]) -> Sample:
    return Sample(
        statistics.median(s.seconds for s in samples),
        statistics.median(s.cpu for s in samples),
        statistics.median(s.driver_cpu for s in samples),
        max(s.driver_mb for s in samples),
        max(s.largest_mb for s in samples),
    )


def table(results: dict[int, dict[str, Sample]], site: dict[int, dict[str, int]], repeat: int) -> list[str]:
    lines = [
        "| command | episodes | wall s | CPU s (driver) | wall ms / episode | marginal wall ms / episode | CPU ms / episode "
        "| driver peak MB | largest process MB |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    sizes = sorted(results)
    for command in COMMANDS:
        for index, size in enumerate(sizes):
            s = results[size][command]
            marginal = ""
            if index:
                previous = sizes[index - 1]
                marginal = f"{1000 * (s.seconds - results[previous][command].seconds) / (size - previous):.2f}"
            lines.append(
                f"| {command} | {size:,} | {s.seconds:.2f} | {s.cpu:.2f} ({s.driver_cpu:.2f}) | {1000 * s.seconds / size:.2f} "
                f"| {marginal} | {1000 * s.cpu / size:.2f} | {s.driver_mb:.0f} | {s.largest_mb:.0f} |"
            )
    lines.append("")
    for size in sizes:
        made = site[size]
        lines.append(
            f"site of {size:,} segments: segments.json {made['segments_json'] / 1e6:.2f} MB "
            f"({made['segments_json'] / size:.0f} B a segment), {made['files']:,} files"
        )
    if repeat > 1:
        lines.append(f"(medians of {repeat} rounds; peaks are the largest)")
    return lines


def site_sizes(directory: Path) -> dict[str, int]:
    site = directory / "site"
    return {"segments_json": (site / "segments.json").stat().st_size, "files": sum(1 for p in site.rglob("*") if p.is_file())}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--episodes", default="100,1000", help="comma-separated dataset sizes (default 100,1000; 10000 takes minutes)")
    parser.add_argument("--frames", type=int, default=20, help="frames per episode (default 20)")
    parser.add_argument("--jobs", type=int, default=2, help="`run --jobs` (default 2)")
    parser.add_argument("--repeat", type=int, default=1, help="rounds per size (medians; default 1)")
    parser.add_argument("--storage", choices=sorted(STORAGES), default="local", help="where the episodes are read from")
    parser.add_argument("--workdir", type=Path, help="keep inputs (reused next time) and logs here (default: a temporary directory)")
    parser.add_argument("--json", type=Path, help="also write the figures as JSON here")
    parser.add_argument("--timeout", type=float, default=900, help="seconds a command may take before it is killed (default 900)")
    parser.add_argument("--prepare", type=Path, help=argparse.SUPPRESS)  # the child that makes one size's inputs
    args = parser.parse_args()
    sizes = [int(size) for size in args.episodes.split(",") if size]
    if not sizes or min(sizes) < 1 or args.frames < 1:
        parser.error("--episodes takes positive sizes and --frames a positive count")
    if args.prepare is not None:
        print(prepare(args.prepare.resolve(), sizes[0], args.frames, STORAGES[args.storage]))
        return
    temporary = None if args.workdir else tempfile.TemporaryDirectory(prefix="bench-many-")
    workdir = (args.workdir or Path(temporary.name)).resolve()  # type: ignore[union-attr]
    logs = workdir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    become_subreaper()
    load = os.getloadavg()
    endpoint = contextlib.ExitStack()
    if args.storage == "s3":  # a real S3 endpoint for the whole benchmark, the commands configured for it
        sys.path.insert(0, str(REPO))
        from tests.s3_server import CREDENTIALS, s3_endpoint

        url, server = endpoint.enter_context(s3_endpoint())
        KEPT_CHILDREN.add(server.pid)
        os.environ.update(CREDENTIALS)
        os.environ.update(
            AWS_ENDPOINT_URL=url, URDF_PIPELINE_ALLOW_URLS=f"s3://{S3Storage.bucket}/", URDF_PIPELINE_CACHE=str(workdir / "cache")
        )
    try:
        results: dict[int, dict[str, Sample]] = {}
        site: dict[int, dict[str, int]] = {}
        for size in sorted(set(sizes)):
            directory = workdir / f"n{size}"
            began = time.perf_counter()
            child = [sys.executable, __file__, "--prepare", str(directory), "--episodes", str(size), "--frames", str(args.frames)]
            done = subprocess.run([*child, "--storage", args.storage], stdout=subprocess.PIPE, text=True, check=True, env=this_checkout())
            config = Path(done.stdout.strip().splitlines()[-1])
            print(f"bench_many_episodes: {size:,} episodes ready in {time.perf_counter() - began:.1f} s", file=sys.stderr, flush=True)
            rounds = [one_round(directory, config, args.jobs, logs, f"n{size}-r{r + 1}", args.timeout) for r in range(args.repeat)]
            results[size] = {name: median_sample([r[name] for r in rounds]) for name in COMMANDS}
            site[size] = site_sizes(directory)
        own_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e6
        print()
        print(
            f"{args.frames} frames per episode, SO-101, split layout, run --jobs {args.jobs}, storage {args.storage}; "
            f"{os.cpu_count()} cores, load average {load[0]:.2f} before and {os.getloadavg()[0]:.2f} after; "
            f"this process's peak RSS {own_mb:.0f} MB (the floor of the largest-process figures)"
        )
        print()
        print("\n".join(table(results, site, args.repeat)))
        if args.json is not None:
            figures = {
                "frames_per_episode": args.frames,
                "jobs": args.jobs,
                "storage": args.storage,
                "repeat": args.repeat,
                "sizes": {
                    str(size): {"commands": {name: asdict(s) for name, s in results[size].items()}, "site": site[size]} for size in results
                },
            }
            args.json.write_text(json.dumps(figures, indent=2) + "\n")
    finally:
        endpoint.close()
        if temporary is not None:
            temporary.cleanup()


if __name__ == "__main__":
    main()
