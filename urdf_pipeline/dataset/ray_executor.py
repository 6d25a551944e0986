"""Run jobs as Ray tasks: on a local Ray instance started for the run, or on an existing cluster.

Workers import `work` and the job types by reference, so every node needs `urdf_pipeline` (the same version) and the
same Ray and Python versions as this process: install them in the cluster's environment, or run this CLI through
`ray job submit --runtime-env-json ...` so Ray installs them. A cluster with token authentication needs
`RAY_AUTH_MODE=token` and its token (`RAY_AUTH_TOKEN`, or `~/.ray/auth_token`) in this process's environment.

Starting a local instance, Ray replaces this process's SIGTERM handler with one that kills its processes and exits 1 at
once; the pipeline's handler is put back, so SIGTERM stops a Ray run as Ctrl-C does. Tasks of a local instance make
their temporary files in a folder of the run, removed at the end: Ray kills its workers without running `atexit`.
"""

from __future__ import annotations

import logging
import os
import re
import socket
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, nullcontext
from typing import TYPE_CHECKING, Any, TypeVar

from ..errors import UserError
from ..process import sigterm_kept
from .cpus import usable_cpus

if TYPE_CHECKING:
    from ray import ObjectRef

J = TypeVar("J")
R = TypeVar("R")

CONNECT_TIMEOUT = 5.0  # seconds; Ray itself retries an unreachable address for over five minutes
STOP_GRACE = 5.0  # seconds that interrupted tasks get to run their cleanup before their workers are killed
_ANSI_COLOUR = re.compile(r"\x1b\[[0-9;]*m")


def _call(
    work: Callable[[J], R], job: J, scratch: str | None = None, initializer: Callable[[Any], None] | None = None, shared: Any = None
) -> R:
    """The task body; top-level so Ray pickles it by reference. `shared` (the run's plan) came through Ray's object
    store, put there once by the driver (a top-level ObjectRef argument: Ray hands the task its value), and
    `initializer(shared)` installs it for `work`: a job does not carry the whole plan with every segment in it."""
    if scratch is not None and os.path.isdir(scratch):
        tempfile.tempdir = scratch  # a worker of the run's own local instance: the driver removes the folder
    if initializer is not None:
        initializer(shared)
    return work(job)


def run_on_ray(
    work: Callable[[J], R],
    jobs: Sequence[J],
    address: str | None,
    on_done: Callable[[J, R], None],
    on_crash: Callable[[J, BaseException], None],
    num_cpus: int | None = None,
    initializer: Callable[[Any], None] | None = None,
    shared: Any = None,
) -> None:
    """Call `on_done` for each job as its task finishes; `on_crash` when `work` raised (a bug) or its worker died.
    `initializer(shared)` runs in the task before `work`; `shared` goes to the cluster once (`ray.put`).

    `address` None starts a local instance with `num_cpus` (default: all cores) and stops it afterwards; otherwise
    connect to `auto`, `host:port` or `ray://host:port` and only disconnect. Ctrl-C (or an exception from a callback)
    cancels the tasks still pending or running, lets running ones handle the KeyboardInterrupt, and re-raises.
    """
    try:
        import ray
    except ImportError:
        raise UserError("the ray executor needs Ray: pip install 'urdf-pipeline[ray]'", None) from None
    if not jobs:
        return
    scratch = tempfile.TemporaryDirectory(prefix="urdf-pipeline-run-", ignore_cleanup_errors=True) if address is None else nullcontext()
    with scratch as folder:
        _run_tasks(ray, work, jobs, address, on_done, on_crash, num_cpus, folder, (initializer, shared))


def _run_tasks(
    ray: Any,
    work: Callable[[J], R],
    jobs: Sequence[J],
    address: str | None,
    on_done: Callable[[J, R], None],
    on_crash: Callable[[J, BaseException], None],
    num_cpus: int | None,
    scratch: str | None,
    setup: tuple[Callable[[Any], None] | None, Any],
) -> None:
    _connect(ray, address, num_cpus)
    try:
        task: Any = ray.remote(num_cpus=1, max_retries=0)(_call)  # a crashed segment is reported, not silently run again
        initializer, shared = setup
        shared_ref = ray.put(shared) if initializer is not None else None
        pending: dict[ObjectRef[Any], J] = {task.remote(work, job, scratch, initializer, shared_ref): job for job in jobs}
        try:
            while pending:
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    job = pending.pop(ref)
                    try:
                        result = ray.get(ref)
                    except ray.exceptions.RayError as error:
                        on_crash(job, _cause(error))
                    else:
                        on_done(job, result)
        except BaseException:
            _cancel(ray, list(pending))
            raise
    finally:
        ray.shutdown()  # stops a local instance; for a cluster it only disconnects this driver


