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


def test_the_fork_server_ignores_ctrl_c_and_sigterm_from_its_first_instruction() -> None:
    """A terminal's Ctrl-C reaches the whole process group, the fork server too, while it imports Rerun: it must
    ignore SIGINT and SIGTERM from its start (inherited across exec), or it prints a traceback. Linux: /proc."""
    import subprocess

    code = (
        "import multiprocessing, re\n"
        "from urdf_pipeline.dataset.local_executor import PRELOAD, _start_fork_server\n"
        "multiprocessing.get_context('forkserver').set_forkserver_preload(PRELOAD)\n"
        "_start_fork_server()\n"
        "from multiprocessing import forkserver\n"
        "status = open(f'/proc/{forkserver._forkserver._forkserver_pid}/status').read()\n"
        "print(int(re.search(r'SigIgn:\\s*([0-9a-f]+)', status).group(1), 16))\n"
    )
    ignored = int(subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout)
    assert ignored & (1 << (2 - 1)) and ignored & (1 << (15 - 1)), f"SigIgn {ignored:x}: SIGINT and SIGTERM must be ignored"
