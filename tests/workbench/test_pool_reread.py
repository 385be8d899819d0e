"""The screen's re-read of the base levels at an effect's values runs in the search's worker
processes (search_pool.EvaluationPool.reread): the ratio guess of rigctl/workbench/guess.py, one
run of the model at the point, counted in the budget."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import search_pool as sp
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import free_params
from rigctl.workbench.model_choice import ModelChoice

MU_S, MU_K = 0.18, 0.14  # the data's levels; the preset's are 0.15 and 0.10


@pytest.fixture(scope="module")
def dataset():
    model = build_model("paper", params={"mu_s": MU_S, "mu_k": MU_K})
    return prepare_dataset(simulate_campaign(model, "tlre", seed=4, duration_scale=0.6))


@pytest.mark.parametrize("workers", [0, 1])
def test_the_levels_are_re_read_from_the_data_at_the_point(dataset, workers):
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s", "mu_k"])
    table = {p.name: p.value for p in choice.parameter_table()}
    at_preset = sp.Point(np.array([fp.to_u(table[fp.name]) for fp in free]))
    budget = Budget()
    with sp.EvaluationPool(dataset, choice, free, budget, workers) as pool:
        (values,) = pool.reread([at_preset])
    assert budget.used == 1
    assert values is not None
    assert values["mu_s"] == pytest.approx(MU_S, rel=0.05)  # from the preset's 0.15
    assert values["mu_s"] - values["mu_k"] == pytest.approx(MU_S - MU_K, rel=0.25)


def test_a_point_that_cannot_be_run_has_nothing_re_read(dataset):
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s", "mu_k"])
    invalid = sp.Point(np.array([free[0].to_u(0.10), free[1].to_u(0.12)]))  # mu_k above mu_s
    with sp.EvaluationPool(dataset, choice, free, Budget(), 0) as pool:
        assert pool.reread([invalid]) == [None]
