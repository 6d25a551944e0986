"""Run jobs on this machine: in the main process for one worker, else in a pool of worker processes.

Workers are forked from a fork server that imported Rerun and the pipeline once (a worker is up in milliseconds, not
the second `spawn` takes to import them), and that never ran Rerun code, so no Rerun thread is forked. Workers ignore
SIGINT: on Ctrl-C the main process cancels what has not started and terminates the workers, and the caller removes
their partial files, so only complete outputs remain.
"""

from __future__ import annotations

import multiprocessing
import signal
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from typing import TypeVar

PRELOAD = ["urdf_pipeline.segment_run", "urdf_pipeline.execute", "rerun.chunk", "rerun.urdf", "rerun.experimental"]
J = TypeVar("J")
R = TypeVar("R")


def start_fork_server() -> None:
    """Start the fork server now, in the background: its imports (~0.7 s) overlap with compiling the config and
    hashing the inputs instead of delaying the first job."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    from multiprocessing import forkserver

    forkserver.ensure_running()


def _start_worker(initializer: Callable[..., None] | None, initargs: tuple[object, ...]) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if initializer is not None:
        initializer(*initargs)


def run_locally(
    work: Callable[[J], R],
    jobs: Sequence[J],
    workers: int,
    on_done: Callable[[J, R], None],
    on_crash: Callable[[J, BaseException], None],
    initializer: Callable[..., None] | None = None,
    initargs: tuple[object, ...] = (),
) -> None:
    """Call `on_done` for each job as it finishes; `on_crash` when its worker died or `work` raised (a bug).

    `initializer(*initargs)` runs once in each worker process (or in this one, when it runs the jobs itself). At most two jobs per worker are queued at a time, so an interrupted run has little to unwind.
    """
    if workers <= 1 or len(jobs) <= 1:
        if initializer is not None:
            initializer(*initargs)
        for job in jobs:
            on_done(job, work(job))
        return
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    workers = min(workers, len(jobs))
    pool = ProcessPoolExecutor(workers, mp_context=context, initializer=_start_worker, initargs=(initializer, initargs))
    pending: dict[Future[R], J] = {}
    queue = list(reversed(jobs))
    try:
        while queue or pending:
            while queue and len(pending) < 2 * workers:
                job = queue.pop()
                pending[pool.submit(work, job)] = job
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                job = pending.pop(future)
                error = future.exception()
                if error is None:
                    on_done(job, future.result())
                else:
                    on_crash(job, error)
    except BaseException:
        for future in pending:
            future.cancel()
        _terminate(pool)
        raise
    pool.shutdown(wait=True)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop the workers now: a job in flight is abandoned and its partial file removed by the caller."""
    processes = list((getattr(pool, "_processes", None) or {}).values())  # no public API lists a pool's processes
    call_queue = getattr(pool, "_call_queue", None)
    if call_queue is not None:
        call_queue.cancel_join_thread()  # its feeder may be blocked writing to a dead worker: exiting must not wait for it
    for process in processes:
        if process.is_alive():
            process.terminate()
    for process in processes:
        process.join(timeout=10)
    pool.shutdown(wait=False, cancel_futures=True)
