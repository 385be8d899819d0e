"""The slider mass searched with the rest of the model refitted at each mass
(:mod:`rigctl.workbench.mass_search`)."""

from __future__ import annotations

import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.identify import free_params, least_squares_fit
from rigctl.workbench.mass_search import refit_over_mass
from rigctl.workbench.model_choice import ModelChoice

pytestmark = pytest.mark.slow  # full fits or diagnoses: the slow tier (make test-all)

FREE = ["m_kg", "c0_N_s_per_m", "mu_s", "mu_k", "k0_N_per_m"]


@pytest.fixture(scope="module")
def runs():
    # 30 s of the preset's TLRE at 1024 Hz: 5 slips, the 48 g slider's ringing not resolved
    return simulate_campaign(build_model("paper"), "tlre", seed=41, duration_scale=0.5)


def _unstated(runs):
    """The runs as another lab's record: the rig's mass and damping not stated."""
    out = []
    for run in runs:
        meta = {k: v for k, v in run.metadata.items() if not k.startswith("rig.")}
        out.append(type(run)(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, run.d1_m, run.d2_m,
                             dict(run.extra), meta, run.source))
    return out


def _fit_from_heavy(dataset, factor=30.0):
    """A local fit started with 30 times the true mass (damping ratio kept): it stays heavy."""
    preset = ModelChoice("paper")
    vals = {p.name: p.value for p in preset.parameter_table()}
    start = preset.with_values({"m_kg": vals["m_kg"] * factor,
                                "c0_N_s_per_m": vals["c0_N_s_per_m"] * factor**0.5})
    free = free_params(start, FREE, rig=dataset.rig)
    return least_squares_fit(dataset, start, free, max_nfev=12), vals["m_kg"]


def _mass(result):
    return next(p.value for p in result.choice.parameter_table() if p.name == "m_kg")


def test_a_mass_the_local_fit_does_not_leave_is_found_by_refitting_at_other_masses(runs):
    dataset = prepare_dataset(_unstated(runs))
    assert not dataset.mass_from_ringing
    local, m_true = _fit_from_heavy(dataset)
    assert _mass(local) > 3.0 * m_true  # the local fit stays in the heavy valley
    said: list[str] = []
    found = refit_over_mass(dataset, local, say=said.append, in_process=True)
    assert found.error < 0.7 * local.error
    assert _mass(found) == pytest.approx(m_true, rel=0.2)
    assert found.free == local.free
    assert said and said[0].startswith("mass search of paper: refitted from another mass")


def test_a_stated_mass_is_not_searched(runs):
    dataset = prepare_dataset(runs)  # the simulated rig states its mass
    assert "m_kg" in dataset.rig.fixed
    preset = ModelChoice("paper")
    fit = least_squares_fit(dataset, preset, free_params(preset, ["mu_s", "mu_k"]), max_nfev=4)
    fit.free = (*fit.free, "m_kg")  # even where a caller lists it as free
    assert refit_over_mass(dataset, fit, in_process=True) is fit
