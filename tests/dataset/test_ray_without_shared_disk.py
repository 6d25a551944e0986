"""`run --executor ray` on a cluster whose worker node shares no folder with the driver's run: sources and outputs in
S3 (a real moto_server), a real `ray start --head` (no CPUs: it runs no task) and a second node (`ray start --address`)
started in a working folder of its own, with its own download cache and staging folder. The node fetches each
episode into ITS cache and uploads its layers; the driver downloads no data, writes the model (its meshes are here)
and the manifest, and the poses in the bucket equal pinocchio's."""

from __future__ import annotations

import os
import secrets
import shutil
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from urdf_pipeline.examples import write_joint_parquet

from ..conftest import S3
from ..local_processes import free_port, stop
from ..source_helpers import PANDA_JOINTS, assert_panda_fk, panda_config, random_panda_q
from .ray_auth import reset_auth_token_state

pytestmark = pytest.mark.slow
ray = pytest.importorskip("ray", reason="needs Ray (a test dependency: pip install -e '.[test]')")

FRAMES = 90
STEMS = ["ep_0", "ep_1", "ep_2"]


@dataclass(frozen=True)
class Cluster:
    address: str
    node_folder: Path  # the worker node's working folder, cache and staging folder


def _wait_for_cpus(address: str, cpus: float, log: Path, deadline: float) -> None:
    """Until the cluster has the worker node's CPUs (the head has none)."""
    probe = [
        sys.executable,
        "-c",
        f"import ray; ray.init(address={address!r}, logging_level='ERROR'); print(ray.cluster_resources().get('CPU', 0))",
    ]
    while True:
        answer = subprocess.run(probe, capture_output=True, text=True, timeout=60)
        if answer.returncode == 0 and float(answer.stdout.strip().splitlines()[-1] or 0) >= cpus:
            return
        assert time.monotonic() < deadline, f"the worker node did not join: {answer.stderr[-2000:]}\n{log.read_text()[-2000:]}"
        time.sleep(1)


