"""A diverging model (residuals of 1e154 and more) scores inf without numpy's overflow warning on
the user's console (it was printed during held-out diagnoses)."""

from __future__ import annotations

import dataclasses
import math
import warnings

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.metrics import score


def test_a_diverging_model_scores_inf_without_a_warning():
    ds = prepare_dataset(simulate_campaign(build_model("paper"), "tlre", seed=4))
    assert math.isfinite(score(ds, [r.events for r in ds.runs]).error)
    diverged = [dataclasses.replace(r.events, features={k: v * 1e170 for k, v in
                                                        r.events.features.items()})
                for r in ds.runs]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert score(ds, diverged).error == math.inf
