"""The local executor's worker processes: they leave pandas out when the run's own process does."""

from __future__ import annotations

import os
import sys
import time

import numpy as np
import pyarrow as pa

from urdf_pipeline import PandasLeftOut
from urdf_pipeline.dataset.local_executor import run_locally


def _pandas_after_an_array(job: int) -> tuple[int, bool]:
    time.sleep(0.2)  # long enough that the workers, not only this process, take jobs
    pa.array(np.zeros(3))  # pyarrow's first numpy array imports pandas when it can
    return os.getpid(), "pandas" in sys.modules


def test_workers_leave_pandas_out_as_the_run_does() -> None:
    finder = PandasLeftOut()
    sys.meta_path.insert(0, finder)  # type: ignore[arg-type]
    results: list[tuple[int, bool]] = []
    try:
        run_locally(
            _pandas_after_an_array,
            list(range(16)),
            2,
            lambda job, result: results.append(result),
            lambda job, error: results.append((0, True)),
        )
    finally:
        sys.meta_path.remove(finder)  # type: ignore[arg-type]
    in_workers = [loaded for pid, loaded in results if pid != os.getpid()]
    assert len(results) == 16 and in_workers
    assert not any(in_workers)
