"""Benchmark: a whole dataset, the real G1 recording of ../shared (100 episodes), written per episode.

Variants, each the real command (`urdf-pipeline run CONFIG --force --report R.json`) in its own process:
  split layout, --jobs 1        (in the main process)
  split layout, --jobs 2        (a pool of two worker processes)
  split layout, --executor ray  (a local Ray instance, 2 CPUs; only if Ray is installed)
  single layout, --jobs 2       (meshes in every episode's recording: for the bytes written)
Reported per variant (median of --repeat runs, alternating): wall time of the whole command, the time of the
segment phase (the run's own clock, from the first job queued to the last written), episodes/s, frames/s,
peak RSS of the worker processes, bytes written. Then peak worker memory with 20 vs 100 episodes.
Usage: python benchmarks/bench_dataset.py [--repeat 3] [--episodes all] [--workdir DIR] [--no-ray]
"""

from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[1]
G1_DATA = REPO.parent / "shared" / "data" / "lerobot_g1_inspire_v21"
G1_CONFIG = REPO / "tests" / "configs" / "valid" / "g1_inspire_lerobot.yaml"


def prepare(workdir: Path) -> dict[str, Path]:
    from urdf_pipeline.examples import prepare as prepare_examples

    prepare_examples(workdir, frames=10)  # robots/share/example-robot-data (the G1 URDF and meshes)
    # a copy (10 MB): a symlink would point outside the config's folder, where a config may not read
    shutil.copytree(G1_DATA, workdir / "data" / G1_DATA.name, dirs_exist_ok=True)
    spec = yaml.safe_load(G1_CONFIG.read_text())
    del spec["sources"]["g1_state"]["episode"]  # one segment per episode
    configs = {}
    for layout in ("split", "single", "split_b"):
        kind = layout.removesuffix("_b")  # split_b: a second split config with its own outputs, for two processes at once
        output = {"layout": kind, "path": f"out/{layout}/{{segment}}.rrd", "segment": "episode_{episode:06d}", "application_id": "g1"}
        if kind == "split":
            output["model"] = f"out/{layout}/model.rrd"
        configs[layout] = workdir / f"g1_{layout}.yaml"
        configs[layout].write_text(yaml.safe_dump({**spec, "output": output}, sort_keys=False))
    return configs


def run(config: Path, extra: list[str], episodes: str) -> dict:
    report = config.with_suffix(".report.json")
    command = [
        sys.executable,
        "-m",
        "urdf_pipeline",
        "run",
        str(config),
        "--force",
        "--episodes",
        episodes,
        "--report",
        str(report),
        *extra,
    ]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True)
    wall = time.perf_counter() - started
    if done.returncode != 0:
        raise SystemExit(f"{' '.join(command)} failed:\n{done.stderr[-3000:]}")
    data = json.loads(report.read_text())
    results = data["results"]
    workers: dict[str, float] = {}
    for r in results:
        if r["worker"]:
            workers[r["worker"]] = max(workers.get(r["worker"], 0.0), r["peak_rss_mib"])
    episodes_done = [r for r in results if r["label"] != "model"]
    return {
        "wall": wall,
        "segments_phase": data["seconds"],
        "episodes": len(episodes_done),
        "frames": sum(r["frames"] for r in results),
        "bytes": sum(r["bytes"] for r in results),
        "model_bytes": sum(r["bytes"] for r in results if r["label"] == "model"),
        "peak_worker_mib": max(workers.values()),
        "workers": len(workers),
    }


