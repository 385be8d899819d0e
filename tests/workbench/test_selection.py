"""Forward selection and backward elimination (rigctl/workbench/selection.py) with the fits replaced
by a table of errors: what is under test is which sets are screened, fitted, added and removed."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from types import SimpleNamespace
from typing import Any, cast

import pytest

from rigctl.records.dataset import Dataset
from rigctl.workbench import selection as sel
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice

N_EVENTS = 200
DATASET = cast(Dataset, SimpleNamespace(n_events=N_EVENTS))


class Table:
    """Fits that return the error of each effect set (order-free); unknown sets: the base's.
    Records which sets were fully fitted and which only screened."""

    def __init__(self, errors: Mapping[frozenset[str], float], screen_offset: float = 0.0,
                 screen_errors: Mapping[frozenset[str], float] | None = None,
                 warm_errors: Mapping[frozenset[str], float] | None = None) -> None:
        self.errors = dict(errors)
        self.warm_errors = dict(warm_errors or {})
        """Errors of a refit started from the values of a fit with more effects (``warm`` set):
        a search from a better start can end lower than the same model's earlier fit."""
        self.screen_errors = dict(screen_errors or {})
        self.screen_offset = screen_offset
        self.fitted: list[frozenset[str]] = []
        self.screened: list[frozenset[str]] = []
        self.starts: dict[frozenset[str], tuple[ModelChoice, ...]] = {}
        """The extra starts each full fit was given."""
        self.walls: list[float | None] = []
        """Each full fit's share of the run's time (``max_wall_s``)."""

    def _result(self, choice: ModelChoice, error: float) -> FitResult:
        free = ("mu_s", "mu_k", *(f"{e}.p" for e in choice.effects))
        if len(choice.effects) >= 2:
            choice = choice.with_values({"warm": 1.0})
        return FitResult(choice, error, {}, free)

    def fit(self, _ds: Any, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
            max_wall_s: float | None = None) -> FitResult:
        key = frozenset(choice.effects)
        self.fitted.append(key)
        self.walls.append(max_wall_s)
        self.starts[key] = tuple(starts)
        if "warm" in choice.values and key in self.warm_errors:
            return self._result(choice, self.warm_errors[key])
        return self._result(choice, self.errors.get(key, self.errors[frozenset()]))

    def screen(self, _ds: Any, choice: ModelChoice) -> FitResult:
        key = frozenset(choice.effects)
        self.screened.append(key)
        e = self.screen_errors.get(key, self.errors.get(key, self.errors[frozenset()]))
        return self._result(choice, e + self.screen_offset)


def S(*names: str) -> frozenset[str]:
    return frozenset(names)


POOL = ("a", "b", "c", "d", "e")


def _select(table: Table, base_effects: tuple[str, ...] = ()) -> sel.Selection:
    base = table.fit(DATASET, ModelChoice("paper", base_effects))
    table.fitted.clear()
    return sel.select_effects(DATASET, base, [p for p in POOL if p not in base_effects],
                              fit=table.fit, screen=sel.by_short_fits(table.screen))


def test_the_best_significant_single_is_added_and_nothing_after_it():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0, S("a", "b"): 3.9, S("a", "c"): 3.95})
    out = _select(t)
    assert [(s.kind, s.effects) for s in out.steps] == [("add", ("a",))]
    assert out.final.choice.effects == ("a",)
    assert out.final.error == 4.0


def test_a_pair_is_added_where_neither_effect_alone_is_significant():
    # each alone removes 5 % of the error (not significant); together 60 %
    t = Table({S(): 10.0, S("a"): 9.5, S("b"): 9.5, S("a", "b"): 4.0})
    out = _select(t)
    assert out.steps[0].effects == ("a", "b")
    assert set(out.final.choice.effects) == {"a", "b"}


def test_a_pair_no_better_than_its_best_single_is_not_taken():
    # the pair beats the base but gains too little over "a" alone for its extra parameter
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 9.0, S("a", "b"): 3.95})
    out = _select(t)
    assert out.steps[0].effects == ("a",)
    assert out.final.choice.effects == ("a",)


def test_only_the_best_screened_sets_are_fitted_fully():
    # "e" would be the best, but its short fit ranks it last: the screen decides what is fitted
    t = Table({S(): 10.0, S("a"): 6.0, S("b"): 6.5, S("c"): 7.0, S("d"): 7.5, S("e"): 3.0},
              screen_errors={S("e"): 9.9})
    _select(t)
    first_round = t.fitted[: 2 * sel.SCREEN_KEEP]
    assert S("e") not in first_round
    assert {S("a"), S("b"), S("c")} <= set(first_round)
    assert len(t.screened) >= len(POOL)  # every single was screened


