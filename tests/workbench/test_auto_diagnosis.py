"""A selection told as a diagnosis (rigctl/workbench/auto_diagnosis.py): rounds, the ranking of
fitted and screened sets, and a step per effect added, removed or refitted. The residual maps are
replaced (what is under test is the bookkeeping, not the simulation)."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace
from typing import Any, cast

import pytest

from rigctl.records.dataset import Dataset
from rigctl.workbench import auto_diagnosis as ad
from rigctl.workbench import selection as sel
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.ranking import VerdictKind, score_candidate
from rigctl.workbench.screening import Screened

N = 100
DATASET = cast(Dataset, SimpleNamespace(n_events=N, runs=[], notes=[]))


@pytest.fixture(autouse=True)
def _no_simulation(monkeypatch):
    monkeypatch.setattr(ad, "_map", lambda dataset, model: SimpleNamespace(model=model))
    monkeypatch.setattr(ad, "discrepancies", lambda m: [f"misfit of {m.model.choice.label()}"])
    monkeypatch.setattr(ad, "explain", lambda base, cand, b, c: f"explained by {c.choice.label()}")
    monkeypatch.setattr(ad, "protocols_present", lambda d: ["tlre"])


def fit(effects: tuple[str, ...], error: float) -> FitResult:
    free = ("mu_s", "mu_k", *(f"{e}.p" for e in effects))
    return FitResult(ModelChoice("paper", effects), error, {}, free)


def trial(model: FitResult, effects: tuple[str, ...], error: float) -> sel.Trial:
    res = fit(effects, error)
    name = " + ".join(effects)
    sc = score_candidate(name, model.error, error, N, len(effects))
    return sel.Trial(effects, res, sc, error)


def screened(effects: tuple[str, ...], error: float) -> Screened:
    return Screened(effects, error, 0.0, 12, "spread point")


def test_a_pair_added_is_two_steps_and_a_removal_a_third():
    base = fit((), 10.0)
    t_a, t_b = trial(base, ("a",), 9.4), trial(base, ("b",), 9.6)
    t_ab = trial(base, ("a", "b"), 3.0)
    r1 = sel.Round(base, [screened(("a", "b"), 3.5), screened(("a",), 9.0), screened(("c",), 9.8)],
                   [t_ab, t_a, t_b], t_ab)
    r2 = sel.Round(t_ab.fit, [screened(("c",), 2.95)], [], None)
    final = fit(("b",), 3.05)
    steps = [sel.Step("add", ("a", "b"), 10.0, 3.0, t_ab.score.delta_bic, t_ab.fit),
             sel.Step("remove", ("a",), 3.0, 3.05, 1.0, final)]
    diag = ad.as_diagnosis(DATASET, sel.Selection(base, final, steps, [r1, r2]))
    assert [(s.added, s.error) for s in diag.steps] == [
        (None, 10.0), ("a", 9.4), ("b", 3.0), (None, 3.05)]
    assert diag.steps[1].note.startswith("added with b")
    assert diag.steps[3].note.startswith("removed a")
    assert diag.final_model is final  # a round of its own after the removal
    assert diag.rounds[-1].verdict.kind is VerdictKind.NONE
    first = diag.rounds[0]
    assert first.verdict.verdict == "a + b"
    names = [s.effect for s in first.ranking]
    assert names[0] == "a + b" and names[-1] == "c"  # fitted first, screened only last
    assert not first.ranking[-1].significant and "screened only" in first.ranking[-1].explains
    assert first.ranking[0].explains == "explained by paper + a + b"
    assert set(first.fits) == {"a", "b", "a + b"}
    assert diag.to_json(True)["final_model"] == "paper + b"


def test_the_verdict_s_set_leads_the_ranking():
    # a + b is significant against the model with a lower delta BIC than a alone, but not
    # against a: the verdict is a, and the table must not put a + b above it
    base = fit((), 10.0)
    t_a, t_ab = trial(base, ("a",), 4.0), trial(base, ("a", "b"), 3.8)
    assert t_ab.score.delta_bic < t_a.score.delta_bic
    rnd = sel.Round(base, [screened(("a",), 5.0), screened(("c",), 9.9)], [t_ab, t_a], t_a)
    diag = ad.as_diagnosis(DATASET, sel.Selection(base, base, [], [rnd]))
    assert diag.first.verdict.verdict == "a"
    assert [s.effect for s in diag.first.ranking] == ["a", "a + b", "c"]


def test_a_refit_goes_into_the_step_s_note_and_its_error():
    base = fit((), 10.0)
    refit = fit((), 8.0)
    t_a = trial(refit, ("a",), 4.0)
    r0 = sel.Round(base, [screened(("a",), 6.0)], [trial(base, ("a",), 8.0)], None)
    r1 = sel.Round(refit, [screened(("a",), 5.0)], [t_a], t_a)
    r2 = sel.Round(t_a.fit, [screened(("b",), 3.9)], [], None)
    steps = [sel.Step("refit", (), 10.0, 8.0, -20.0, refit),
             sel.Step("add", ("a",), 8.0, 4.0, t_a.score.delta_bic, t_a.fit)]
    diag = ad.as_diagnosis(DATASET, sel.Selection(base, t_a.fit, steps, [r0, r1, r2]))
    assert [(s.added, s.error) for s in diag.steps] == [(None, 8.0), ("a", 4.0)]
    assert "10 -> 8" in diag.steps[0].note
    assert diag.final_model is t_a.fit and len(diag.rounds) == 3


def test_nothing_added_says_what_is_unexplained():
    base = fit((), 10.0)
    rnd = sel.Round(base, [screened(("a",), 9.7)], [], None)
    diag = ad.as_diagnosis(DATASET, sel.Selection(base, base, [], [rnd]))
    assert len(diag.steps) == 1 and len(diag.rounds) == 1
    v = diag.first.verdict
    assert v.kind is VerdictKind.NONE
    assert "misfit of paper" in v.unexplained  # E^2 = 100 > 4 with a structured residual


def test_diagnose_auto_hands_the_fits_to_on_fit(monkeypatch):
    base = fit((), 10.0)
    t_a = trial(base, ("a",), 4.0)
    out = sel.Selection(base, t_a.fit, [sel.Step("add", ("a",), 10.0, 4.0, -50.0, t_a.fit)],
                        [sel.Round(base, [screened(("a",), 5.0)], [t_a], t_a)])
    seen: list[Any] = []
    monkeypatch.setattr(ad, "auto_select", lambda *a, **kw: out)
    diag = ad.diagnose_auto(DATASET, ModelChoice("paper"), candidates=["a"],
                            on_fit=lambda name, f: seen.append((name, f.error)))
    assert seen == [("a", 4.0)]
    assert diag.final_model is t_a.fit


def _patch_auto(monkeypatch: pytest.MonkeyPatch, search: Any, screen: Any) -> None:
    """auto_select's search and screen replaced; every model without effects errs 10.0 there."""
    from rigctl.workbench import auto

    monkeypatch.setattr(auto, "search_model", search)
    monkeypatch.setattr(auto, "score_screen", screen)
    monkeypatch.setattr(auto, "error_or_inf", lambda ds, c, fns: 10.0)
    monkeypatch.setattr(auto, "fn_range", lambda ds: (1.0, 2.0))


