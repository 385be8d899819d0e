"""A model that slips far more often than its record can show is not integrated to the end inside
a fit: its simulation stops (evaluate.slip_budget) and the fit counts it as a model that cannot be
run. On the ENS record one presliding candidate chattered through 4.9 million slips (64 s, 2.4 GB)
inside a candidate fit. Outside the fits (compare, overlays) the model runs unbounded."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.model.simulator import SlipBudgetError
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import evaluate as ev
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import Objective, fn_range, free_params
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.start_error import error_or_inf


@pytest.fixture(scope="module")
def dataset():
    return prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4))


def _tight(monkeypatch):
    """A budget below the record's own slips."""
    monkeypatch.setattr(ev, "MODEL_SLIPS_MIN", 0)
    monkeypatch.setattr(ev, "MODEL_SLIPS_PER_SAMPLE", 1e-6)


def test_the_budget_follows_the_record_s_length(dataset, monkeypatch):
    run = dataset.runs[0]
    assert ev.slip_budget(run) == max(ev.MODEL_SLIPS_MIN, ev.MODEL_SLIPS_PER_SAMPLE * run.n_samples)
    spec = ModelChoice("paper").build()
    assert len(ev.simulate_run(spec, run, bounded=True).events) >= 5  # far below the budget
    _tight(monkeypatch)
    with pytest.raises(SlipBudgetError, match="global slips by t = "):
        ev.simulate_run(spec, run, bounded=True)
    # unbounded outside the fits
    assert len(ev.simulate_run(spec, run).events) >= 5
    assert math.isfinite(ev.evaluate(dataset, spec).score.error)


def test_a_model_over_the_budget_is_a_failed_evaluation_not_a_crash(dataset, monkeypatch):
    choice = ModelChoice("paper")
    fns = fn_range(dataset)
    assert math.isfinite(error_or_inf(dataset, choice, fns))
    obj = Objective(dataset, choice, free_params(choice, ["mu_s", "mu_k"]))
    table = {p.name: p.value for p in choice.parameter_table()}
    u = np.array([fp.to_u(table[fp.name]) for fp in obj.free])
    first = obj(u)  # a fit's start, within the budget
    _tight(monkeypatch)
    assert error_or_inf(dataset, choice, fns) == math.inf
    # a later step of the fit that goes over the budget gets the failure penalty
    step = u * 1.001
    vec = obj(step)
    assert obj.failed(step) and not obj.failed(u)
    assert vec.shape == first.shape and np.all(np.isfinite(vec))
    assert float(vec @ vec) > float(first @ first)


def test_a_fit_whose_start_is_over_the_budget_still_has_its_residual_length(dataset, monkeypatch):
    _tight(monkeypatch)
    choice = ModelChoice("paper")
    obj = Objective(dataset, choice, free_params(choice, ["mu_s", "mu_k"]))
    table = {p.name: p.value for p in choice.parameter_table()}
    vec = obj(np.array([fp.to_u(table[fp.name]) for fp in obj.free]))
    assert vec.shape[0] > 0 and np.all(np.isfinite(vec))