def test_backward_elimination_removes_an_effect_the_later_one_made_redundant():
    # "a" is added first (b's first fit stops at 5.5), then "b"; refitted from the a + b model
    # without "a", "b" alone reaches 2.02: "a" no longer earns its place
    t = Table({S(): 10.0, S("a"): 5.0, S("b"): 5.5, S("a", "b"): 2.0, S("a", "c"): 4.9},
              warm_errors={S("b"): 2.02, S("a"): 4.0})
    out = _select(t)
    kinds = [(s.kind, s.effects) for s in out.steps]
    assert ("remove", ("a",)) in kinds
    assert out.final.choice.effects == ("b",)


def test_effects_the_user_gave_are_never_removed():
    t = Table({S(): 10.0, S("a"): 10.0, S("a", "b"): 4.0, S("b"): 4.0})
    out = _select(t, base_effects=("a",))
    assert "a" in out.final.choice.effects
    assert all(s.effects != ("a",) for s in out.steps if s.kind == "remove")


def test_nothing_is_added_when_nothing_is_significant():
    t = Table({S(): 1.05, S("a"): 1.0, S("b"): 1.01, S("a", "b"): 0.98})
    out = _select(t)
    assert out.steps == []
    assert out.final is out.base
    assert len(out.rounds) == 1


def test_no_set_is_fitted_fully_when_no_screen_is_significant():
    # the short fits see at most 5 % of the error (not significant): the step ends unfitted,
    # although "a" fitted fully would have been (the screen's miss, the gate's price)
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 9.6}, screen_errors={S("a"): 9.5})
    out = _select(t)
    assert t.fitted == [] and out.steps == [] and out.final is out.base
    assert [r.trials for r in out.rounds] == [[]] and out.rounds[0].chosen is None
    assert {s.effects for s in out.rounds[0].screens} >= {("a",), ("b",)}


def test_only_the_kept_sets_that_screen_significant_are_fitted():
    # "b" alone would fit to 4.0 but screens at 9.6 (not significant): the screen's miss
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 4.0, S("c"): 9.7}, screen_errors={S("a"): 8.0,
                                                                             S("b"): 9.6})
    out = _select(t)
    first_round = {t.effects for t in out.rounds[0].trials}
    assert ("a",) in first_round and ("b",) not in first_round and ("c",) not in first_round
    assert out.steps[0].effects == ("a",)


def test_each_full_fit_also_starts_where_its_screen_ended():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0})
    _select(t)
    starts = t.starts[S("a")]
    assert len(starts) == 1 and starts[0].effects == ("a",)


@pytest.mark.parametrize("effects", [("a",), ("a", "b")])
def test_with_and_without_effects_round_trip(effects):
    choice = sel.with_effects(ModelChoice("paper"), effects).with_values({"a.p": 1.0, "mu_s": 0.2})
    back = sel.without_effect(choice, "a")
    assert "a" not in back.effects and "a.p" not in back.values and back.values["mu_s"] == 0.2


class Unfinished(Table):
    """A model whose own fit is unfinished: every trial's fit moves the base parameters to where
    the base without any effect scores ``finished`` (marked by a value ``at_trial``)."""

    def __init__(self, errors: Mapping[frozenset[str], float], finished: float) -> None:
        super().__init__(errors)
        self.finished = finished
        self.evaluated: list[ModelChoice] = []

    def _result(self, choice: ModelChoice, error: float) -> FitResult:
        res = super()._result(choice, error)
        if choice.effects:  # a trial: its fit reached the better base values
            res = FitResult(res.choice.with_values({"at_trial": 1.0}), res.error, {}, res.free)
        return res

    def fit(self, ds: Any, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
            max_wall_s: float | None = None) -> FitResult:
        if not choice.effects and "at_trial" in choice.values:  # the base refitted from there
            self.fitted.append(frozenset())
            return FitResult(choice, self.finished, {}, ("mu_s", "mu_k"))
        return super().fit(ds, choice, starts=starts, max_wall_s=max_wall_s)

    def error_of(self, _ds: Any, choice: ModelChoice) -> float:
        self.evaluated.append(choice)
        if "at_trial" in choice.values and not choice.effects:
            return self.finished
        return self.errors[frozenset(choice.effects)]