def _connect(ray: Any, address: str | None, num_cpus: int | None) -> None:
    """`ray.init`, with Ray's log noise kept off stderr and connection failures as user errors that name the address."""
    # Task output stays in Ray's logs (/tmp/ray/session_latest/logs on each node): results carry what matters, and
    # Ray would print it to this process's stdout, where `run` lists the files it wrote.
    options: dict[str, Any] = {"logging_level": logging.WARNING, "log_to_driver": False}
    if address is None:
        # "local", not None: None would join a cluster named by RAY_ADDRESS or the last `ray start` on this machine
        options |= {"address": "local", "num_cpus": num_cpus or usable_cpus(), "include_dashboard": False}
        what = "could not start a local Ray instance"
    else:
        if address != "auto":
            _check_reachable(address)
        options["address"] = address
        what = f"could not connect to the Ray cluster at {address}"
    try:
        with _quiet_token_notice(), sigterm_kept():  # Ray replaces the SIGTERM handler
            ray.init(**options)
    except BaseException as error:
        ray.shutdown()  # what a Ctrl-C or a failure left half started
        if isinstance(error, Exception):  # ConnectionError, ValueError (address format, ray[client] missing), RuntimeError, ...
            raise UserError(f"{what}: {error}{_auth_hint(address, error)}", None) from error
        raise


def _auth_hint(address: str | None, error: Exception) -> str:
    """Ray's message for a rejected token is only "Failed to connect"; the missing setting is the likely cause."""
    if address is None or not isinstance(error, ConnectionError) or os.environ.get("RAY_AUTH_MODE") == "token":
        return ""
    return " (a cluster with token authentication also needs RAY_AUTH_MODE=token and RAY_AUTH_TOKEN in this environment)"


def _check_reachable(address: str) -> None:
    """Fail in seconds when nothing listens at `address`: `ray.init` would wait for minutes."""
    host, _, port = address.removeprefix("ray://").rpartition(":")
    host = host.strip("[]")  # [::1]:6379
    if not host or not port.isdigit():
        raise UserError(f"not a Ray address: {address!r}; expected host:port, ray://host:port or auto", None)
    try:
        socket.create_connection((host, int(port)), timeout=CONNECT_TIMEOUT).close()
    except OSError as error:
        reason = "timed out" if isinstance(error, TimeoutError) else (error.strerror or str(error))
        raise UserError(f"could not connect to the Ray cluster at {address}: {reason}", None) from error


@contextmanager
def _quiet_token_notice() -> Iterator[None]:
    """Ray >= 2.59 logs a warning on every local start that it enabled token authentication: news, not a problem."""
    logger = logging.getLogger("ray._private.authentication.authentication_token_setup")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _cause(error: BaseException) -> BaseException:
    """The exception `work` raised, with the worker's traceback as a note; Ray's own errors (a worker died) as they are."""
    cause = getattr(error, "cause", None)
    if not isinstance(cause, BaseException):
        return error
    remote = _ANSI_COLOUR.sub("", str(error)).strip()  # "ray::_call() (pid=..., ip=...)" and the traceback
    if remote:
        cause.add_note(remote)
    return cause


def _cancel(ray: Any, refs: list[ObjectRef[Any]]) -> None:
    """Cancel tasks: a running one gets a KeyboardInterrupt so its cleanup runs; stragglers are killed after a grace period."""
    if not refs:
        return
    for ref in refs:
        ray.cancel(ref, force=False)
    _, running = ray.wait(refs, num_returns=len(refs), timeout=STOP_GRACE)
    for ref in running:
        ray.cancel(ref, force=True)
    if running:
        ray.wait(running, num_returns=len(running), timeout=STOP_GRACE)  # so the caller's cleanup comes after the kills