def run_halves(configs: dict[str, Path]) -> dict:
    """The bound on this machine: two independent `--jobs 1` processes at once, each on half of the episodes."""
    commands = [
        [sys.executable, "-m", "urdf_pipeline", "run", str(configs["split"]), "--force", "--jobs", "1", "--episodes", ":50"],
        [sys.executable, "-m", "urdf_pipeline", "run", str(configs["split_b"]), "--force", "--jobs", "1", "--episodes", "50:"],
    ]
    started = time.perf_counter()
    processes = [subprocess.Popen(c, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for c in commands]
    if any(p.wait() != 0 for p in processes):
        raise SystemExit("a half run failed")
    return {"wall": time.perf_counter() - started}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--episodes", default="all")
    parser.add_argument("--workdir", type=Path)
    parser.add_argument("--no-ray", action="store_true")
    args = parser.parse_args()
    if not G1_DATA.is_dir():
        raise SystemExit(f"{G1_DATA} is absent: this benchmark needs the shared G1 recording")
    workdir = args.workdir or Path(tempfile.mkdtemp(prefix="bench-dataset-"))
    configs = prepare(workdir)
    variants = {
        "split, jobs 1": (configs["split"], ["--jobs", "1"]),
        "split, jobs 2": (configs["split"], ["--jobs", "2"]),
        "single, jobs 2": (configs["single"], ["--jobs", "2"]),
    }
    try:
        import ray  # noqa: F401

        if not args.no_ray:
            variants["split, ray (2 CPUs)"] = (configs["split"], ["--executor", "ray", "--jobs", "2"])
    except ImportError:
        print("ray is not installed: the ray variant is left out", file=sys.stderr)
    measured: dict[str, list[dict]] = {name: [] for name in variants}
    halves: list[float] = []
    for round_index in range(args.repeat):
        order = list(variants) if round_index % 2 == 0 else list(reversed(variants))
        for name in order:
            config, extra = variants[name]
            measured[name].append(run(config, extra, args.episodes))
            print(f"round {round_index + 1} {name}: {measured[name][-1]['wall']:.2f} s", file=sys.stderr)
        if args.episodes == "all":
            halves.append(run_halves(configs)["wall"])

    def median(name: str, key: str) -> float:
        return statistics.median(m[key] for m in measured[name])

    print(
        f"\nG1 dataset, {measured['split, jobs 1'][0]['episodes']} episodes, {measured['split, jobs 1'][0]['frames']:,} frames; medians of {args.repeat} runs\n"
    )
    print("| variant | wall s | segment phase s | episodes/s (wall) | frames/s (wall) | peak RSS per worker MiB | bytes written |")
    print("|---|---|---|---|---|---|---|")
    for name in variants:
        wall, phase = median(name, "wall"), median(name, "segments_phase")
        first = measured[name][0]
        print(
            f"| {name} | {wall:.2f} | {phase:.2f} | {first['episodes'] / wall:.1f} | {first['frames'] / wall:,.0f} | "
            f"{median(name, 'peak_worker_mib'):.0f} | {first['bytes']:,} |"
        )
    one, two = "split, jobs 1", "split, jobs 2"
    print(
        f"\nspeed-up jobs 2 / jobs 1: whole command {median(one, 'wall') / median(two, 'wall'):.2f}x, segment phase {median(one, 'segments_phase') / median(two, 'segments_phase'):.2f}x"
    )
    if halves:
        bound = median(one, "wall") / statistics.median(halves)
        print(
            f"upper bound on this machine: two independent --jobs 1 processes on 50 episodes each take {statistics.median(halves):.2f} s, {bound:.2f}x"
        )
    single_one = run(configs["single"], ["--jobs", "1"], args.episodes)
    print(
        f"single layout: jobs 1 {single_one['wall']:.2f} s, jobs 2 {median('single, jobs 2', 'wall'):.2f} s: {single_one['wall'] / median('single, jobs 2', 'wall'):.2f}x (segment phase {single_one['segments_phase'] / median('single, jobs 2', 'segments_phase'):.2f}x)"
    )
    split_bytes, single_bytes = measured[two][0]["bytes"], measured["single, jobs 2"][0]["bytes"]
    print(
        f"bytes: single {single_bytes:,} / split {split_bytes:,} (model {measured[two][0]['model_bytes']:,}) = {single_bytes / split_bytes:.1f}x fewer with split"
    )

    few = run(configs["split"], ["--jobs", "2"], "0:20")
    many = run(configs["split"], ["--jobs", "2"], args.episodes)
    print(
        f"peak RSS per worker, split, jobs 2: {few['episodes']} episodes {few['peak_worker_mib']:.0f} MiB, {many['episodes']} episodes {many['peak_worker_mib']:.0f} MiB"
    )
    if not args.workdir:
        shutil.rmtree(workdir)


if __name__ == "__main__":
    main()
