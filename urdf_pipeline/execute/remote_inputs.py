"""A segment's remote inputs made local before its sources open: each `s3://` file the plan names (a parquet, CSV,
MCAP, HDF5 or .rrd source: any plan whose `remote_of` is set) is fetched into this machine's download cache (pinned to
the version that was planned; a Ray worker fetches into its own), its data checks run (compile read only its metadata:
the kind's `check_download`), and the plan's paths point at the cached files while the segment runs. A remote LeRobot
dataset is read from a local view of the files its episode needs (`sources.local_dataset`)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import replace

from ..plan import FileSourcePlan, LeRobotSourcePlan, RecordingPlan, SourcePlan, remote_of, with_local_path
from ..remote import fetched
from ..sources import local_dataset, module_for


@contextmanager
def local_inputs(plan: RecordingPlan) -> Iterator[RecordingPlan]:
    """`plan` with every remote source's `path` its cached file, held in the cache until the block ends."""
    if not any(getattr(source, "remote", None) is not None for source in plan.sources):
        yield plan
        return
    with ExitStack() as held:
        sources: list[SourcePlan] = []
        for source in plan.sources:
            if isinstance(source, LeRobotSourcePlan) and source.remote is not None:
                dataset = held.enter_context(local_dataset(source))
                module_for(dataset).check_download(dataset)
                sources.append(dataset)
                continue
            remote = remote_of(source)
            if remote is None or isinstance(source, LeRobotSourcePlan):
                sources.append(source)
                continue
            local: FileSourcePlan = with_local_path(source, held.enter_context(fetched(remote, source.where)))
            module_for(local).check_download(local)
            sources.append(local)
        yield replace(plan, sources=tuple(sources))
