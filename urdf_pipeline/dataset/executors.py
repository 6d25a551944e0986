"""Where segments run: one `Executor` interface, one class per executor (this machine's processes, or Ray).

An executor calls `on_done(job, result)` as each job finishes and `on_crash(job, error)` when `work` raised (a bug)
or its worker died; it returns when every job has been handled, and on Ctrl-C/SIGTERM it stops its workers and
re-raises the KeyboardInterrupt. `dataset.run` keeps the manifest and the results; the executor only runs jobs.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal, Protocol

from ..execute import SegmentJob, SegmentResult, install_run_plan
from ..plan import Plan

ExecutorName = Literal["local", "ray"]
Work = Callable[[SegmentJob], SegmentResult]
OnDone = Callable[[SegmentJob, SegmentResult], None]
OnCrash = Callable[[SegmentJob, BaseException], None]


class Executor(Protocol):
    """Runs segment jobs somewhere; see the module's docstring for the contract."""

    def run(self, work: Work, jobs: Sequence[SegmentJob], on_done: OnDone, on_crash: OnCrash) -> None: ...


@dataclass(frozen=True)
class LocalExecutor:
    """Worker processes on this machine (`--jobs N`); each worker gets the plan once, not with every job."""

    workers: int
    plan: Plan

    def run(self, work: Work, jobs: Sequence[SegmentJob], on_done: OnDone, on_crash: OnCrash) -> None:
        from .local_executor import run_locally

        slim = [replace(job, run_plan=None) for job in jobs]  # workers get the plan from install_run_plan
        run_locally(work, slim, self.workers, on_done, on_crash, install_run_plan, (self.plan,))


@dataclass(frozen=True)
class RayExecutor:
    """Ray tasks (`--executor ray`): a local instance with `num_cpus`, or the cluster at `address`. The plan goes
    to the cluster once (Ray's object store), not with every job."""

    address: str | None
    num_cpus: int | None
    plan: Plan

    def run(self, work: Work, jobs: Sequence[SegmentJob], on_done: OnDone, on_crash: OnCrash) -> None:
        from .ray_executor import run_on_ray

        slim = [replace(job, run_plan=None) for job in jobs]
        run_on_ray(work, slim, self.address, on_done, on_crash, num_cpus=self.num_cpus, initializer=install_run_plan, shared=self.plan)


def executor_for(name: ExecutorName, jobs: int, ray_address: str | None, plan: Plan) -> Executor:
    """The executor the command line asked for."""
    if name == "ray":
        return RayExecutor(ray_address, jobs, plan)
    return LocalExecutor(jobs, plan)