def test_a_candidate_that_cannot_be_fitted_is_a_failed_trial_not_a_failed_run(monkeypatch):
    from rigctl.model import ParameterError
    from rigctl.workbench import auto

    base = fit((), 10.0)

    def search(dataset: Any, choice: ModelChoice, **kw: Any) -> FitResult:
        if "b" in choice.effects:
            raise ParameterError("paper + b: kinetic friction is not below static friction")
        return fit(choice.effects, 4.0 if choice.effects == ("a",) else 10.0)

    def screen(dataset: Any, model: FitResult, sets: Any, **kw: Any) -> list[Screened]:
        return sorted((screened(s, 5.0 if s == ("a",) else 6.0) for s in sets),
                      key=lambda s: s.error)

    _patch_auto(monkeypatch, search, screen)
    said: list[str] = []
    out = auto.auto_select(DATASET, base, pool=["a", "b"], say=said.append)
    assert out.final.choice.effects == ("a",)
    failed = [t for r in out.rounds for t in r.trials if "b" in t.effects]
    assert failed and all(t.fit.error == float("inf") for t in failed)
    assert any("no fit" in m for m in said)


def test_each_fit_s_residual_map_is_evaluated_once(monkeypatch):
    mapped: list[str] = []

    def counted(dataset: Any, model: FitResult) -> Any:
        mapped.append(model.choice.label())
        return SimpleNamespace(model=model)

    monkeypatch.setattr(ad, "_map", counted)
    base = fit((), 10.0)
    t_a = trial(base, ("a",), 4.0)
    t_b = trial(t_a.fit, ("a", "b"), 3.9)
    r1 = sel.Round(base, [screened(("a",), 5.0)], [t_a], t_a)
    r2 = sel.Round(t_a.fit, [screened(("b",), 3.95)], [t_b], None)  # the chosen fit, mapped again
    ad.as_diagnosis(DATASET, sel.Selection(
        base, t_a.fit, [sel.Step("add", ("a",), 10.0, 4.0, -50.0, t_a.fit)], [r1, r2]))
    assert sorted(mapped) == sorted(["paper", "paper + a", "paper + a + b"])


