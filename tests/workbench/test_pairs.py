"""Two effects fitted together where neither alone is significant (rigctl.workbench.pairs).

The candidate fits themselves are stood in for by a table of the errors each ordered pair's fit
ends at: what is tested is which pairs are fitted, from which fits, and which one is taken."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from rigctl.workbench import pairs
from rigctl.workbench.fitting import SWITCHED_OFF
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.ranking import score_candidate

BASE_FREE = ("mu_s", "mu_k", "k0_N_per_m", "kts_N_per_m")


@dataclass
class _Events:
    n_events: int = 126


def _fit(effects: tuple[str, ...], error: float, n_extra: int = 2) -> FitResult:
    free = BASE_FREE + tuple(f"{e}.p{j}" for e in effects for j in range(n_extra))
    return FitResult(ModelChoice("paper", effects), error, {}, free)


MODEL = _fit((), 16.2)
ALONE = {"rate_state": 12.0, "load_dependent_friction": 14.0, "stribeck": 16.2, "wear": 15.0,
         "presliding": 16.3}
"""Errors alone from MODEL's 16.2: removed 26 %, 14 %, nothing, 7 % (under the 10 % a first needs)."""
TOGETHER = {("load_dependent_friction", "stribeck"): 1.1, ("rate_state", "stribeck"): 9.0}
"""Where each ordered pair's fit ends (the first's own fit continued with the second); others 15."""


@pytest.fixture
def fits() -> dict[str, tuple[FitResult, float]]:
    return {name: (_fit((name,), e), MODEL.error) for name, e in ALONE.items()}


@pytest.fixture
def fitted(monkeypatch) -> list[tuple[str, str]]:
    calls: list[tuple[str, str]] = []

    def fake(task):
        first = task.base.choice.effects[-1]
        calls.append((first, task.effect))
        return _fit((first, task.effect), TOGETHER.get((first, task.effect), 15.0))

    def fake_on(_dataset, res):
        calls.append(("fit on", "+".join(res.choice.effects)))
        return _fit(res.choice.effects, FINISHED.get(res.choice.effects, res.error))

    def fake_search(_dataset, results, effects, **_run):
        out = []
        for res, effs in zip(results, effects, strict=True):
            calls.append(("search", "+".join(effs)))
            e = SEARCHED.get(res.choice.effects)
            out.append(res if e is None or e >= res.error else _fit(res.choice.effects, e))
        return out

    monkeypatch.setattr(pairs, "fit_candidate", fake)
    monkeypatch.setattr(pairs, "fit_on", fake_on)
    monkeypatch.setattr(pairs, "refit_over_effects", fake_search)
    return calls


FINISHED: dict[tuple[str, ...], float] = {}
"""Where fitting a pair on ends (fit_on); others where the pair fit ended."""
SEARCHED: dict[tuple[str, ...], float] = {}
"""Where the search over a pair's effect parameters ends (refit_over_effects); others unchanged."""


def test_the_firsts_removed_most_of_their_model_s_error_alone(fits) -> None:
    assert pairs.firsts(fits) == ["rate_state", "load_dependent_friction"]
    # a fit on the model before it was refitted counts by what it removed from that model
    fits["wear"] = (_fit(("wear",), 24.3), 49.5)
    assert pairs.firsts(fits) == ["wear", "rate_state"]
    fits["rate_state"][0].misses_most_slips = True  # a trap, not a fit
    fits["presliding"] = (_fit(("presliding",), 8.0), MODEL.error)
    fits["presliding"][0].message = SWITCHED_OFF  # nothing better than its base: not a start
    assert pairs.firsts(fits) == ["wear", "load_dependent_friction"]
    fits["load_dependent_friction"] = (_fit(("load_dependent_friction",), 14.8), MODEL.error)
    assert pairs.firsts(fits) == ["wear"]  # 9 % is no start


def test_pairs_are_fitted_in_both_orders_and_the_best_significant_one_is_taken(fits, fitted) -> None:
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    # the two best alone, each continued with every other candidate once; the one significant
    # pair within 1.5 times the best is the best (9.0 is not within), fitted on
    pair_fits = [(a, b) for a in ("rate_state", "load_dependent_friction") for b in ALONE if b != a]
    assert sorted(fitted) == sorted([*pair_fits, ("fit on", "load_dependent_friction+stribeck"),
                                     ("search", "load_dependent_friction+stribeck")])
    assert pair is not None
    assert (pair.first, pair.second) == ("load_dependent_friction", "stribeck")
    assert pair.fit.error == 1.1 and pair.first_fit is fits["load_dependent_friction"][0]
    assert pair.score.significant and pair.score.n_params == 4  # both effects' parameters counted


def test_no_pair_is_taken_where_none_is_significant(fits, fitted, monkeypatch) -> None:
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "stribeck"), 15.2)  # 6 % off 16.2
    monkeypatch.setitem(TOGETHER, ("rate_state", "stribeck"), 15.8)
    assert pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True) is None  # type: ignore[arg-type]
    assert len(fitted) == 8


