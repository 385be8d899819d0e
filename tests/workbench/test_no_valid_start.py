"""A candidate with no physically valid start on the model is reported switched off at once (on the
ENS record's base fit `stribeck` was invalid at every scan point, and its fit ran into the 300 s
time limit)."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import fitting
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.fitting import SWITCHED_OFF, CandidateTask, fit_candidate
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)


def test_a_candidate_invalid_at_every_scan_point_is_switched_off_without_a_fit(monkeypatch):
    ds = prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4,
                                           duration_scale=0.3))
    choice = ModelChoice("paper")
    score = evaluate(ds, choice).score
    base = FitResult(choice, score.error, score.feature_error, ("mu_s", "mu_k"))
    real = fitting.physically_valid

    def valid(c, fns):
        return "stribeck" not in c.label() and real(c, fns)

    monkeypatch.setattr(fitting, "physically_valid", valid)
    res = fit_candidate(CandidateTask(ds, base, "stribeck"))
    assert res.message.startswith(SWITCHED_OFF) and "no physically valid start" in res.message
    assert res.error == base.error and res.n_evaluations == 0
    # a valid candidate is still fitted
    monkeypatch.setattr(fitting, "physically_valid", real)
    assert fit_candidate(CandidateTask(ds, base, "stribeck")).n_evaluations > 0
