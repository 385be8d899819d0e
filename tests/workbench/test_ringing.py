"""The post-slip ringing gives a model of another rig its mass and damping, where the sampling
resolves it, and never an alias (identification.md, "Starting values from the data")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.records.ringing import RingFit, Ringing, campaign_ringing, fit_ring
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.data_scale import PRESET, DataScale, base_start
from rigctl.workbench.data_start import campaign_scale, data_scaled
from rigctl.workbench.identify import Objective, free_params
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.search import search_model
from tests.workbench.synth import sawtooth_run

# a heavy slider on a soft drive: it rings at 64 Hz in stick (32 Hz on the drive spring alone
# during a slip), resolved at 2 kHz
RIG = {"k0_N_per_m": 2.0e4, "kts_N_per_m": 6.0e4, "m_kg": 0.5, "c0_N_s_per_m": 3.0,
       "mu_s": 0.5, "mu_k": 0.4, "mu_smax": 0.55, "kt0_N_per_m": 6.0e4, "n_elements": 12}
RATE_HZ = 2000.0
OMEGA_N = math.sqrt((RIG["k0_N_per_m"] + RIG["kts_N_per_m"]) / RIG["m_kg"])
SIGMA = RIG["c0_N_s_per_m"] / (2.0 * RIG["m_kg"])


@pytest.fixture(scope="module")
def heavy_rig():
    runs = simulate_campaign(build_model("paper", params=RIG), "tlre", seed=5,
                             sample_rate_hz=RATE_HZ, fn_N=50.0, velocity_m_s=5e-4,
                             duration_scale=0.5)
    for run in runs:  # another lab's record: mass and damping not stated
        for key in [k for k in run.metadata if k.startswith("rig.")]:
            del run.metadata[key]
    return prepare_dataset(runs)


def test_a_resolved_ringing_gives_its_frequency_and_decay(heavy_rig):
    ring = campaign_scale(heavy_rig).ringing
    assert ring.resolved, ring
    f_d = math.sqrt(OMEGA_N**2 - SIGMA**2) / (2.0 * math.pi)
    assert ring.freq_hz == pytest.approx(f_d, rel=0.01)
    assert ring.decay_per_s == pytest.approx(SIGMA, rel=0.15)
    assert ring.omega_n2 == pytest.approx(OMEGA_N**2, rel=0.02)


def test_the_data_scale_start_takes_mass_and_damping_from_it(heavy_rig):
    scaled = data_scaled(heavy_rig, ModelChoice("paper"), [])
    assert scaled is not None
    start = scaled.values
    assert start["m_kg"] == pytest.approx(RIG["m_kg"], rel=0.15)
    assert start["c0_N_s_per_m"] == pytest.approx(RIG["c0_N_s_per_m"], rel=0.25)
    # without the ringing the mass would keep the preset's slip frequency: 0.65 g, not 0.5 kg
    preset_rule = start["k0_N_per_m"] * PRESET["m_kg"] / PRESET["k0_N_per_m"]
    assert preset_rule < 0.01 * RIG["m_kg"]


def test_a_stated_mass_wins_over_the_ringing():
    scale = DataScale(fn_N=50.0, v_m_per_s=1e-4, mu_peak=0.5, mu_trough=0.3, mu_first=0.55,
                      k_eff_N_per_m=1.5e4, k_stick_N_per_m=6e4, stick_s=1.0,
                      ringing=Ringing(freq_hz=60.0, decay_per_s=3.0, n_resolved=20, n_tried=20))
    current = {p.name: p.value for p in ModelChoice("paper").parameter_table()}
    free = base_start(scale, current)
    assert free["m_kg"] == pytest.approx((free["k0_N_per_m"] + free["kts_N_per_m"])
                                         / Ringing(60.0, 3.0).omega_n2)
    assert free["c0_N_s_per_m"] == pytest.approx(2.0 * 3.0 * free["m_kg"])
    stated = base_start(scale, current, fixed={"m_kg": 0.2})
    assert stated["m_kg"] == 0.2
    assert stated["c0_N_s_per_m"] == pytest.approx(2.0 * 3.0 * 0.2)


def _stick_window(true_hz: float, fs_hz: float, seed: int = 0):
    """Samples of a stick after a slip: a loading line and a ringing at ``true_hz``."""
    rng = np.random.default_rng(seed)
    t = 0.004 + np.arange(int(0.4 * fs_hz)) / fs_hz
    f = 20.0 + 5.0 * t + 2.0 * np.exp(-SIGMA * t) * np.cos(2.0 * math.pi * true_hz * t)
    return t, f + rng.normal(0.0, 0.02, t.size)


def test_an_aliased_ringing_is_not_taken_for_one():
    """This rig's own 1.1 kHz ringing at 1024 Hz reads as a clean 95 Hz ringing; the slip before it
    fell within a sample, which a 95 Hz ringing cannot follow (ringing.py, the alias test)."""
    t, f = _stick_window(1119.5, 1024.0)
    alias = fit_ring(t, f, 0.02, half_fall_s=0.6 / 1024.0, step_frac=1.0, t_drop_s=0.0)
    assert alias is not None
    assert alias.freq_hz == pytest.approx(1119.5 - 1024.0, rel=0.01)
    assert not alias.resolved
    # the same window after a slip that took a quarter of a 75 Hz swing to fall half-way is a
    # ringing the sampling resolves
    slow = fit_ring(t, f, 0.02, half_fall_s=1.0 / (4.0 * 75.0),
                    step_frac=2.0 * math.pi * 75.0 / 1024.0, t_drop_s=0.0)
    assert slow is not None and slow.resolved


def test_rings_at_scattered_phases_are_not_a_ringing():
    rng = np.random.default_rng(1)
    aligned = [RingFit(95.5, 40.0, True, float(p)) for p in rng.normal(1.0, 0.1, 20)]
    scattered = [RingFit(95.5, 40.0, True, float(p)) for p in rng.uniform(0, 2 * math.pi, 20)]
    assert campaign_ringing(aligned).resolved
    assert not campaign_ringing(scattered).resolved
    # a ringing after a few of the slips only is not the campaign's
    few = aligned[:6] + [RingFit(math.nan, math.nan, False)] * 30
    assert not campaign_ringing(few).resolved


@pytest.mark.slow
def test_this_rigs_own_campaign_and_instant_slips_show_no_ringing():
    """At 1024 Hz this rig's ringing is aliased (the preset's slip frequency is kept); the
    synthetic records' slips are instantaneous, with an apparent 130 Hz ringing after them."""
    own = prepare_dataset(simulate_campaign(build_model("paper"), "slide_hold_slide", seed=3,
                                            duration_scale=0.5))
    assert not campaign_scale(own).ringing.resolved
    run, _ = sawtooth_run(duration_s=30.0)
    assert not campaign_scale(prepare_dataset([run])).ringing.resolved
    quiet, _ = sawtooth_run(duration_s=30.0, ring_N=0.0)
    assert not campaign_scale(prepare_dataset([quiet])).ringing.resolved


