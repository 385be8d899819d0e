"""The normal force's swing with Ft is taken out of the drive's applied load (fn_coupling.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import Drive, Simulator, build_model
from rigctl.records import fn_coupling
from rigctl.records.dataset import prepare_dataset
from rigctl.records.drive_profile import drive_profile
from rigctl.records.fn_coupling import applied_normal_force, coupling_ratio


def _run(kappa: float, seed: int = 5, *, seconds: float = 12.0, v_m_s: float = 2e-5,
         params: dict[str, float] | None = None):
    effects = ["normal_coupling"] if kappa else []
    effect_params = {"normal_coupling": {"kappa": kappa}} if kappa else {}
    model = build_model("paper", effects=effects, params=params, effect_params=effect_params)
    res = Simulator(model, sample_rate_hz=2000.0).run(Drive.constant(300.0, v_m_s, seconds),
                                                      noise=True, seed=seed, record_elements=False)
    return res.to_measured()


@pytest.mark.parametrize("kappa", [0.1, -0.08])
def test_the_ratio_at_slips_is_the_frames_coupling(kappa):
    run = _run(kappa)
    c, se = coupling_ratio(run.ft_N, run.fn_N)
    assert c == pytest.approx(kappa, abs=0.15 * abs(kappa)) and abs(c) > 5 * se


def test_without_coupling_the_measured_load_is_the_drive():
    run = _run(0.0)
    c, se = coupling_ratio(run.ft_N, run.fn_N)
    assert abs(c) < 0.01 and abs(c) < 5 * se
    fn, c = applied_normal_force(run.ft_N, run.fn_N)
    assert c == 0.0 and fn is run.fn_N
    assert drive_profile(run).fn_per_ft == 0.0


def test_a_coupling_within_the_drive_fits_tolerance_still_leaves_the_level():
    # kappa 0.1 swings Fn by about 4 N at 300 N, within the fit's 3 %; its mean still lifts the
    # measured level by kappa * mean(Ft), which the applied load does not have
    run = _run(0.1)
    prof = drive_profile(run)
    assert prof.fn_per_ft == pytest.approx(0.1, abs=0.015)
    loaded = prof.fn_N[prof.t_s > 3.0]
    assert np.median(loaded) == pytest.approx(300.0, abs=1.0)
    assert np.median(run.fn_N[run.t_s > 3.0]) > 302.0  # the measured level is lifted


def test_the_drive_takes_the_applied_load_not_the_coupled_swing():
    # a swing within the drive fit's tolerance (3 % of Fn) never shows in the drive; this one does
    run = _run(0.3)
    assert np.ptp(run.fn_N[run.t_s > 3.0]) > 12.0  # the measured load swings with every slip
    prof = drive_profile(run)
    assert prof.fn_per_ft == pytest.approx(0.3, abs=0.045)
    loaded = prof.fn_N[prof.t_s > 3.0]
    assert np.ptp(loaded) < 1.0 and np.median(loaded) == pytest.approx(300.0, abs=1.5)


def test_too_few_slips_give_no_ratio():
    t = np.linspace(0.0, 1.0, 500)
    assert coupling_ratio(10.0 * t, 300.0 + t)[0] == 0.0  # a smooth ramp: no slip steps


HEAVY = {"m_kg": 20.0, "k0_N_per_m": 2.5e4}
"""A 20 kg slider on a 25 kN/m spring, driven at 1 mm/s: a slip lasts about 90 ms (180 samples),
and no one-sample step of it stands 10 step-noises out."""


def _heavy_run(seconds: float, seed: int = 5, kappa: float = 0.1):
    return _run(kappa, seed, seconds=seconds, v_m_s=1e-3, params=HEAVY)


def test_a_slow_slip_is_read_over_longer_steps(monkeypatch):
    run = _heavy_run(12.0)
    c, se = coupling_ratio(run.ft_N, run.fn_N)
    assert c == pytest.approx(0.1, abs=0.015) and abs(c) > 5 * se
    # over one-sample steps alone the coupling is not significant
    monkeypatch.setattr(fn_coupling, "LAGS_SAMPLES", (1,))
    c1, se1 = coupling_ratio(run.ft_N, run.fn_N)
    assert not abs(c1) > 5 * se1


def test_a_run_with_few_slips_takes_the_campaign_coupling():
    long, short = _heavy_run(12.0, kappa=0.05), _heavy_run(2.6, seed=6, kappa=0.05)
    c, se = coupling_ratio(short.ft_N, short.fn_N)
    assert not abs(c) > 5 * se  # alone, its one slip does not tell
    assert drive_profile(short).fn_per_ft == 0.0
    ds = prepare_dataset([long, short])
    assert ds.runs[1].drive.fn_per_ft == pytest.approx(0.05, abs=0.01)
    assert ds.runs[0].drive.fn_per_ft == ds.runs[1].drive.fn_per_ft
