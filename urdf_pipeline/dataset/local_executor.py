"""Run jobs on this machine: in the main process for one worker, else in a pool of worker processes.

Workers are forked from a fork server that imported Rerun and the pipeline once (a worker is up in milliseconds) and
never ran Rerun code, so no Rerun thread is forked. Workers ignore SIGINT and SIGTERM (a terminal's signal reaches the
whole process group): the main process cancels what has not started and kills the workers, and the caller removes
their partial files. A worker exits as soon as the main process is gone, even killed with SIGKILL (it would otherwise
wait forever, and keep the fork server alive). Workers make their temporary files in a folder of the run that the
main process removes: a pool worker exits without running `atexit` handlers.
"""

from __future__ import annotations

import multiprocessing
import os
import select
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing.process import BaseProcess
from typing import TypeVar

from ..execute import process_alive
from ..package import PandasLeftOut
from ..process import deferred_signals, held_off, ignore_stop_signals

PRELOAD = ["urdf_pipeline.execute.segment_run", "urdf_pipeline.execute.segment", "rerun.chunk", "rerun.urdf", "rerun.experimental"]
POLL_SECONDS = 0.2  # how soon a Ctrl-C or SIGTERM is acted on while waiting for the workers
J = TypeVar("J")
R = TypeVar("R")


def _start_fork_server() -> None:
    """Started with SIGINT and SIGTERM ignored (a disposition that survives exec, unlike a blocked mask): the fork
    server imports Rerun before it could ignore a terminal's Ctrl-C itself, and would print a traceback from the
    middle of an import. A Ctrl-C in those few milliseconds is lost, not half-handled."""
    from multiprocessing import forkserver

    with held_off(ignored=True):
        forkserver.ensure_running()


