"""How many CPUs this process may use: the default worker count everywhere one is chosen (`run --jobs`, the API's
`run`, a local Ray instance).

`os.cpu_count()` is the machine's count, not this process's: under `taskset`, a CI runner's or a container's CPU set,
or a cgroup CPU quota (Docker's `--cpus`, Kubernetes' limits), as many workers as the machine has cores would share a
few CPUs, each slower and all of them holding memory. The answer is the smaller of the CPUs the process may be
scheduled on (`os.sched_getaffinity`) and the cgroup quota (v2 `cpu.max`, v1 `cpu.cfs_quota_us` over
`cpu.cfs_period_us`, rounded up), at least 1.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

CGROUP_ROOT = Path("/sys/fs/cgroup")
MEMBERSHIP = Path("/proc/self/cgroup")
MEMBERSHIP_BYTES = 65_536  # /proc/self/cgroup is a few lines; what is read of it is bounded whatever it holds
MAX_LEVELS = 32  # cgroups nested deeper than this: the deepest levels are read (a quota is set near the process)


def usable_cpus(cgroup_root: Path = CGROUP_ROOT, membership: str | None = None) -> int:
    """The CPUs this process may use; `cgroup_root` and `membership` (the text of /proc/self/cgroup) are where the
    quota is read from, so that a test can point them at files of its own."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except (AttributeError, OSError):  # not on Linux
        cpus = os.cpu_count() or 1
    quota = cgroup_cpu_quota(cgroup_root, membership)
    return max(1, min(cpus, quota) if quota is not None else cpus)


def cgroup_cpu_quota(cgroup_root: Path = CGROUP_ROOT, membership: str | None = None) -> int | None:
    """The smallest CPU quota on the way from this process's cgroup up to the root (each level may limit it), in CPUs
    rounded up; None when no level sets one or nothing can be read (no cgroups: no limit to respect)."""
    if membership is None:
        membership = _read(MEMBERSHIP, MEMBERSHIP_BYTES)
    quotas = []
    for line in membership[:MEMBERSHIP_BYTES].splitlines()[:64]:
        number, _, rest = line.partition(":")
        controllers, _, path = rest.partition(":")
        if number == "0" and controllers == "":  # v2 (unified); under v1's hybrid mount, at unified/
            for mount in (cgroup_root, cgroup_root / "unified"):
                quotas += [_v2_quota(folder) for folder in _levels(mount, path)]
        elif "cpu" in controllers.split(","):  # v1: the cpu controller's own hierarchy
            for mount in dict.fromkeys((cgroup_root / controllers, cgroup_root / "cpu", cgroup_root / "cpu,cpuacct")):
                quotas += [_v1_quota(folder) for folder in _levels(mount, path)]
    if not membership.strip():  # no membership to follow: the root as a container sees its own
        quotas += [_v2_quota(cgroup_root), _v1_quota(cgroup_root / "cpu")]
    found = [quota for quota in quotas if quota is not None]
    return min(found) if found else None


def _levels(mount: Path, path: str) -> list[Path]:
    """The folders from the process's cgroup up to the mount (a container's namespace shows its own cgroup as `/`)."""
    parts = [part for part in path.strip().split("/") if part and part not in (".", "..")]
    levels = [mount.joinpath(*parts)]
    while len(levels) < min(len(parts), MAX_LEVELS):  # each a step up: the deepest MAX_LEVELS levels, in linear time
        levels.append(levels[-1].parent)
    return [*levels, mount] if parts else levels


def _v2_quota(folder: Path) -> int | None:
    """`cpu.max`: "QUOTA PERIOD" in microseconds, or "max PERIOD" for no limit."""
    fields = _read(folder / "cpu.max").split()
    if len(fields) != 2 or fields[0] == "max":
        return None
    return _cpus(fields[0], fields[1])


def _v1_quota(folder: Path) -> int | None:
    """`cpu.cfs_quota_us` over `cpu.cfs_period_us`; a quota of -1 is no limit."""
    return _cpus(_read(folder / "cpu.cfs_quota_us").strip(), _read(folder / "cpu.cfs_period_us").strip())


def _cpus(quota: str, period: str) -> int | None:
    try:
        q, p = int(quota), int(period)
    except ValueError:
        return None
    return max(1, math.ceil(q / p)) if q > 0 and p > 0 else None


def _read(path: Path, limit: int = 256) -> str:
    try:
        with path.open("rb") as file:
            return file.read(limit).decode("ascii", errors="replace")  # a line of numbers: bounded whatever is there
    except OSError:
        return ""
