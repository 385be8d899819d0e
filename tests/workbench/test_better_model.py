"""A candidate's gain that is the model's own unfinished fit is given back to the model
(diagnose.better_model), not credited to the candidate."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.model.effects import LIBRARY
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.diagnose import better_model
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)

TRUTH = {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
         "mu_smax": 0.21, "kt0_N_per_m": 1.7e6, "p_slope": 0.8}
FREE = ("mu_s", "mu_k", "k0_N_per_m", "kts_N_per_m", "kt0_N_per_m", "mu_smax", "p_slope")


@pytest.fixture(scope="module")
def tlre() -> Dataset:
    return prepare_dataset(simulate_campaign(build_model("paper", params=TRUTH), "tlre", seed=12))


def _result(ds: Dataset, choice: ModelChoice) -> FitResult:
    score = evaluate(ds, choice).score
    return FitResult(choice, score.error, score.feature_error, FREE)


def _with_wear_off(choice: ModelChoice) -> ModelChoice:
    offs = LIBRARY["wear"]().off_values({"mu_s": TRUTH["mu_s"], "kts_N_per_m": TRUTH["kts_N_per_m"]})
    return choice.with_effect("wear").with_values({f"wear.{k}": v for k, v in offs.items()})


def test_a_candidate_whose_gain_is_the_models_own_fit_gives_it_back(tlre: Dataset) -> None:
    stuck = _result(tlre, ModelChoice("paper").with_values({**TRUTH, "mu_k": 0.128}))
    # the candidate's fit found the model's own better point, its effect switched off
    cand = _result(tlre, _with_wear_off(ModelChoice("paper").with_values(TRUTH)))
    assert cand.error < 0.5 * stuck.error
    better = better_model(tlre, stuck, {"wear": cand})
    assert better is not None
    assert better.choice.effects == ()
    assert better.error <= cand.error * 1.05
    assert "wear" in better.message


def test_a_gain_the_effect_itself_makes_is_left_to_the_candidate(tlre: Dataset) -> None:
    model = _result(tlre, ModelChoice("paper").with_values({**TRUTH, "mu_k": 0.128}))
    # the candidate's base values are the model's: without the effect it is the model again
    cand_choice = _with_wear_off(model.choice)
    cand = FitResult(cand_choice, 0.5 * model.error, {}, FREE)
    assert better_model(tlre, model, {"wear": cand}) is None
    # a candidate that did not improve is not looked at
    assert better_model(tlre, model, {"wear": FitResult(cand_choice, model.error, {}, FREE)}) is None


def test_a_candidates_fit_from_before_the_refit_is_kept_where_it_is_better() -> None:
    """After better_model refits the model, the round is run again from the new model; a
    candidate whose new fit ends worse than its fit in the first pass keeps the first one."""
    from rigctl.workbench.diagnose import keep_better
    from rigctl.workbench.parallel import TaskFailed

    before = FitResult(ModelChoice("paper").with_effect("wear"), 1.01, {}, FREE)
    after = FitResult(ModelChoice("paper").with_effect("wear"), 3.25, {}, FREE)
    kept = keep_better(after, before)
    assert isinstance(kept, FitResult) and kept.error == 1.01
    assert "kept from before the refit" in kept.message
    assert before.message == ""  # the carried fit itself is not changed
    assert keep_better(before, after) is before  # the new fit is better: it stays
    assert keep_better(after, None) is after
    failed = TaskFailed("worker died")
    assert keep_better(failed, before).error == 1.01  # type: ignore[union-attr]
    # a carried fit that misses most slips is a trap, never kept
    trap = FitResult(before.choice, 0.5, {}, FREE, misses_most_slips=True)
    assert keep_better(after, trap) is after


def test_the_progress_line_says_when_the_fit_from_before_is_kept(
        tlre: Dataset, monkeypatch: pytest.MonkeyPatch) -> None:
    from rigctl.workbench import diagnose

    model = _result(tlre, ModelChoice("paper").with_values(TRUTH))
    before = _result(tlre, _with_wear_off(model.choice))
    after = FitResult(before.choice, before.error + 1.0, {}, FREE)

    def fake_run_tasks(fn: object, tasks: list[object], **kw: object) -> list[FitResult]:
        kw["on_done"](0, after)  # type: ignore[operator]
        return [after]

    monkeypatch.setattr(diagnose, "run_tasks", fake_run_tasks)
    lines: list[str] = []
    rnd = diagnose.run_round(tlre, model, ["wear"], workers=1, scheduler=None,
                             progress=lines.append, carried={"wear": before})
    fitted = [line for line in lines if "fitted wear" in line]
    assert len(fitted) == 1
    assert f"error {after.error:.3g}" in fitted[0]
    assert f"keeps its fit from before the refit, error {before.error:.3g}" in fitted[0]
    assert rnd.fits["wear"].error == before.error