def test_a_gain_the_model_reaches_without_the_effect_is_not_credited_to_the_effect():
    # every effect seems to take 10 -> 6, but the base alone at the trials' values scores 6
    t = Unfinished({S(): 10.0, S("a"): 6.0, S("b"): 6.2, S("a", "b"): 6.0}, finished=6.0)
    base = t.fit(DATASET, ModelChoice("paper"))
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit, screen=sel.by_short_fits(t.screen),
                             error_of=t.error_of)
    assert [s.kind for s in out.steps] == ["refit"]
    assert out.steps[0].error_before == 10.0 and out.steps[0].error_after == 6.0
    assert out.final.choice.effects == () and out.final.error == 6.0
    # every evaluated point had the trial's effects off: the model, or a single at a pair's
    # values (selection.best_known)
    assert any(c.effects == () for c in t.evaluated)
    assert all(c.effects == () or (len(c.effects) == 1 and "warm" in c.values)
               for c in t.evaluated)


def test_without_error_of_the_unfinished_gain_is_credited_as_before():
    t = Unfinished({S(): 10.0, S("a"): 6.0, S("b"): 6.2, S("a", "b"): 6.0}, finished=6.0)
    base = t.fit(DATASET, ModelChoice("paper"))
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit, screen=sel.by_short_fits(t.screen))
    assert out.steps[0].kind == "add"


def test_a_trial_whose_gain_is_its_own_is_added_after_the_check():
    # the base at the trials' values is no better than the model: the effect keeps its gain
    t = Unfinished({S(): 10.0, S("a"): 4.0, S("b"): 8.0, S("a", "b"): 3.95}, finished=9.9)
    base = t.fit(DATASET, ModelChoice("paper"))
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit, screen=sel.by_short_fits(t.screen),
                             error_of=t.error_of)
    assert [(s.kind, s.effects) for s in out.steps] == [("add", ("a",))]


def test_each_full_fit_and_refit_says_how_far_its_part_is():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0})
    base = t.fit(DATASET, ModelChoice("paper"))
    said: list[str] = []
    sel.select_effects(DATASET, base, list(POOL), fit=t.fit, screen=sel.by_short_fits(t.screen),
                       say=said.append)
    fitted = [m for m in said if m.strip().startswith("fitted")]
    assert fitted and fitted[0].endswith("left in this round]") and "[1/" in fitted[0]
    assert fitted[-1].endswith(f"[{len(fitted)}/{len(fitted)}]")
    assert any(m.strip().startswith("without a") and m.endswith("[1/1]") for m in said)


def test_no_pair_holding_the_best_significant_single_is_screened():
    # "a" alone removes 60 %: a pair holding it is the next step's question (its partner with "a"
    # in the model), so none is screened; b + c (neither significant alone) still is
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 9.5, S("c"): 9.6, S("a", "b"): 3.95,
               S("a", "c"): 3.97, S("b", "c"): 9.4})
    base = t.fit(DATASET, ModelChoice("paper"))
    t.fitted.clear()
    out = sel.rank_effects(DATASET, base, list(POOL), fit=t.fit,
                           screen=sel.by_short_fits(t.screen))
    pairs = [k for k in t.screened if len(k) == 2]
    assert pairs and all("a" not in k for k in pairs)
    assert S("b", "c") in pairs
    assert not any(len(k) == 2 for k in t.fitted)
    assert out.rounds[0].chosen is not None and out.rounds[0].chosen.effects == ("a",)


def test_a_pair_is_fitted_only_where_it_screens_significant_against_the_best_single():
    # "a" removes 60 %; b + c screens at 3.9 (not significant against a's 4.0): not fitted
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 9.5, S("c"): 9.6, S("b", "c"): 3.9})
    said: list[str] = []
    base = t.fit(DATASET, ModelChoice("paper"))
    t.fitted.clear()
    sel.rank_effects(DATASET, base, list(POOL), fit=t.fit, screen=sel.by_short_fits(t.screen),
                     say=said.append)
    assert S("b", "c") in t.screened and S("b", "c") not in t.fitted
    assert any("b + c: screened 3.9, not significant against a (4): not fitted" in m
               for m in said)
    # the same pair at 2.0 beats a's fit: it is fitted and taken
    t2 = Table({S(): 10.0, S("a"): 4.0, S("b"): 9.5, S("c"): 9.6, S("b", "c"): 2.0})
    out2 = _select(t2)
    assert S("b", "c") in t2.fitted
    assert out2.steps[0].effects == ("b", "c")


