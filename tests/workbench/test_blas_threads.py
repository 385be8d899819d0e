"""The search's worker processes run one BLAS thread each: the workers are the parallelism
(issue 34; rigctl.workbench.search_pool)."""

from __future__ import annotations

import numpy  # noqa: F401  (its BLAS: the pool the test reads)
from threadpoolctl import threadpool_info, threadpool_limits

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import search_pool as sp
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import free_params
from rigctl.workbench.model_choice import ModelChoice


def blas_threads(_: int) -> int:
    """The most threads any BLAS library loaded in this process would use."""
    return max(pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas")


def test_each_search_worker_runs_one_blas_thread() -> None:
    dataset = prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4,
                                                duration_scale=0.25))
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s"])
    with threadpool_limits(2):  # the parent's pool: 2 threads, which a forked worker inherits
        assert blas_threads(0) == 2
        with sp.EvaluationPool(dataset, choice, free, Budget(), workers=2) as pool:
            assert pool._pool.map(blas_threads, [0, 1, 2]) == [1, 1, 1]
        assert blas_threads(0) == 2  # the parent's own pool is left as it was