def test_an_undecided_step_is_an_indistinguishable_verdict_with_the_runs_that_reveal_each():
    base = fit((), 10.0)
    t_s, t_r = trial(base, ("stribeck",), 4.0), trial(base, ("rate_state",), 4.02)
    rnd = sel.Round(base, [screened(("stribeck",), 4.5), screened(("rate_state",), 4.6)],
                    [t_s, t_r], None, (t_s, t_r))
    diag = ad.as_diagnosis(DATASET, sel.Selection(base, base, [], [rnd]))
    v = diag.rounds[-1].verdict
    assert v.kind is VerdictKind.INDISTINGUISHABLE
    assert v.candidates == ["stribeck", "rate_state"]
    assert "velocity steps" in (v.suggest or "") and "slide-hold-slide" in (v.suggest or "")
    assert {r["protocol"] for r in v.runs} == {"velocity_steps", "slide_hold_slide"}
    js = diag.to_json(True)
    assert js["final_verdict"] == "indistinguishable" and js["final_model"] == "paper"
    assert js["final_candidates"] == ["stribeck", "rate_state"]


def test_each_fit_after_the_model_s_own_has_the_time_limit_and_says_when_it_ended_it(
        monkeypatch):
    from rigctl.workbench import auto

    base = fit((), 10.0)
    limits: list[Any] = []

    def search(dataset: Any, choice: ModelChoice, **kw: Any) -> FitResult:
        limits.append(kw.get("max_wall_s"))
        res = fit(choice.effects, 4.0 if choice.effects == ("a",) else 10.0)
        if choice.effects == ("a",):  # ended by its budget's time
            return replace(res, elapsed_s=59.0, message="starts 8; CMA-ES 120 (budget)",
                           time_limited=True, n_timed_out=3, n_evaluations=130)
        return replace(res, elapsed_s=1.0, message="starts 8; CMA-ES 40 (no gain)")

    def screen(dataset: Any, model: FitResult, sets: Any, **kw: Any) -> list[Screened]:
        return sorted((screened(s, 5.0 if s == ("a",) else 9.9) for s in sets),
                      key=lambda s: s.error)

    _patch_auto(monkeypatch, search, screen)
    said: list[str] = []
    out = auto.auto_select(DATASET, base, pool=["a", "b"], say=said.append, fit_wall_s=60.0)
    assert out.final.choice.effects == ("a",)
    assert limits and all(x == 60.0 for x in limits)
    ended = [m for m in said if "reached its time limit of 60 s" in m]
    assert len(ended) == 1 and "paper + a" in ended[0]
    stopped = [m for m in said if "stopped at the per-evaluation time limit" in m]
    assert stopped == ["  paper + a: 3 of its 130 simulations were stopped at the "
                       "per-evaluation time limit"]