def test_two_sets_the_data_cannot_tell_apart_are_reported_and_neither_is_added():
    # "a" and "b" each remove 60 % of the error, 2 apart in delta BIC (under 6): no name is forced
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 4.02, S("a", "b"): 3.99})
    out = _select(t)
    assert out.steps == [] and out.final is out.base
    (rnd,) = out.rounds
    assert rnd.chosen is None
    assert [x.effects for x in rnd.undecided] == [("a",), ("b",)]


def test_a_runner_up_well_behind_or_nested_is_no_contender():
    # "b" 20 apart in delta BIC: decided; the pair a + b contains "a": the pair rule decides
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 4.2, S("a", "b"): 3.99})
    out = _select(t)
    assert out.steps[0].effects == ("a",)
    assert all(not r.undecided for r in out.rounds)


class Scored(Table):
    """A table whose screen is a score screen: each set's screened error (as ``Table``) and its
    score statistic (``scores``, 0 where absent) with one degree of freedom per effect."""

    def __init__(self, errors: Mapping[frozenset[str], float],
                 screen_errors: Mapping[frozenset[str], float],
                 scores: Mapping[frozenset[str], float]) -> None:
        super().__init__(errors, screen_errors=screen_errors)
        self.scores = dict(scores)

    def score_screen(self, ds: Any, model: FitResult, sets: Sequence[tuple[str, ...]]
                     ) -> list[sel.Screened]:
        out = []
        for effects in sets:
            res = self.screen(ds, sel.with_effects(model.choice, effects))
            out.append(sel.Screened(effects, res.error, self.scores.get(frozenset(effects), 0.0),
                                    1, "spread point", None, len(effects)))
        return sorted(out, key=lambda s: s.error)


def _select_scored(table: Scored) -> sel.Selection:
    base = table.fit(DATASET, ModelChoice("paper"))
    table.fitted.clear()
    return sel.select_effects(DATASET, base, list(POOL), fit=table.fit, screen=table.score_screen)


def test_a_set_with_a_significant_score_is_fitted_although_its_screened_error_is_not():
    # "d" fits to 3.0, but its screen saw only 9.8 (the gain beyond the linear re-fit); its score
    # of 60 on one coordinate is far beyond chance (chi-square tail ~1e-14)
    t = Scored({S(): 10.0, S("d"): 3.0}, screen_errors={S(c): 9.8 for c in POOL},
               scores={S("d"): 60.0, S("a"): 1.0})
    out = _select_scored(t)
    assert S("d") in t.fitted[: 2 * sel.SCREEN_KEEP]
    assert out.steps[0].effects == ("d",)


def test_a_score_within_chance_sends_nothing_to_a_full_fit():
    # scores of 3 on one coordinate (tail 0.08) over five singles: within chance at SCORE_ALPHA
    t = Scored({S(): 10.0, S("d"): 3.0}, screen_errors={S(c): 9.8 for c in POOL},
               scores={S(c): 3.0 for c in POOL})
    out = _select_scored(t)
    assert t.fitted == [] and out.steps == []


def test_significant_errors_keep_their_places_and_scores_fill_the_rest_strongest_first():
    # "a" screens significant; "c", "d" and "e" have significant scores: two free places go to
    # the strongest scores, "e" (80) and "d" (40), not "c" (20)
    t = Scored({S(): 10.0, S("a"): 5.0}, screen_errors={S("a"): 6.0, S("b"): 9.7, S("c"): 9.8,
                                                        S("d"): 9.9, S("e"): 9.9},
               scores={S("c"): 20.0, S("d"): 40.0, S("e"): 80.0})
    _select_scored(t)
    first = set(t.fitted[: sel.SCREEN_KEEP])
    assert first == {S("a"), S("e"), S("d")}


def test_a_large_score_is_judged_by_the_bonferroni_share_of_its_step():
    # the tail of 9 on one coordinate is 0.0027: significant alone at 0.01, not over 5 singles
    one = sel.Screened(("a",), 9.9, 9.0, 1, "off", None, 1)
    assert sel.score_significant(one, 1)
    assert not sel.score_significant(one, 5)
    assert not sel.score_significant(sel.Screened(("a",), 9.9, 9.0, 1, "short fit"), 1)


