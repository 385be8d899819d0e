"""The search's space and starts (rigctl/workbench/search_space.py, search.py): every effect's off
value is a point of the space exactly, and a search from a fit with an effect added never ends
worse than that fit (the start with the effect off is one of its points)."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from rigctl.model import build_model
from rigctl.model.effects import LIBRARY
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.records.rig_description import RigDescription
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, simulate_campaign
from rigctl.workbench.element_count import spreads_elements
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import added_effects, search_model
from rigctl.workbench.search_space import MASS_LINE_STEP_DECADES, build_space
from rigctl.workbench.selection import with_effects
from tests.workbench.hidden import MAGNITUDE, TEST_BASE, scaled_values

HIDDEN = "load_dependent_friction"


@pytest.fixture(scope="module")
def dataset() -> Dataset:
    """A short force sweep with the load dependence hidden (the selection screen's case)."""
    model = build_model("paper", effects=[HIDDEN], params=TEST_BASE,
                        effect_params={HIDDEN: scaled_values(HIDDEN, MAGNITUDE)})
    runs = simulate_campaign(model, PROTOCOL_FOR_EFFECT[HIDDEN], seed=3, velocity_m_s=2e-5,
                             duration_scale=0.3)
    return prepare_dataset(runs)


@pytest.mark.parametrize("effect", sorted(LIBRARY))
def test_every_effects_off_point_is_the_model_without_it(dataset, effect):
    base = ModelChoice("paper").with_values({**TEST_BASE, "n_elements": 7})
    choice = with_effects(base, (effect,))
    space = build_space(dataset, choice, choice, spreads_elements(choice))
    x_off = space.off_point(space.vector(choice))
    values = space.values(x_off)
    table = {p.name: p for p in choice.parameter_table()}
    offs = LIBRARY[effect]().off_values({n: p.value for n, p in table.items() if "." not in n})
    for name, value in values.items():
        if name.startswith(effect + "."):
            assert value == offs[name.split(".", 1)[1]], name  # exactly, not to an ulp
        else:  # ln and exp of a base value: to an ulp
            assert value == pytest.approx(table[name].value, rel=1e-14, abs=0.0), name
    off_model = choice.with_values(values)
    assert evaluate(dataset, off_model).score.error == pytest.approx(
        evaluate(dataset, base).score.error, rel=1e-9)


def test_a_search_from_a_fit_with_an_effect_added_never_ends_worse_than_that_fit(dataset):
    # a short fit (no global stage): presliding at its default is far worse than the fit it was
    # added to, and so is the data-scale start with presliding off; the fit itself with the effect
    # off must be among the starts
    short = Budget(max_evaluations=60)
    base = search_model(dataset, ModelChoice("paper"), budget=short, workers=0,
                        with_uncertainty=False)
    res = search_model(dataset, with_effects(base.choice, ("presliding",)),
                       budget=Budget(max_evaluations=60), workers=0, with_uncertainty=False)
    assert res.error <= base.error * (1.0 + 1e-9)


def test_only_the_effects_being_added_are_switched_off_in_the_start_from_the_fit(dataset):
    base = ModelChoice("paper").with_values({**TEST_BASE, "n_elements": 7})
    fitted = base.with_effect("presliding").with_values({"presliding.spread": 0.3})
    assert added_effects(fitted) == []
    assert added_effects(with_effects(fitted, ("wear",))) == ["wear"]
    choice = with_effects(fitted, ("wear",))
    space = build_space(dataset, choice, choice, False).switching_off(added_effects(choice))
    off = space.values(space.off_point(space.vector(choice)))
    table = {p.name: p for p in choice.parameter_table()}
    for name, value in off.items():
        if name.startswith("presliding."):  # the model's own fitted effect keeps its value
            assert value == pytest.approx(table[name].value, rel=1e-12), name
    assert off["presliding.spread"] == pytest.approx(0.3)
    assert space.off and {space.free[i].name.split(".")[0] for i in space.off} == {"wear"}


@pytest.mark.slow  # three short searches
def test_a_search_from_a_model_with_fitted_effects_never_ends_worse_than_that_model(dataset):
    short = Budget(max_evaluations=60)
    base = search_model(dataset, ModelChoice("paper"), budget=short, workers=0,
                        with_uncertainty=False)
    # the hidden effect fitted first, then presliding added: the start with every effect off
    # would drop the fitted load dependence too, and presliding at its default is far off
    first = search_model(dataset, with_effects(base.choice, (HIDDEN,)),
                         budget=Budget(max_evaluations=60), workers=0, with_uncertainty=False)
    assert first.error < 0.8 * base.error
    second = search_model(dataset, with_effects(first.choice, ("presliding",)),
                          budget=Budget(max_evaluations=60), workers=0, with_uncertainty=False)
    assert second.error <= first.error * (1.0 + 1e-9)


def test_the_mass_line_steps_half_decades_over_the_plausible_mass_at_the_damping_ratio(dataset):
    choice = ModelChoice("paper")
    unstated = replace(dataset, rig=RigDescription())  # another lab's record: no mass stated
    space = build_space(unstated, choice, choice, False)
    names = [fp.name for fp in space.free]
    im, ic = names.index("m_kg"), names.index("c0_N_s_per_m")
    x0 = space.vector(choice)
    line = space.mass_line(x0)
    lo, hi = space.spread[im]
    steps = sorted(round((x[im] - x0[im]) / math.log(10.0) / MASS_LINE_STEP_DECADES, 9)
                   for x in line)
    inside = [k for k in range(-8, 9) if k != 0
              and lo - 1e-9 <= x0[im] + k * MASS_LINE_STEP_DECADES * math.log(10.0) <= hi + 1e-9]
    assert steps == inside and len(inside) >= 6  # every half decade of the interval, x0 apart
    for x in line:  # the damping at x0's damping ratio: ln C0 moves by half of ln M
        assert x[ic] - x0[ic] == pytest.approx(0.5 * (x[im] - x0[im]))
        others = [j for j in range(space.dim) if j not in (im, ic)]
        assert (x[others] == x0[others]).all()
    stated = build_space(dataset, choice, choice, False)  # the simulated rig states its mass
    assert "m_kg" not in [fp.name for fp in stated.free]
    assert stated.mass_line(stated.vector(choice)) == []
