"""The default worker count is the CPUs this process may use: its affinity (`taskset`) and its cgroup's CPU quota (v2
`cpu.max`, v1 `cpu.cfs_quota_us`/`cpu.cfs_period_us`, rounded up, at least 1), read from a cgroup root the test
builds."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from urdf_pipeline.dataset import usable_cpus
from urdf_pipeline.dataset.cpus import cgroup_cpu_quota

from ..dataset_helpers import isolated_examples

AFFINITY = len(os.sched_getaffinity(0))


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


def test_a_v2_quota_is_rounded_up(tmp_path: Path) -> None:
    _write(tmp_path / "cpu.max", "150000 100000\n")
    assert cgroup_cpu_quota(tmp_path, "0::/\n") == 2
    _write(tmp_path / "cpu.max", "1000 100000\n")  # a hundredth of a CPU: at least 1
    assert cgroup_cpu_quota(tmp_path, "0::/\n") == 1
    assert usable_cpus(tmp_path, "0::/\n") == 1


def test_the_smallest_quota_on_the_way_up_counts(tmp_path: Path) -> None:
    _write(tmp_path / "a" / "b" / "cpu.max", "max 100000\n")  # the process's own cgroup sets none
    _write(tmp_path / "a" / "cpu.max", "300000 100000\n")
    _write(tmp_path / "cpu.max", "max 100000\n")
    assert cgroup_cpu_quota(tmp_path, "0::/a/b\n") == 3
    assert usable_cpus(tmp_path, "0::/a/b\n") == min(AFFINITY, 3)


def test_no_quota_leaves_the_affinity(tmp_path: Path) -> None:
    _write(tmp_path / "cpu.max", "max 100000\n")
    assert cgroup_cpu_quota(tmp_path, "0::/\n") is None
    assert usable_cpus(tmp_path, "0::/\n") == AFFINITY
    assert usable_cpus(tmp_path / "nothing", "") == AFFINITY  # no cgroup files at all


def test_a_v1_quota(tmp_path: Path) -> None:
    folder = tmp_path / "cpu,cpuacct" / "docker" / "c0ffee"
    _write(folder / "cpu.cfs_quota_us", "250000\n")
    _write(folder / "cpu.cfs_period_us", "100000\n")
    membership = "12:memory:/docker/c0ffee\n4:cpu,cpuacct:/docker/c0ffee\n0::/\n"
    assert cgroup_cpu_quota(tmp_path, membership) == 3
    _write(folder / "cpu.cfs_quota_us", "-1\n")  # no limit
    assert cgroup_cpu_quota(tmp_path, membership) is None


def test_unreadable_or_hostile_files_mean_no_quota(tmp_path: Path) -> None:
    _write(tmp_path / "cpu.max", "x" * 10_000_000)  # read only as far as a line of numbers goes
    assert cgroup_cpu_quota(tmp_path, "0::/\n") is None
    _write(tmp_path / "cpu.max", "0 0\n")
    assert cgroup_cpu_quota(tmp_path, "0::/../../etc\n") is None  # a path leading out is not followed
    _write(tmp_path / "cpu.max", "200000 100000\n")
    deep = "0::/" + "/a" * 30_000 + "\n" * 100_000  # far deeper than any cgroup: the deepest levels and the root are read
    assert cgroup_cpu_quota(tmp_path, deep) == 2
    (tmp_path / "cpu.max").unlink()
    (tmp_path / "cpu.max").mkdir()
    assert cgroup_cpu_quota(tmp_path, "0::/\n") is None


@pytest.mark.skipif(shutil.which("taskset") is None, reason="needs taskset (util-linux)")
def test_taskset_one_cpu_means_one_job(examples_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("URDF_PIPELINE_ALLOW_PATHS", str(examples_dir))
    pinned = ["taskset", "-c", "0", sys.executable]
    alone = subprocess.run(
        [*pinned, "-c", "from urdf_pipeline.dataset import usable_cpus; print(usable_cpus())"], capture_output=True, text=True, timeout=60
    )
    assert alone.stdout.strip() == "1", alone.stderr
    config = isolated_examples(examples_dir, tmp_path / "run")
    run = subprocess.run([*pinned, "-m", "urdf_pipeline", "run", str(config)], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "1 job(s) on the local executor" in run.stderr
