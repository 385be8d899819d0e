"""Identification recovers parameters, reports uncertainties and flags what the data cannot see."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import free_params, least_squares_fit, with_uncertainties
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import search_model

TRUTH = {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
         "mu_smax": 0.21, "kt0_N_per_m": 1.7e6, "p_slope": 0.8}


@pytest.fixture(scope="module")
def tlre():
    return prepare_dataset(simulate_campaign(build_model("paper", params=TRUTH), "tlre", seed=11))


@pytest.mark.slow
def test_base_parameters_are_recovered_from_a_noisy_run(tlre):
    res = search_model(tlre, ModelChoice("paper"), workers=2)
    for name in ("mu_s", "mu_k", "kts_N_per_m", "k0_N_per_m", "mu_smax"):
        assert res.choice.values[name] == pytest.approx(TRUTH[name], rel=0.03), name
    assert res.error < 2.0
    assert set(res.sigma) == set(res.free)
    assert all(s > 0 for s in res.sigma.values())
    assert "mu_s" not in res.undetermined


def test_a_parameter_without_influence_on_the_data_is_flagged(tlre):
    choice = ModelChoice("paper").with_values(TRUTH).with_effect("contact_degradation").with_values(
        {"contact_degradation.amplitude": 0.0})
    free = free_params(choice, ["mu_s", "contact_degradation.n_cycles"])
    res = least_squares_fit(tlre, choice, free, max_nfev=4, with_uncertainty=True)
    assert "contact_degradation.n_cycles" in res.undetermined
    assert "mu_s" not in res.undetermined


def test_uncertainties_at_a_fit_s_own_values_are_the_fit_s(tlre):
    """``with_uncertainties`` takes them where a fit ended, without fitting further (the final
    ``--auto`` model's, after its polishing passes)."""
    free = free_params(ModelChoice("paper"), ["mu_s", "mu_k", "k0_N_per_m"])
    plain = least_squares_fit(tlre, ModelChoice("paper"), free, max_nfev=3)
    assert not plain.sigma
    res = with_uncertainties(tlre, plain)
    assert res.choice.values == plain.choice.values and res.error == plain.error
    fitted = least_squares_fit(tlre, ModelChoice("paper"), free, max_nfev=3, with_uncertainty=True)
    assert fitted.choice.values == plain.choice.values
    for name in ("mu_s", "mu_k", "k0_N_per_m"):
        # the same point, but the internal units differ (u is relative to the start: 1.0 here,
        # 1.16 for mu_k in the fit), so the finite-difference steps differ by up to 16 % in
        # parameter units; over a residual with sample-phase steps (drop sharpness and delay at
        # 1024 Hz) the two Jacobians agree to a few per cent, not to rounding
        assert res.sigma[name] == pytest.approx(fitted.sigma[name], rel=5e-2), name
    assert res.jacobian is not None and res.jacobian.shape[1] == 3
