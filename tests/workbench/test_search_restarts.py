"""Restarts of the one search (``search_model(..., restarts=N)``): further passes from the same
given starts with their own random draws, within the one budget, the best pass the answer."""

from __future__ import annotations

import re

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import default_budget, popsize, search_model
from rigctl.workbench.search_space import build_space
from tests.workbench.test_search import FN_N, NOISE, RIG, V_M_S

PAPER = ModelChoice("paper")


@pytest.fixture(scope="module")
def record() -> Dataset:
    """A 15 s TLRE of another rig's scale at 1 kHz that states no mass or damping (their starts
    are guesses, spread by Sobol points)."""
    model = build_model("paper", params=RIG)
    runs = simulate_campaign(model, "tlre", seed=5, noise=NOISE, sample_rate_hz=1000.0,
                             fn_N=FN_N, velocity_m_s=V_M_S, duration_scale=0.25)
    for run in runs:
        for name in ("m_kg", "c0_N_s_per_m"):
            run.metadata.pop(f"rig.{name}", None)
    return prepare_dataset(runs)


@pytest.fixture(scope="module")
def one_pass(record: Dataset) -> FitResult:
    return search_model(record, PAPER, workers=2, with_uncertainty=False)


@pytest.fixture(scope="module")
def three(record: Dataset) -> tuple[FitResult, Budget]:
    budget = default_budget(build_space(record, PAPER, PAPER, False).dim)
    return search_model(record, PAPER, workers=2, with_uncertainty=False, restarts=2,
                        budget=budget), budget


def test_restarts_never_end_worse_than_the_first_pass_and_stay_in_the_budget(one_pass, three):
    res, budget = three
    assert "restart 1:" in res.message  # the first pass left the budget for another
    assert res.error <= one_pass.error
    assert res.n_evaluations == budget.used <= budget.max_evaluations


def test_a_restart_reuses_the_given_starts_and_draws_only_its_own(record, three):
    res, _ = three
    dim = build_space(record, PAPER, PAPER, False).dim
    sobol = 1 << max(1, (popsize(dim) - 1).bit_length())  # a population, to a power of two
    found = re.search(r"restart 1: starts (\d+)", res.message)
    assert found is not None and int(found.group(1)) == sobol


def test_no_restart_is_begun_that_the_budget_cannot_pay_for(record, one_pass):
    budget = Budget(max_evaluations=int(1.5 * one_pass.n_evaluations))
    res = search_model(record, PAPER, workers=2, with_uncertainty=False, restarts=2,
                       budget=budget)
    assert "restart" not in res.message
    assert res.n_evaluations <= budget.max_evaluations