def test_each_full_fit_says_how_long_it_took():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0})
    base = t.fit(DATASET, ModelChoice("paper"))

    def timed(ds: Any, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
              max_wall_s: float | None = None) -> FitResult:
        res = t.fit(ds, choice, starts=starts, max_wall_s=max_wall_s)
        return FitResult(res.choice, res.error, {}, res.free, elapsed_s=42.4)

    said: list[str] = []
    sel.select_effects(DATASET, base, list(POOL), fit=timed, screen=sel.by_short_fits(t.screen),
                       say=said.append)
    fitted = [m for m in said if m.strip().startswith("fitted")]
    assert fitted and all(" in 42 s [" in m for m in fitted)


def test_the_ranking_is_one_step_that_adds_nothing():
    t = Table({S(): 10.0, S("a"): 4.0, S("b"): 8.0, S("a", "b"): 3.9})
    base = t.fit(DATASET, ModelChoice("paper"))
    out = sel.rank_effects(DATASET, base, list(POOL), fit=t.fit,
                           screen=sel.by_short_fits(t.screen))
    assert out.steps == [] and out.final is base  # nothing added, nothing removed
    assert len(out.rounds) == 1
    rnd = out.rounds[0]
    assert rnd.chosen is not None and rnd.chosen.effects == ("a",)  # the verdict
    assert {t_.effects for t_ in rnd.trials} >= {("a",)}
    assert {s.effects for s in rnd.screens} >= {(p,) for p in POOL}  # every candidate screened


def test_the_ranking_after_the_model_s_refit_is_the_refitted_model_s():
    t = Unfinished({S(): 10.0, S("a"): 6.0, S("b"): 6.2, S("a", "b"): 6.0}, finished=6.0)
    base = t.fit(DATASET, ModelChoice("paper"))
    out = sel.rank_effects(DATASET, base, list(POOL), fit=t.fit,
                           screen=sel.by_short_fits(t.screen), error_of=t.error_of)
    assert [s.kind for s in out.steps] == ["refit"]
    assert len(out.rounds) == 1 and out.rounds[0].model is out.final
    assert out.final.error == 6.0 and out.rounds[0].chosen is None


def test_a_pair_is_judged_against_its_member_at_the_best_point_known_for_it():
    # the pair's fit found values at which `a` alone scores 2.05, where a's own fit stopped at 5:
    # the pair's gain over `a` was a's unfinished fit, not `b` ("c", a little better than `a`
    # at first, is the step's best single, so pairs holding `a` are screened)
    t = Table({S(): 10.0, S("a"): 5.0, S("b"): 9.9, S("c"): 4.9, S("a", "b"): 2.0},
              warm_errors={S("a"): 2.05})

    def error_of(_ds: Any, choice: ModelChoice) -> float:
        key = frozenset(choice.effects)
        if "warm" in choice.values and key in t.warm_errors:
            return t.warm_errors[key]
        return t.errors[key]

    base = t.fit(DATASET, ModelChoice("paper"))
    said: list[str] = []
    out = sel.select_effects(DATASET, base, ["a", "b", "c"], fit=t.fit,
                             screen=sel.by_short_fits(t.screen), error_of=error_of,
                             say=said.append)
    assert out.steps[0].effects == ("a",) and out.steps[0].error_after == 2.05
    single = next(tr for tr in out.rounds[0].trials if tr.effects == ("a",))
    assert single.fit.error == 2.05
    assert "at a + b's fitted values without b" in single.fit.message
    assert any("a: 5 -> 2.05 at a + b's fitted values without b" in m for m in said)
    # without error_of the pair takes the single's unfinished gain
    t2 = Table({S(): 10.0, S("a"): 5.0, S("b"): 9.9, S("c"): 4.9, S("a", "b"): 2.0})
    out2 = sel.select_effects(DATASET, t2.fit(DATASET, ModelChoice("paper")), ["a", "b", "c"],
                              fit=t2.fit, screen=sel.by_short_fits(t2.screen))
    assert out2.steps[0].effects == ("a", "b")