def test_pairs_are_wanted_where_the_misfit_is_structured_and_no_single_effect_halves_it() -> None:
    assert pairs.wants_pairs(MODEL, None)  # no significant single candidate
    assert pairs.wants_pairs(MODEL, score_candidate("interface_damping", 16.2, 13.4, 126, 2))
    assert not pairs.wants_pairs(MODEL, score_candidate("interface_damping", 16.2, 7.0, 126, 2))
    assert not pairs.wants_pairs(_fit((), 1.6), None)  # E^2 2.6: the scatter's


def test_a_pair_is_taken_over_a_single_effect_only_where_it_beats_that_one_too(fits, fitted) -> None:
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    assert pair is not None
    single_fit = _fit(("interface_damping",), 13.4)
    single = score_candidate("interface_damping", MODEL.error, 13.4, 126, 2)
    assert pairs.beats_single(pair, single, single_fit, 126)  # 1.1 against 13.4
    close = _fit(("interface_damping",), 1.12)
    assert not pairs.beats_single(pair, score_candidate("interface_damping", MODEL.error, 1.12, 126, 2),
                                  close, 126)  # two more parameters for 2 %
    assert pairs.beats_single(pair, None, None, 126)


def test_pairs_near_the_best_are_fitted_on_before_one_is_chosen(fits, fitted, monkeypatch) -> None:
    """A short pair fit may stop short: the best after the fit-on is taken (held-out seed 4 case
    11: a wrong second effect ended at 3.40 where the hidden one, still descending, stopped at
    4.54)."""
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "stribeck"), 4.54)
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "presliding"), 3.40)
    monkeypatch.setitem(FINISHED, ("load_dependent_friction", "stribeck"), 1.2)
    monkeypatch.setitem(FINISHED, ("load_dependent_friction", "presliding"), 3.3)
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    assert pair is not None and pair.second == "stribeck" and pair.fit.error == 1.2
    assert pair.score.error == 1.2 and pair.score.significant
    on = sorted(b for a, b in fitted if a == "fit on")
    # 9.0 (rate_state + stribeck) is beyond 1.5 x 3.40 and is not fitted on
    assert on == ["load_dependent_friction+presliding", "load_dependent_friction+stribeck"]


def _hidden_pair_third(monkeypatch) -> None:
    """Held-out seed 4 case 11's pair round: two wrong pairs ahead of the hidden one (6.61)."""
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "rate_state"), 4.81)
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "wear"), 5.21)
    monkeypatch.setitem(TOGETHER, ("load_dependent_friction", "stribeck"), 6.61)


def test_a_pair_is_fitted_on_once_in_its_better_order(fits, fitted, monkeypatch) -> None:
    """Both orders of one pair fit the same model: the worse order does not take one of the
    MAX_CLOSE places (held-out seed 4 case 11: one pair in both orders took two of the three, and
    the hidden pair, fourth, was not fitted on)."""
    _hidden_pair_third(monkeypatch)
    monkeypatch.setitem(TOGETHER, ("rate_state", "load_dependent_friction"), 5.2)
    monkeypatch.setitem(FINISHED, ("load_dependent_friction", "stribeck"), 1.4)
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    on = sorted(b for a, b in fitted if a == "fit on")
    assert on == ["load_dependent_friction+rate_state", "load_dependent_friction+stribeck",
                  "load_dependent_friction+wear"]
    assert pair is not None and pair.second == "stribeck" and pair.fit.error == 1.4


def test_pairs_near_the_best_are_searched_over_their_effects_parameters(fits, fitted,
                                                                        monkeypatch) -> None:
    """Fitted on, a pair may stay in a valley no local step leaves (held-out seed 4 case 11: the
    hidden pair at 6.51, third; refitted from three times its Stribeck velocity, 1.29): each pair
    fitted on is then searched (rigctl.workbench.effect_search), and the best end is taken."""
    _hidden_pair_third(monkeypatch)
    monkeypatch.setitem(FINISHED, ("load_dependent_friction", "rate_state"), 3.07)
    monkeypatch.setitem(FINISHED, ("load_dependent_friction", "stribeck"), 6.51)
    monkeypatch.setitem(SEARCHED, ("load_dependent_friction", "stribeck"), 0.956)
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    searched = sorted(b for a, b in fitted if a == "search")
    assert searched == ["load_dependent_friction+rate_state", "load_dependent_friction+stribeck",
                        "load_dependent_friction+wear"]
    assert pair is not None and pair.second == "stribeck" and pair.fit.error == 0.956
    assert pair.score.error == 0.956 and pair.score.significant
    monkeypatch.delitem(SEARCHED, ("load_dependent_friction", "stribeck"))
    pair = pairs.best_pair(_Events(), MODEL, fits, workers=1, in_process=True)  # type: ignore[arg-type]
    assert pair is not None and pair.second == "rate_state"  # without the search: the wrong pair
