"""A fit that adds effects also searches from the data's mass and damping
(:func:`rigctl.workbench.search.dynamics_guessed`): a second pass from the given starts with the
slider mass and drive damping at the data-scale start's, the better pass the answer."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.data_start import data_scaled
from rigctl.workbench.identify import FitResult, free_params
from rigctl.workbench.model_choice import ModelChoice, with_effects
from rigctl.workbench.search import dynamics_guessed, search_model
from rigctl.workbench.search_space import build_space
from tests.workbench.test_search import FN_N, NOISE, RIG, V_M_S

PASS = "from the data's mass and damping"


def _record(state_mass: bool) -> Dataset:
    model = build_model("paper", params=RIG)
    runs = simulate_campaign(model, "tlre", seed=5, noise=NOISE, sample_rate_hz=1000.0,
                             fn_N=FN_N, velocity_m_s=V_M_S, duration_scale=0.25)
    if not state_mass:
        for run in runs:
            for name in ("m_kg", "c0_N_s_per_m"):
                run.metadata.pop(f"rig.{name}", None)
    return prepare_dataset(runs)


@pytest.fixture(scope="module")
def record() -> Dataset:
    """A 15 s TLRE of another rig's scale at 1 kHz that states no mass or damping."""
    return _record(state_mass=False)


@pytest.fixture(scope="module")
def base(record: Dataset) -> FitResult:
    return search_model(record, ModelChoice("paper"), workers=2, with_uncertainty=False)


def _guessed(record: Dataset, choice: ModelChoice) -> tuple[list[ModelChoice], ModelChoice]:
    scaled = data_scaled(record, choice, free_params(choice, rig=record.rig))
    assert scaled is not None
    space = build_space(record, choice, scaled, spreads_elements=False)
    return dynamics_guessed([choice, scaled], scaled, space), scaled


def test_the_guessed_starts_are_the_given_ones_at_the_data_s_mass_and_damping(record):
    fitted = ModelChoice("paper", values={"mu_s": 0.41, "mu_k": 0.29, "m_kg": 0.5,
                                          "c0_N_s_per_m": 0.01})
    choice = with_effects(fitted, ("stribeck",))
    guessed, scaled = _guessed(record, choice)
    # the data-scale start has the data's mass and damping already: only the model's is new
    assert len(guessed) == 1
    (g,) = guessed
    for name in ("m_kg", "c0_N_s_per_m"):
        assert g.values[name] == scaled.values[name] != choice.values[name]
    assert {k: v for k, v in g.values.items() if k not in ("m_kg", "c0_N_s_per_m")} == \
        {k: v for k, v in choice.values.items() if k not in ("m_kg", "c0_N_s_per_m")}


def test_no_start_is_guessed_where_the_rig_states_its_mass_and_damping():
    stated = _record(state_mass=True)
    choice = ModelChoice("paper", ("stribeck",), {"mu_s": 0.4})
    assert _guessed(stated, choice)[0] == []


@pytest.mark.slow
def test_a_fit_that_adds_an_effect_searches_from_the_data_s_mass_and_damping_too(record, base):
    # the base's fit at a mass and damping decades off: an effect's fit from those values
    off = base.choice.with_values({"m_kg": base.choice.values["m_kg"] * 30.0,
                                   "c0_N_s_per_m": base.choice.values["c0_N_s_per_m"] / 30.0})
    res = search_model(record, with_effects(off, ("stribeck",)), workers=2,
                       with_uncertainty=False)
    assert PASS in res.message
    # the better pass is the answer: it is no worse than the base's own fit, which the data's
    # mass and damping lead back to
    assert res.error <= base.error * 1.001


@pytest.mark.slow
def test_a_fit_that_adds_nothing_has_one_pass(record, base):
    res = search_model(record, base.choice, workers=2, with_uncertainty=False)
    assert PASS not in res.message


@pytest.mark.slow
def test_a_model_with_no_fitted_values_has_one_pass_that_walks_every_start_s_mass_line(record):
    res = search_model(record, ModelChoice("paper", ("stribeck",)), workers=2,
                       with_uncertainty=False)
    assert PASS not in res.message


@pytest.mark.slow
def test_no_second_pass_is_begun_that_the_budget_cannot_pay_for(record, base):
    choice = with_effects(base.choice, ("stribeck",))
    both = search_model(record, choice, workers=2, with_uncertainty=False)
    assert PASS in both.message
    # a second pass is begun only while the budget left pays for one like the first: about
    # half of both passes cannot
    budget = Budget(max_evaluations=int(0.55 * both.n_evaluations))
    res = search_model(record, choice, workers=2, with_uncertainty=False, budget=budget)
    assert PASS not in res.message
    assert budget.max_evaluations is not None
    assert res.n_evaluations <= budget.max_evaluations
