"""On another rig's data both starts are fitted (fitting.identify_model); the preset's start keeps
the preset's mass and damping in its first fit. Where its end is kept, they are scanned and fitted
on from there, so that later fits (candidates, refits) fit them too: kept at the preset, a 48 g
mass stayed through a whole held-out diagnosis of an 8.9 g slider."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench import fitting
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import FitResult
from rigctl.workbench.model_choice import ModelChoice

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)

PRESET_END = ModelChoice("paper").with_values({"mu_s": 0.21, "mu_k": 0.11})
SCALED = ModelChoice("paper").with_values({"mu_s": 0.3, "mu_k": 0.2})


def _dataset(stated: bool):
    runs = simulate_campaign(build_model("paper"), "tlre", seed=4, duration_scale=0.3)
    if not stated:  # another lab's record: mass and damping not stated
        for run in runs:
            for key in [k for k in run.metadata if k.startswith("rig.")]:
                del run.metadata[key]
    return prepare_dataset(runs)


@pytest.fixture(scope="module")
def unstated():
    return _dataset(stated=False)


@pytest.fixture(scope="module")
def stated():
    return _dataset(stated=True)


def _fake_fits(monkeypatch, errors):
    """identify_model on another rig's data with fits replaced: ``errors`` maps (start, free
    dynamics) to the error the fit from there ends at; returns the calls made."""
    calls = []

    def fit_from(dataset, choice, e_start, free, fns, *, free_dynamics, max_nfev,
                 with_uncertainty):
        start = "scaled" if choice == SCALED else "preset end" if choice == PRESET_END \
            else "preset"
        calls.append((start, free_dynamics))
        names = [fp.name for fp in free]
        if free_dynamics:
            names += fitting._dynamics_to_fit(dataset, names)
        end = PRESET_END if start == "preset" else choice
        return FitResult(end, errors[(start, free_dynamics)], {}, tuple(names))

    monkeypatch.setattr(fitting, "_fit_from", fit_from)
    monkeypatch.setattr(fitting, "data_scaled", lambda dataset, choice, free: SCALED)
    monkeypatch.setattr(fitting, "_another_rig", lambda model, scaled: True)
    monkeypatch.setattr(fitting, "error_or_inf", lambda dataset, choice, fns: 10.0)
    return calls


def test_a_kept_preset_end_has_its_mass_and_damping_fitted_on(monkeypatch, unstated):
    calls = _fake_fits(monkeypatch, {("preset", False): 1.0, ("scaled", True): 2.0,
                                     ("preset end", True): 0.5})
    res = fitting.identify_model(unstated, ModelChoice("paper"))
    assert calls == [("preset", False), ("scaled", True), ("preset end", True)]
    assert res.error == 0.5 and res.choice == PRESET_END
    assert {"m_kg", "c0_N_s_per_m"} <= set(res.free)


def test_a_kept_data_scale_end_is_not_fitted_again(monkeypatch, unstated):
    calls = _fake_fits(monkeypatch, {("preset", False): 3.0, ("scaled", True): 2.0})
    res = fitting.identify_model(unstated, ModelChoice("paper"))
    assert calls == [("preset", False), ("scaled", True)]
    assert res.error == 2.0 and res.choice == SCALED


def test_stated_mass_and_damping_stay_fixed(monkeypatch, stated):
    """The simulated rig states M and C0: the preset's end is kept as it is."""
    calls = _fake_fits(monkeypatch, {("preset", False): 1.0, ("scaled", True): 2.0})
    res = fitting.identify_model(stated, ModelChoice("paper"))
    assert calls == [("preset", False), ("scaled", True)]
    assert res.error == 1.0 and "m_kg" not in res.free
