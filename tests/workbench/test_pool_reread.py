"""The screen's re-read of the base levels at an effect's values (search_pool.Point.reread): the
ratio guess of rigctl/workbench/guess.py, read in the worker from the slips of the point's own
evaluation (no second run of the model), the same values a run of its own gives."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import search_pool as sp
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.guess import initial_guess
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
    at_preset = sp.Point(np.array([fp.to_u(table[fp.name]) for fp in free]), reread=True)
    budget = Budget()
    with sp.EvaluationPool(dataset, choice, free, budget, workers) as pool:
        (out,) = pool.evaluate([at_preset])
    assert budget.used == 1  # one run of the model: the evaluation's
    assert out.status == sp.OK and out.reread is not None
    assert out.reread["mu_s"] == pytest.approx(MU_S, rel=0.05)  # from the preset's 0.15
    assert out.reread["mu_s"] - out.reread["mu_k"] == pytest.approx(MU_S - MU_K, rel=0.25)
    # exactly what a run of the model of its own re-reads
    assert out.reread == initial_guess(dataset, choice, free, bounded=True)


def test_only_the_points_that_ask_are_re_read_and_a_cached_point_is_run_again(dataset):
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s", "mu_k"])
    u = np.array([free[0].to_u(0.16), free[1].to_u(0.11)])
    with sp.EvaluationPool(dataset, choice, free, Budget(), 0) as pool:
        plain, _other = pool.evaluate([sp.Point(u), sp.Point(u + 0.01)])
        assert plain.reread is None
        (again,) = pool.evaluate([sp.Point(u, reread=True)])  # answered from the cache
    direct = initial_guess(dataset, choice.with_values(
        {fp.name: fp.to_p(float(x)) for fp, x in zip(free, u, strict=True)}), free, bounded=True)
    assert again.reread is not None
    assert again.reread == pytest.approx(direct, rel=1e-12)  # the coordinates' round trip


def test_a_point_that_cannot_be_run_has_nothing_re_read(dataset):
    choice = ModelChoice("paper")
    free = free_params(choice, ["mu_s", "mu_k"])
    invalid = sp.Point(np.array([free[0].to_u(0.10), free[1].to_u(0.12)]), reread=True)
    with sp.EvaluationPool(dataset, choice, free, Budget(), 0) as pool:
        (out,) = pool.evaluate([replace(invalid)])
    assert out.status == sp.FAILED and out.reread is None
