"""Evidence, significance and verdicts from given fit results (no fitting here)."""

from __future__ import annotations

import math

import pytest

from rigctl.workbench.ranking import (
    CandidateScore,
    delta_bic,
    rank,
    score_candidate,
    suggest_protocol,
    verdict,
)


def test_delta_bic_is_n_log_error_ratio_plus_the_parameter_penalty():
    assert delta_bic(4.0, 2.0, 100, 2) == pytest.approx(100 * math.log(0.25) + 2 * math.log(100))
    assert delta_bic(4.0, 4.0, 50, 1) == pytest.approx(math.log(50))


def test_a_tiny_improvement_does_not_earn_its_parameters():
    s = score_candidate("x", 1.00, 0.99, 40, 2)
    assert s.delta_bic > 0 and not s.significant


def test_a_large_improvement_is_significant_and_ranks_first():
    scores = [score_candidate("a", 5.0, 4.9, 60, 1), score_candidate("b", 5.0, 1.0, 60, 2),
              score_candidate("c", 5.0, 6.0, 60, 1)]
    ranked = rank(scores)
    assert [s.effect for s in ranked] == ["b", "a", "c"]
    assert ranked[0].significant and not ranked[1].significant
    assert ranked[0].error_reduction == pytest.approx(0.8)
    assert verdict(ranked).verdict == "b"


def test_significant_needs_ten_percent_less_error_even_with_many_events():
    s = score_candidate("x", 1.0, 0.93, 5000, 1)
    assert s.delta_bic < -10 and not s.significant


def test_none_when_nothing_is_significant():
    v = verdict(rank([score_candidate("a", 2.0, 1.95, 30, 2)]))
    assert v.verdict == "none" and v.candidates == [] and v.suggest is None


def test_indistinguishable_names_the_candidates_and_the_protocols_that_separate_them():
    ranked = rank([score_candidate("rate_state", 6.0, 2.0, 50, 2),
                   score_candidate("stribeck", 6.0, 2.05, 50, 1),
                   score_candidate("wear", 6.0, 5.9, 50, 2)])
    v = verdict(ranked, protocols_present=["velocity steps"])
    assert v.verdict == "indistinguishable"
    assert set(v.candidates) == {"rate_state", "stribeck"}
    assert v.suggest is not None
    assert "slide-hold-slide" in v.suggest and "velocity steps" in v.suggest


def test_failed_fits_rank_last_and_are_never_significant():
    failed = score_candidate("broken", 3.0, math.nan, 30, 0)
    ranked = rank([failed, score_candidate("ok", 3.0, 2.9, 30, 1)])
    assert ranked[-1].effect == "broken" and not failed.significant


def test_suggestion_falls_back_to_generic_advice_for_unknown_effects():
    assert "normal force" in suggest_protocol(["no_such_effect"])


def test_json_of_a_score_has_the_contract_keys():
    s = CandidateScore("wear", 1.0, 0.5, -20.0, True, 2, "peaks vs time")
    assert set(s.to_json()) == {"effect", "error", "error_reduction", "delta_bic", "significant",
                                "explains"}
