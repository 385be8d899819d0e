"""A control diagnosis in process on a small campaign (the fast tier's end-to-end check of
``diagnose``; the full hidden-effect diagnoses are the slow tier)."""

from __future__ import annotations

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.diagnose import diagnose
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.ranking import VerdictKind

TRUTH = {"mu_s": 0.15, "mu_k": 0.105}


def test_a_control_campaign_gets_the_verdict_none_in_process():
    """Nothing screens or fits significant on the generating model's own data."""
    runs = simulate_campaign(build_model("paper", params=TRUTH), "tlre", seed=5,
                             duration_scale=0.3)
    ds = prepare_dataset(runs)
    diag = diagnose(ds, ModelChoice("paper").with_values(TRUTH), candidates=("wear", "stribeck"),
                    workers=0)
    assert diag.first.verdict.kind is VerdictKind.NONE
    assert [s.effect for s in diag.first.ranking] and not any(
        s.significant for s in diag.first.ranking)
    assert diag.final_model.error < 2.0  # the generating model, within about the scatter