@pytest.fixture(scope="module")
def cluster(s3_endpoint: str, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    from ..s3_server import CREDENTIALS

    node_folder = tmp_path_factory.mktemp("worker-node")
    temp_dir = tempfile.mkdtemp(prefix="ray", dir="/tmp")  # short: Ray's socket paths live under it
    ray_cli = str(Path(sys.executable).with_name("ray"))
    port = free_port()
    base = os.environ | {
        "RAY_USAGE_STATS_ENABLED": "0",
        "RAY_AUTH_MODE": "token",
        "RAY_AUTH_TOKEN": secrets.token_hex(16),
        "RAY_GRACEFUL_SHUTDOWN_DRAIN_TIMEOUT_S": "0",
    }
    base.pop("RAY_ADDRESS", None)
    node_env = (
        base
        | CREDENTIALS
        | {
            "AWS_ENDPOINT_URL": s3_endpoint,
            "URDF_PIPELINE_CACHE": str(node_folder / "cache"),
            "URDF_PIPELINE_STAGING": str(node_folder / "staging"),
        }
    )
    log = Path(temp_dir, "cluster.log")
    processes: list[subprocess.Popen[bytes]] = []
    with pytest.MonkeyPatch.context() as patch, log.open("w") as out:
        for name in ("RAY_USAGE_STATS_ENABLED", "RAY_AUTH_MODE", "RAY_AUTH_TOKEN"):
            patch.setenv(name, base[name])
        patch.delenv("RAY_ADDRESS", raising=False)
        reset_auth_token_state()
        head = [ray_cli, "start", "--head", "--block", "--num-cpus", "0", "--port", str(port), "--temp-dir", temp_dir]
        head += ["--include-dashboard", "false", "--disable-usage-stats", "--ray-client-server-port", str(free_port())]
        processes.append(subprocess.Popen(head, env=base, stdout=out, stderr=subprocess.STDOUT))
        try:
            address = f"127.0.0.1:{port}"
            deadline = time.monotonic() + 120
            while True:
                try:
                    socket.create_connection(("127.0.0.1", port), timeout=1).close()
                    break
                except OSError:
                    assert processes[0].poll() is None and time.monotonic() < deadline, log.read_text()[-3000:]
                    time.sleep(0.2)
            node = [ray_cli, "start", "--address", address, "--block", "--num-cpus", "2", "--disable-usage-stats"]
            processes.append(subprocess.Popen(node, env=node_env, cwd=node_folder, stdout=out, stderr=subprocess.STDOUT))
            _wait_for_cpus(address, 2, log, deadline)
            yield Cluster(address, node_folder)
        finally:
            for process in reversed(processes):
                stop(process)
            shutil.rmtree(temp_dir, ignore_errors=True)
            reset_auth_token_state()


def _files(folder: Path, suffix: str) -> list[str]:
    return sorted(p.name for p in folder.rglob(f"*{suffix}") if not p.name.startswith(".")) if folder.exists() else []


def test_a_cluster_node_fetches_its_inputs_and_uploads_its_layers(
    cluster: Cluster, s3: S3, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(tmp_path / "driver-cache"))
    monkeypatch.setenv("URDF_PIPELINE_STAGING", str(tmp_path / "driver-staging"))
    values = {stem: random_panda_q(examples_dir, FRAMES, seed=40 + n) for n, stem in enumerate(STEMS)}
    for stem, q in values.items():
        local = tmp_path / "upload" / f"{stem}.parquet"
        write_joint_parquet(local, q)
        s3.client().upload_file(str(local), s3.bucket, f"in/{stem}.parquet")
    source = {"parquet": s3.url("in/*.parquet"), "column": "observation.state", "index": "frame_index", "names": PANDA_JOINTS}
    config = panda_config(examples_dir, "{stem}", source)
    data = yaml.safe_load(config.read_text())
    data["output"].update(path=s3.url("out/{segment}.rrd"), layout="split", model=s3.url("out/model.rrd"))
    config = examples_dir / "ray_without_shared_disk.yaml"
    config.write_text(yaml.safe_dump(data, sort_keys=False))

    result = run_cli("run", str(config), "--executor", "ray", "--ray-address", cluster.address, "--jobs", "2")
    assert result.code == 0, result.err
    keys = sorted(e["Key"] for e in s3.client().list_objects_v2(Bucket=s3.bucket, Prefix="out/")["Contents"])
    assert keys == sorted(
        ["out/model.rrd", "out/ray_without_shared_disk.manifest.json", "out/ray_without_shared_disk.rbl"] + [f"out/{s}.rrd" for s in STEMS]
    )

    assert _files(cluster.node_folder / "cache", ".parquet") == [f"{s}.parquet" for s in STEMS], "the node fetched into its own cache"
    assert _files(tmp_path / "driver-cache", ".parquet") == [], "the driver downloaded no data (footers by ranged reads)"
    assert _files(cluster.node_folder / "staging", ".rrd") == [] and _files(tmp_path / "driver-staging", ".rrd") == []

    model = tmp_path / "model.rrd"
    s3.client().download_file(s3.bucket, "out/model.rrd", str(model))
    for stem, q in values.items():
        layer = tmp_path / f"{stem}.rrd"
        s3.client().download_file(s3.bucket, f"out/{stem}.rrd", str(layer))
        assert_panda_fk(examples_dir, [model, layer], "frame_index", list(range(FRAMES)), q, [0, FRAMES // 2])  # as a catalog merges them

    again = run_cli("run", str(config), "--executor", "ray", "--ray-address", cluster.address)
    assert again.code == 0 and again.err.count("skipped") >= len(STEMS) + 1, again.err


def test_a_lerobot_dataset_on_s3_runs_on_the_node_from_its_own_view(
    cluster: Cluster, s3: S3, examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, run_cli
) -> None:
    """A LeRobot dataset (v3: episodes share data files) in S3: the node fetches each episode's files into its cache
    and reads them from a view of its own; the driver fetched the metadata only."""
    from ..lerobot_layouts import dataset_files, lerobot_panda_config, write_dataset

    monkeypatch.setenv("URDF_PIPELINE_CACHE", str(tmp_path / "driver-cache"))
    monkeypatch.setenv("URDF_PIPELINE_STAGING", str(tmp_path / "driver-staging"))
    episodes = [random_panda_q(examples_dir, frames, seed=60 + n) for n, frames in enumerate((40, 55, 30))]
    write_dataset(tmp_path / "dataset", episodes, "v3")
    for relative in dataset_files(tmp_path / "dataset"):
        s3.client().upload_file(str(tmp_path / "dataset" / relative), s3.bucket, f"lerobot/pick/{relative}")
    config = lerobot_panda_config(examples_dir, "ray_lerobot_s3", {"lerobot": s3.url("lerobot/pick")})
    data = yaml.safe_load(config.read_text())
    data["output"].update(path=s3.url("lerobot-out/{segment}.rrd"), layout="split", model=s3.url("lerobot-out/model.rrd"))
    config.write_text(yaml.safe_dump(data, sort_keys=False))

    result = run_cli("run", str(config), "--executor", "ray", "--ray-address", cluster.address, "--jobs", "2")
    assert result.code == 0, result.err
    # v3, two episodes a data file: data/chunk-000/file-001.parquet holds the third (meta/ has a file-000.parquet only)
    assert "file-001.parquet" in _files(cluster.node_folder / "cache", ".parquet"), "the node fetched the episodes' data files"
    assert "file-001.parquet" not in _files(tmp_path / "driver-cache", ".parquet"), "the driver fetched metadata only"
    model = tmp_path / "model.rrd"
    s3.client().download_file(s3.bucket, "lerobot-out/model.rrd", str(model))
    for episode, q in enumerate(episodes):
        layer = tmp_path / f"episode_{episode}.rrd"
        s3.client().download_file(s3.bucket, f"lerobot-out/episode_{episode:06d}.rrd", str(layer))
        assert_panda_fk(examples_dir, [model, layer], "frame_index", list(range(len(q))), q, [0, len(q) - 1])
