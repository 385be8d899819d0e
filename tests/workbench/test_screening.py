"""The score screen (rigctl/workbench/screening.py): the linear profile over the base, and on small
generated campaigns with one hidden library effect, the generating effect among the sets the screen
keeps, at a fraction of a short fit's evaluations."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.records.dataset import Dataset, prepare_dataset
from rigctl.workbench import selection as sel
from rigctl.workbench.budget import Budget
from rigctl.workbench.campaigns import PROTOCOL_FOR_EFFECT, simulate_campaign
from rigctl.workbench.identify import FitResult, fn_range, physically_valid
from rigctl.workbench.model_choice import ModelChoice, with_effects
from rigctl.workbench.screening import base_basis, profiled_cost, score_screen, screened_error
from rigctl.workbench.search import search_model
from rigctl.workbench.start_error import error_or_inf
from tests.workbench.hidden import DECOYS, MAGNITUDE, TEST_BASE, scaled_values

SHORT_FIT_EVALUATIONS = 60
"""The short fit's budget (tests/workbench/test_selection_screen.py): what the score screen saves
against."""


def test_the_profile_removes_what_the_base_explains_and_keeps_the_rest():
    rng = np.random.default_rng(0)
    J = rng.normal(size=(40, 3))
    J = np.column_stack([J, J[:, 0] + J[:, 1], np.zeros(40)])  # a dependent and a dead column
    Q = base_basis(J)
    assert Q.shape == (40, 3)
    assert np.allclose(Q.T @ Q, np.eye(3))
    inside = J @ np.array([1.0, -2.0, 0.5, 0.3, 7.0])
    assert profiled_cost(inside, Q) == pytest.approx(0.0, abs=1e-18 * float(inside @ inside) + 1e-20)
    outside = rng.normal(size=40)
    outside -= Q @ (Q.T @ outside)
    assert profiled_cost(outside + inside, Q) == pytest.approx(float(outside @ outside))
    assert base_basis(np.zeros((5, 2))).shape == (5, 0)


def test_a_set_is_credited_only_with_what_it_adds_to_the_base_s_own_linear_re_fit():
    # the model's |r0|^2 = 100; its base re-fitted linearly predicts 64 (an unfinished fit or a
    # rough residual): a set whose best point is the off point, or a point at the same profiled
    # cost, gains nothing; one at 16 halves the error of the re-fitted base
    assert screened_error(5.0, 64.0, 64.0, 100.0) == pytest.approx(5.0)
    assert screened_error(5.0, 16.0, 64.0, 100.0) == pytest.approx(2.5)
    # a model at its least-squares minimum: the off point's profile removes nothing
    assert screened_error(5.0, 25.0, 100.0, 100.0) == pytest.approx(2.5)
    # a profile that removes everything at off falls back to the model's own cost
    assert screened_error(5.0, 0.0, 0.0, 100.0) == 0.0
    assert screened_error(5.0, 0.0, 0.0, 0.0) == 5.0


def _dataset(hidden: str) -> Dataset:
    model = build_model("paper", effects=[hidden], params=TEST_BASE,
                        effect_params={hidden: scaled_values(hidden, MAGNITUDE)})
    runs = simulate_campaign(model, PROTOCOL_FOR_EFFECT[hidden], seed=3, velocity_m_s=2e-5,
                             duration_scale=0.3)
    return prepare_dataset(runs)


def _case(hidden: str) -> tuple[Dataset, FitResult]:
    dataset = _dataset(hidden)
    base = search_model(dataset, ModelChoice("paper"),
                        budget=Budget(max_evaluations=SHORT_FIT_EVALUATIONS), workers=1,
                        with_uncertainty=False)
    return dataset, base


def test_the_hidden_effect_screens_first_at_a_fraction_of_a_short_fit():
    hidden = "load_dependent_friction"
    dataset, base = _case(hidden)
    sets = [(hidden,), ("wear",), ("stribeck",)]
    out = score_screen(dataset, base, sets, workers=1)
    assert out[0].effects == (hidden,), out
    assert out[0].error < 0.7 * base.error, out
    # the first set pays for the base's Jacobian too; every other costs 0.6 of a short fit at
    # most (its points twice: as drawn, and with the base levels re-read there, each re-read a
    # run of its own)
    assert all(s.evaluations <= 0.6 * SHORT_FIT_EVALUATIONS for s in out if s.effects != sets[0])
    # a set that helps nowhere screens at the model's own error, re-fitted linearly
    assert all(s.error <= base.error * (1 + 1e-9) for s in out)
    # the best point is a start for the set's full fit, which cannot end worse than it
    start = out[0].start
    assert start is not None and start.effects == (*base.choice.effects, hidden)
    e_start = error_or_inf(dataset, start, fn_range(dataset))
    assert out[0].error <= e_start  # the screened error has the base re-fitted linearly
    fit = search_model(dataset, with_effects(base.choice, (hidden,)), starts=(start,),
                       budget=Budget(max_evaluations=30), workers=1, with_uncertainty=False)
    assert fit.error <= e_start * (1 + 1e-9)


@pytest.mark.slow  # a short base fit and six screens per case: about 5 s each
@pytest.mark.parametrize("hidden", [
    "load_dependent_friction", "stribeck", "interface_damping", "sensor_dynamics", "presliding",
    "rate_state", "load_dependent_stiffness", "contact_degradation",
    pytest.param("stress_evolution", marks=pytest.mark.xfail(
        strict=True, reason="at duration_scale 0.3 the hidden stress evolution moves the error "
        "from 0.27 to 0.23 only in a short fit's hands, and none of the screen's points (the "
        "score step and eight spread points, the base re-fitted linearly) gains on the off "
        "value: a weak signature whose optimum lies in a fraction of the plausible range")),
])
def test_the_screen_keeps_the_hidden_effect(hidden: str):
    dataset, base = _case(hidden)
    pool = list(dict.fromkeys([hidden, *DECOYS[hidden], "stribeck", "presliding", "wear"]))
    out = score_screen(dataset, base, [(c,) for c in pool], workers=1)
    kept = [s.effects for s in out[: sel.SCREEN_KEEP]]
    assert (hidden,) in kept, [(s.effects, round(s.error, 3)) for s in out]


def test_an_effect_whose_defaults_are_invalid_is_searched_from_off():
    """A model whose kinetic friction is close to the initial stage's mu_s,max: the default
    exponents of load_dependent_friction take mu_k above it at the sweep's 350 N, so the model
    with the effect at its defaults cannot be run, but the model it is added to can. Adding it
    must search from off (the screen and the fit alike), not refuse the model."""
    dataset = _dataset("load_dependent_friction")
    model = ModelChoice("paper").with_values({"mu_s": 0.14, "mu_k": 0.139, "mu_smax": 0.141})
    added = model.with_effect("load_dependent_friction")
    assert not physically_valid(added, fn_range(dataset))
    assert physically_valid(model, fn_range(dataset))
    fit = search_model(dataset, added, budget=Budget(max_evaluations=30), workers=0,
                       with_uncertainty=False)
    assert math.isfinite(fit.error)
    assert physically_valid(fit.choice, fn_range(dataset))
