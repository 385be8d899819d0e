"""Candidate costs (diagnose.cost_order): what the parallel time limit scales with."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import diagnose
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice


def test_a_candidate_that_cannot_be_timed_gets_the_largest_cost(monkeypatch):
    """A candidate not physically valid at its starting values is not simulated; timed at ~0 s its
    fit had the 20 s floor of the adaptive time limit. It gets the largest time measured."""
    ds = prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4,
                                           duration_scale=0.3))
    model = FitResult(ModelChoice("paper"), 1.0, {}, ("mu_s",))
    real = diagnose.physically_valid

    def valid(choice, fns):
        return "wear" not in choice.label() and real(choice, fns)

    monkeypatch.setattr(diagnose, "physically_valid", valid)
    names, costs = diagnose.cost_order(ds, model, ["stribeck", "wear", "probe_drift"])
    cost = dict(zip(names, costs, strict=True))
    assert cost["stribeck"] > 0 and cost["probe_drift"] > 0
    assert cost["wear"] == pytest.approx(max(cost["stribeck"], cost["probe_drift"]))
    assert costs == sorted(costs, reverse=True)


def test_the_cost_probe_has_the_slip_budget_of_its_own_length(monkeypatch):
    """The probe simulates the first COST_PROBE_S of the first run; its slip budget (read from the
    run's sample count) is the probe's, not the whole run's."""
    ds = prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4,
                                           duration_scale=0.3))
    run = ds.runs[0]
    monkeypatch.setattr(diagnose, "COST_PROBE_S", 1.0)
    seen = []

    def record(spec, probe, bounded=False):
        seen.append((probe.n_samples, bounded, float(probe.drive.t_s[-1])))

    monkeypatch.setattr(diagnose, "simulate_run", record)
    diagnose.cost_order(ds, FitResult(ModelChoice("paper"), 1.0, {}, ("mu_s",)), ["stribeck"])
    assert run.n_samples > 2 * run.sample_rate_hz  # the run is longer than the probe
    assert seen == [(round(run.sample_rate_hz) + 1, True, 1.0)]