class Moves(Table):
    """Fits whose effects move the base's values: each fit sets ``mu_s`` to its effects' count
    and each effect's ``p`` to 1. A fit of ``slow`` reaches ``good`` only from a start with
    ``mu_s`` where the base had it (0) and its effects at their fitted ``p`` (1); from anywhere
    else it ends at its error in ``errors``."""

    def __init__(self, errors: Mapping[frozenset[str], float], slow: frozenset[str],
                 good: float) -> None:
        super().__init__(errors)
        self.slow, self.good = slow, good

    def _result(self, choice: ModelChoice, error: float) -> FitResult:
        moved = choice.with_values({"mu_s": float(len(choice.effects)),
                                    **{f"{e}.p": 1.0 for e in choice.effects}})
        return FitResult(moved, error, {}, ("mu_s", "mu_k", *(f"{e}.p" for e in choice.effects)))

    def fit(self, _ds: Any, choice: ModelChoice, *, starts: Sequence[ModelChoice] = (),
            max_wall_s: float | None = None) -> FitResult:
        res = super().fit(_ds, choice, starts=starts, max_wall_s=max_wall_s)
        if frozenset(choice.effects) == self.slow and any(
                s.values.get("mu_s") == 0.0 and all(s.values.get(f"{e}.p") == 1.0
                                                     for e in self.slow)
                for s in (choice, *starts)):
            return self._result(choice, self.good)
        return res


def test_a_removal_is_also_fitted_from_the_values_before_the_effect_was_added():
    # "a" is added first and moves the base; "b" is added on top. Without "a", "b" reaches
    # 2.02 only from the base's own values with "b" as fitted, not from where "a" put the base
    t = Moves({S(): 10.0, S("a"): 5.0, S("b"): 5.5, S("a", "b"): 2.0}, slow=S("b"), good=2.02)
    base = t.fit(DATASET, ModelChoice("paper", values={"mu_s": 0.0}))
    out = sel.select_effects(DATASET, base, list(POOL), fit=t.fit,
                             screen=sel.by_short_fits(t.screen))
    assert [(s.kind, s.effects) for s in out.steps] == [
        ("add", ("a",)), ("add", ("b",)), ("remove", ("a",))]
    assert out.final.choice.effects == ("b",) and out.final.error == 2.02
    (start,) = t.starts[S("b")]
    assert start.effects == ("b",)
    assert start.values["mu_s"] == 0.0  # the base's value before "a" was added
    assert start.values["b.p"] == 1.0  # "b" (added after "a") at its final value
    assert not any(k.startswith("a.") for k in start.values)


def test_without_its_path_a_removal_starts_from_the_final_values_only():
    t = Moves({S(): 10.0, S("a"): 5.0, S("b"): 5.5, S("a", "b"): 2.0}, slow=S("b"), good=2.02)
    final = t.fit(DATASET, ModelChoice("paper", ("a", "b")))
    model, removed = sel.backward_elimination(DATASET, final, fit=t.fit, protected=(),
                                              say=lambda _m: None)
    assert removed == [] and model is final  # "b" alone ended at 5.5 from the final values
    assert t.starts[S("b")] == ()


def test_before_added_takes_the_model_before_the_step_that_added_the_effect():
    base = FitResult(ModelChoice("paper", values={"mu_s": 0.0}), 10.0, {}, ("mu_s",))
    m1 = FitResult(ModelChoice("paper", ("a",), {"mu_s": 1.0, "a.p": 1.0}), 5.0, {}, ())
    m2 = FitResult(ModelChoice("paper", ("a",), {"mu_s": 2.0, "a.p": 2.0}), 4.0, {}, ())
    m3 = FitResult(ModelChoice("paper", ("a", "b", "c"),
                               {"mu_s": 3.0, "a.p": 3.0, "b.p": 3.0, "c.p": 3.0}), 2.0, {}, ())
    path = [sel.Step("add", ("a",), 10.0, 5.0, 1.0, m1),
            sel.Step("refit", (), 5.0, 4.0, 1.0, m2),
            sel.Step("add", ("b", "c"), 4.0, 2.0, 1.0, m3)]
    final = m3.choice
    # "b" came with "c" after a refit: the start is the refitted model's, "c" at its final value
    b = sel.before_added(final, "b", path, base)
    assert b is not None and b.effects == ("a", "c")
    assert dict(b.values) == {"mu_s": 2.0, "a.p": 2.0, "c.p": 3.0}
    # "a" was the first: the base's values, the later effects at their final values
    a = sel.before_added(final, "a", path, base)
    assert a is not None and dict(a.values) == {"mu_s": 0.0, "b.p": 3.0, "c.p": 3.0}
    # an effect no step added (the user's) has no such start
    assert sel.before_added(final.with_effect("u"), "u", path, base) is None