@pytest.mark.slow
def test_a_fit_keeps_the_mass_at_the_measured_ringing(heavy_rig):
    """Where the ringing is resolved and the mass not stated, the mass follows K0 + Kts at the
    measured frequency in every fit (identify.Objective), and the dataset says so."""
    assert heavy_rig.mass_from_ringing
    assert any("post-slip ringing resolved" in n for n in heavy_rig.notes)
    res = search_model(heavy_rig, ModelChoice("paper"), with_uncertainty=False)
    v = res.choice.values
    assert "m_kg" not in res.free
    assert v["m_kg"] == pytest.approx(
        (v["k0_N_per_m"] + v["kts_N_per_m"]) / heavy_rig.ringing.omega_n2, rel=1e-9)
    assert v["m_kg"] == pytest.approx(RIG["m_kg"], rel=0.1)
    assert res.error < 2.0


def test_the_tied_mass_stays_within_its_bounds(heavy_rig):
    """A fit may try stiffnesses whose tied mass lies beyond the mass's bounds; the point is then
    the bound's (it failed in the final evaluation before)."""
    free = free_params(ModelChoice("paper"), ["k0_N_per_m", "kts_N_per_m"])
    obj = Objective(heavy_rig, ModelChoice("paper"), free)
    u = np.array([fp.to_u(1e13) for fp in free])
    assert obj.values(u)["m_kg"] == 1e5
    ModelChoice("paper").with_values(obj.values(u)).build()  # no ParameterError