def test_diagnose_hands_its_timeout_to_auto_as_each_fit_s_limit(monkeypatch):
    from rigctl.workbench import diagnose as dg

    got: dict[str, Any] = {}

    def fake(*a: Any, **kw: Any) -> Any:
        got.update(kw)
        return "diagnosis"

    monkeypatch.setattr(ad, "diagnose_auto", fake)
    assert dg.diagnose(DATASET, ModelChoice("paper"), auto=True, timeout_s=42.0) == "diagnosis"
    assert got["fit_wall_s"] == 42.0


def test_each_fit_s_limit_is_its_share_of_the_run_where_that_is_less(monkeypatch):
    from rigctl.workbench import auto

    base = fit((), 10.0)
    limits: list[Any] = []

    def search(dataset: Any, choice: ModelChoice, **kw: Any) -> FitResult:
        limits.append(kw.get("max_wall_s"))
        return replace(fit(choice.effects, 4.0 if choice.effects == ("a",) else 10.0),
                       time_limited=True)

    def screen(dataset: Any, model: FitResult, sets: Any, **kw: Any) -> list[Screened]:
        return sorted((screened(s, 5.0 if s == ("a",) else 9.9) for s in sets),
                      key=lambda s: s.error)

    _patch_auto(monkeypatch, search, screen)
    said: list[str] = []
    out = auto.auto_select(DATASET, base, pool=["a", "b"], say=said.append, fit_wall_s=300.0,
                           max_run_s=100.0)
    assert out.final.choice.effects == ("a",) and out.time_limited == ""
    # one fit in the step: half the time left; never the 300 s of --timeout
    assert limits and all(x is not None and 0 < x <= 50.0 for x in limits)
    assert any("its share of the run's --max-time" in m for m in said)


def test_the_time_limit_of_the_selection_reaches_the_diagnosis_and_its_json():
    base = fit((), 10.0)
    s = sel.Selection(base, base, time_limited="the run's time limit ended forward step 1")
    diag = ad.as_diagnosis(DATASET, s)
    assert diag.time_limited == s.time_limited
    assert diag.to_json(True)["time_limited"] == s.time_limited


def test_diagnose_runs_auto_within_the_default_run_limit(monkeypatch):
    from rigctl.workbench import diagnose as dg
    from rigctl.workbench.run_deadline import DEFAULT_RUN_S

    got: dict[str, Any] = {}
    monkeypatch.setattr(ad, "diagnose_auto", lambda *a, **kw: got.update(kw))
    dg.diagnose(DATASET, ModelChoice("paper"), auto=True)
    assert got["max_run_s"] == DEFAULT_RUN_S


def test_the_model_s_own_fit_gets_at_most_half_the_run_and_says_when_it_ended_it(monkeypatch):
    from rigctl.workbench import auto

    limits: list[Any] = []

    def search(dataset: Any, choice: ModelChoice, **kw: Any) -> FitResult:
        limits.append(kw.get("max_wall_s"))
        return replace(fit(choice.effects, 10.0), time_limited=not choice.effects)

    def screen(dataset: Any, model: FitResult, sets: Any, **kw: Any) -> list[Screened]:
        return [screened(s, 9.99) for s in sets]

    _patch_auto(monkeypatch, search, screen)
    said: list[str] = []
    out = auto.auto_select(DATASET, ModelChoice("paper"), pool=["a"], say=said.append,
                           max_run_s=100.0)
    assert limits[0] is not None and 49.0 < limits[0] <= 50.0
    assert any("its fit reached half the run's time limit" in m for m in said)
    assert out.final is out.base
