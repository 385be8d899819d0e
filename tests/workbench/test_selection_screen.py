"""The screen of forward selection (rigctl/workbench/selection.py) with real short fits: on a small
generated campaign with one hidden library effect, the sets it keeps for the full fit contain the
generating effect."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench import selection as sel
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, simulate_campaign
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import search_model
from tests.workbench.hidden import DECOYS, MAGNITUDE, TEST_BASE, scaled_values

SHORT_FIT_EVALUATIONS = 60
"""The screen's budget: the search's starts (about 20 at ten coordinates) and two to three
Jacobians of its polish, no global stage: a short fit ranks candidates, it does not finish them."""


def _short_fit(dataset: Dataset, choice: ModelChoice) -> FitResult:
    return search_model(dataset, choice, budget=Budget(max_evaluations=SHORT_FIT_EVALUATIONS),
                        workers=2, with_uncertainty=False)


@pytest.mark.slow  # a base fit and six short fits: about a minute on two loaded cores
def test_the_screen_keeps_the_hidden_effect():
    hidden = "load_dependent_friction"
    model = build_model("paper", effects=[hidden], params=TEST_BASE,
                        effect_params={hidden: scaled_values(hidden, MAGNITUDE)})
    runs = simulate_campaign(model, PROTOCOL_FOR_EFFECT[hidden], seed=3, velocity_m_s=2e-5,
                             duration_scale=0.3)
    dataset = prepare_dataset(runs)
    base = _short_fit(dataset, ModelChoice("paper"))
    # the hidden effect, the effects of similar signature, and two of other signatures: half the
    # pool is dropped, so keeping the hidden one is not chance
    pool = [hidden, *DECOYS[hidden], "stribeck", "presliding"]
    assert len(pool) == 2 * sel.SCREEN_KEEP
    ranked = sel.screen_sets(dataset, base, [(c,) for c in pool], screen=_short_fit)
    kept = [s.effects for s in ranked[: sel.SCREEN_KEEP]]
    assert (hidden,) in kept, ranked
