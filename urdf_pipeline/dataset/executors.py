"""Where segments run: this machine's processes, or Ray.

An executor calls `on_done(job, result)` as each job finishes and `on_crash(job, error)` when `run_segment` raised (a
bug) or its worker died; it returns when every job has been handled, and on Ctrl-C/SIGTERM it stops its workers and
re-raises the KeyboardInterrupt. `dataset.run` keeps the manifest and the results; the executor only runs jobs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import Literal

from ..execute import SegmentJob, SegmentResult, install_run_plan, run_segment
from ..plan import Plan

ExecutorName = Literal["local", "ray"]


def run_jobs(
    name: ExecutorName,
    workers: int,
    ray_address: str | None,
    plan: Plan,
    jobs: Sequence[SegmentJob],
    on_done: Callable[[SegmentJob, SegmentResult], None],
    on_crash: Callable[[SegmentJob, BaseException], None],
) -> None:
    """`jobs` on the executor the command line asked for: `workers` processes here (`--jobs N`), or Ray tasks (a local
    instance with `workers` CPUs, or the cluster at `ray_address`). Each worker gets the plan once (Ray: through its
    object store), not with every job."""
    slim = [replace(job, run_plan=None) for job in jobs]  # workers get the plan from install_run_plan
    if name == "ray":
        from .ray_executor import run_on_ray

        run_on_ray(run_segment, slim, ray_address, on_done, on_crash, num_cpus=workers, initializer=install_run_plan, shared=plan)
    else:
        from .local_executor import run_locally

        run_locally(run_segment, slim, workers, on_done, on_crash, install_run_plan, (plan,))