def _start_worker(
    initializer: Callable[..., None] | None,
    initargs: tuple[object, ...],
    scratch: str,
    main: int,
    no_pandas: bool,
    environment: dict[str, str],
) -> None:
    # The fork server keeps the environment it was started with (an earlier run of this process, in a notebook or a
    # test session); a worker runs with the run's own (credentials' chains, the allow lists, the caches' folders).
    os.environ.clear()
    os.environ.update(environment)
    if no_pandas and not PandasLeftOut.installed():  # as in the run's own process: pyarrow's first array would import it
        sys.meta_path.insert(0, PandasLeftOut())
    ignore_stop_signals()
    threading.Thread(target=_exit_with, args=(main,), name="urdf-pipeline-watch-main", daemon=True).start()
    tempfile.tempdir = scratch  # removed by the main process, even when this worker is killed
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

    This process runs jobs itself until the fork server has started the workers (about 0.7 s of imports), then
    leaves the jobs to them: a small dataset is not slower with more workers. `initializer(*initargs)` runs once in
    each worker process and here. At most two jobs per worker process are queued at a time, so an interrupted run
    has little to unwind.
    """
    if initializer is not None:
        initializer(*initargs)
    helpers = min(workers, len(jobs)) if workers > 1 and len(jobs) > 1 else 0  # one job: this process, no pool
    if helpers < 1:
        for job in jobs:
            _run_here(work, job, on_done, on_crash)
        return
    with tempfile.TemporaryDirectory(prefix="urdf-pipeline-run-", ignore_cleanup_errors=True) as scratch:
        _run_in_pool(work, jobs, helpers, on_done, on_crash, initializer, initargs, scratch)


def _run_in_pool(
    work: Callable[[J], R],
    jobs: Sequence[J],
    helpers: int,
    on_done: Callable[[J, R], None],
    on_crash: Callable[[J, BaseException], None],
    initializer: Callable[..., None] | None,
    initargs: tuple[object, ...],
    scratch: str,
) -> None:
    pool, ready = _start_pool(helpers, initializer, initargs, scratch)  # until `ready`, this process works alone
    pending: dict[Future[R], J] = {}
    queue = list(reversed(jobs))
    try:
        while queue or pending:
            with deferred_signals() as stop:  # no signal raised inside the pool's locks: see process/signals.py
                while ready.is_set() and queue and len(pending) < 2 * helpers:
                    job = queue.pop()
                    pending[pool.submit(work, job)] = job
                done = [future for future in pending if future.done()]
                run_here = bool(queue) and not ready.is_set()
                while not done and not run_here and pending and not stop:  # a signal ends the wait within POLL_SECONDS
                    done = list(wait(pending, timeout=POLL_SECONDS, return_when=FIRST_COMPLETED)[0])
                finished = _outcomes(pending, done)
            for job, result, error in finished:  # our callbacks: interruptible as any of our code
                if error is None:
                    on_done(job, result)  # type: ignore[arg-type]
                else:
                    on_crash(job, error)
            if run_here:
                _run_here(work, queue.pop(), on_done, on_crash)
    except BaseException:  # futures are not cancelled one by one: Python 3.11's pool then fails on them (InvalidStateError)
        _terminate(pool)
        raise
    if ready.is_set():
        with deferred_signals():
            pool.shutdown(wait=True)
    else:  # every job was done here before the workers came up: they are not needed
        _terminate(pool)


def _start_pool(
    helpers: int, initializer: Callable[..., None] | None, initargs: tuple[object, ...], scratch: str
) -> tuple[ProcessPoolExecutor, threading.Event]:
    """The pool of `helpers` workers forked from the fork server, and an event set once they are up: they are started
    in a thread, which blocks until the fork server has imported Rerun, so this process works meanwhile."""
    context = multiprocessing.get_context("forkserver")
    context.set_forkserver_preload(PRELOAD)
    _start_fork_server()
    pool = ProcessPoolExecutor(
        helpers,
        mp_context=context,
        initializer=_start_worker,
        initargs=(initializer, initargs, scratch, os.getpid(), PandasLeftOut.installed(), dict(os.environ)),
    )
    ready = threading.Event()

    def start_workers() -> None:
        try:
            wait([pool.submit(_started) for _ in range(helpers)])
        except (RuntimeError, BrokenProcessPool):  # the run ended first (all done here, Ctrl-C): the pool is shut down
            pass
        finally:
            ready.set()

    threading.Thread(target=start_workers, name="urdf-pipeline-start-workers", daemon=True).start()
    return pool, ready


def _outcomes(pending: dict[Future[R], J], done: Sequence[Future[R]]) -> list[tuple[J, R | None, BaseException | None]]:
    """(job, result, error) of finished futures, taken out of `pending` (reading a future takes its lock)."""
    taken = []
    for future in done:
        job, error = pending.pop(future), future.exception()
        taken.append((job, None if error is not None else future.result(), error))
    return taken


def _started() -> None:
    """A no-op task: its completion says a worker process is up."""


def _exit_with(main: int) -> None:
    """A worker's watch: end this process when the main process `main` is gone, so no worker outlives a killed run."""
    try:
        handle = os.pidfd_open(main)  # Linux: readable once the process has exited, no polling
    except ProcessLookupError:
        os._exit(1)
    except (AttributeError, OSError):  # another system: look once a second
        while process_alive(main):
            time.sleep(1.0)
        os._exit(1)
    select.select([handle], [], [])
    os._exit(1)


def _run_here(work: Callable[[J], R], job: J, on_done: Callable[[J, R], None], on_crash: Callable[[J, BaseException], None]) -> None:
    try:
        result = work(job)
    except Exception as error:  # a bug in `work`: reported for this job, like one raised in a worker process
        on_crash(job, error)
    else:
        on_done(job, result)


def _terminate(pool: ProcessPoolExecutor) -> None:
    """Stop the workers now (SIGKILL: they ignore SIGTERM): a job in flight is abandoned and its partial file removed by
    the caller.

    A worker still being started (by a `submit` of `start_workers`, which waits for the fork server) is not listed
    yet: `shutdown` waits for that `submit`, no worker is started after it, and the ones listed then are killed too.
    One left alive would hang this process at exit: the pool's manager thread joins every worker (after a SIGTERM,
    which they ignore), and the interpreter joins that thread (seen after SIGTERM came while the workers started)."""
    processes = getattr(pool, "_processes", None)  # the pool's own dict, kept: shutdown forgets it; no public API lists them
    call_queue = getattr(pool, "_call_queue", None)
    if call_queue is not None:
        call_queue.cancel_join_thread()  # its feeder may be blocked writing to a dead worker: exiting must not wait for it
    _kill(processes)  # at once: no worker goes on writing
    pool.shutdown(wait=False, cancel_futures=True)
    _kill(processes)  # and any started meanwhile


def _kill(processes: dict[int, BaseProcess] | None) -> None:
    listed = list((processes or {}).values())
    for process in listed:
        if process.is_alive():
            process.kill()
    for process in listed:
        process.join(timeout=10)
