"""Local worker processes run one BLAS thread each: the workers are the parallelism (issue 34)."""

from __future__ import annotations

import numpy  # noqa: F401  (its BLAS: the pool the test reads)
from threadpoolctl import threadpool_info, threadpool_limits

from rigctl.workbench.parallel import run_tasks


def blas_threads(_: int) -> int:
    """The most threads any BLAS library loaded in this process would use."""
    return max(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas")


def test_each_local_worker_runs_one_blas_thread() -> None:
    with threadpool_limits(2):  # the parent's pool: 2 threads, which a forked worker inherits
        assert blas_threads(0) == 2
        assert run_tasks(blas_threads, [0, 1, 2], workers=2) == [1, 1, 1]
        assert blas_threads(0) == 2  # the parent's own pool is left as it was
