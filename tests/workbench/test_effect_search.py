"""The effects' own parameters searched with the rest of the model refitted from each point
(:mod:`rigctl.workbench.effect_search`)."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import effect_search
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.fitting import fit_on
from rigctl.workbench.identify import FitResult, free_params, least_squares_fit
from rigctl.workbench.model_choice import ModelChoice

VS = "stribeck.vs_m_per_s"
ALPHA_S = "load_dependent_friction.alpha_s"
ALPHA_K = "load_dependent_friction.alpha_k"


@pytest.fixture(scope="module")
def dataset():
    runs = simulate_campaign(build_model("paper"), "tlre", seed=41, duration_scale=0.5)
    return prepare_dataset(runs)


def _result(values: dict[str, float], free: tuple[str, ...], error: float = 5.0) -> FitResult:
    choice = ModelChoice("paper", ("load_dependent_friction", "stribeck")).with_values(values)
    return FitResult(choice, error, {}, free)


def _moved(points) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {}
    for what, choice in points:
        name = what.split()[0]
        out.setdefault(name, []).append(next(p.value for p in choice.parameter_table() if p.name == name))
    return out


def test_each_free_effect_parameter_is_moved_alone_to_a_third_and_three_times_its_value(dataset):
    res = _result({VS: 0.02, ALPHA_S: 0.3, ALPHA_K: 0.2}, ("mu_s", "mu_k", VS, ALPHA_S, ALPHA_K))
    points = effect_search.effect_points(dataset, res, ("stribeck", "load_dependent_friction"))
    moved = _moved(points)
    assert sorted(moved) == sorted([VS, ALPHA_S, ALPHA_K])  # the base parameters are not moved
    assert moved[VS] == pytest.approx([0.006, 0.06])
    assert moved[ALPHA_S] == pytest.approx([0.09, 0.9])
    for what, choice in points:  # the others keep their values
        name = what.split()[0]
        vals = {p.name: p.value for p in choice.parameter_table()}
        for other, v in {VS: 0.02, ALPHA_S: 0.3, ALPHA_K: 0.2}.items():
            if other != name:
                assert vals[other] == pytest.approx(v)


def test_only_the_named_effects_free_parameters_at_a_nonzero_value_are_searched(dataset):
    # alpha_k is not free; stribeck is not named; alpha_s at zero has no scale
    res = _result({VS: 0.02, ALPHA_S: 0.0, ALPHA_K: 0.2}, ("mu_s", VS, ALPHA_S))
    assert effect_search.effect_points(dataset, res, ("load_dependent_friction",)) == []
    res = _result({VS: 0.02, ALPHA_S: 0.3, ALPHA_K: 0.2}, ("mu_s", VS, ALPHA_S))
    assert sorted(_moved(effect_search.effect_points(dataset, res, ("load_dependent_friction",))))\
        == [ALPHA_S]


def test_a_point_beyond_a_bound_is_clipped_to_it_and_one_clipped_back_to_the_value_left_out(dataset):
    upper = next(p.upper for p in ModelChoice("paper", ("stribeck",)).parameter_table()
                 if p.name == VS)
    res = _result({VS: 0.5 * upper}, ("mu_s", VS))
    assert _moved(effect_search.effect_points(dataset, res, ("stribeck",)))[VS] == \
        pytest.approx([0.15 * upper, upper])
    res = _result({VS: upper}, ("mu_s", VS))
    assert _moved(effect_search.effect_points(dataset, res, ("stribeck",)))[VS] == \
        pytest.approx([0.3 * upper])


def test_the_best_better_end_of_each_model_is_kept(dataset, monkeypatch):
    """Every point of every model is one task; each model keeps its own best end where it beats it."""
    seen: list[float] = []

    def fake_refit(task):
        vs = next(p.value for p in task.choice.parameter_table() if p.name == VS)
        seen.append(vs)
        return FitResult(task.choice, {0.006: 4.0, 0.06: 1.0}.get(round(vs, 6), 9.0), {}, task.free)

    monkeypatch.setattr(effect_search, "refit_task", fake_refit)
    a = _result({VS: 0.02}, ("mu_s", VS), error=5.0)
    b = _result({VS: 0.2}, ("mu_s", VS), error=5.0)  # its points 0.06 and 0.6: 0.06 gains
    c = _result({VS: 0.02}, ("mu_s",), error=5.0)  # nothing free to search
    said: list[str] = []
    out = effect_search.refit_over_effects(dataset, [a, b, c], [("stribeck",)] * 3, say=said.append,
                                           in_process=True)
    assert sorted(seen) == pytest.approx(sorted([0.006, 0.06, 0.06, 0.6]))
    assert out[0].error == 1.0 and out[1].error == 1.0 and out[2] is c
    assert out[0].message == "refitted from stribeck.vs_m_per_s 0.02 -> 0.06 (5 before)"
    assert said[0] == ("effect search of paper + load_dependent_friction + stribeck: refitted from "
                       "stribeck.vs_m_per_s 0.02 -> 0.06, error 5 -> 1")
    worse = _result({VS: 0.002}, ("mu_s", VS), error=0.5)  # 0.0006 and 0.006 end above 0.5
    assert effect_search.refit_over_effects(dataset, [worse], [("stribeck",)],
                                            in_process=True)[0] is worse


@pytest.mark.xfail(strict=True, reason="the premise is gone: since the compiled reader (features "
                   "equal to rounding) the local fit from 4 v_s ends at 1.33 v_s, not in the valley "
                   "at 1.7 v_s this test needs; effect_search is to be replaced by the one search "
                   "(issue 34)")
def test_a_valley_the_local_fit_does_not_leave_is_left_by_refitting_from_another_value():
    """The preset's TLRE with a Stribeck law (v_s 5 mm/s): a fit started at four times v_s stops at
    1.7 times it, and fitting on gains nothing; the refit from a third of that value ends near the
    generating v_s."""
    vs_true = 5e-3
    model = build_model("paper", effects=["stribeck"], effect_params={"stribeck": {"vs_m_per_s": vs_true}})
    ds = prepare_dataset(simulate_campaign(model, "tlre", seed=13, duration_scale=0.5))
    start = ModelChoice("paper", ("stribeck",)).with_values({VS: 4.0 * vs_true})
    local = least_squares_fit(ds, start, free_params(start, ["mu_s", "mu_k", VS], rig=ds.rig),
                              max_nfev=12)
    assert fit_on(ds, local).error > 0.95 * local.error  # the local fit has ended
    assert _vs(local) > 1.5 * vs_true
    [found] = effect_search.refit_over_effects(ds, [local], [("stribeck",)], in_process=True)
    assert found.error < 0.7 * local.error
    assert _vs(found) == pytest.approx(vs_true, rel=0.35)
    assert found.free == local.free


def _vs(result: FitResult) -> float:
    return next(p.value for p in result.choice.parameter_table() if p.name == VS)
