"""The normal force's swing with Ft is taken out of the drive's applied load (fn_coupling.py)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.model import Drive, Simulator, build_model
from rigctl.workbench.drive_profile import drive_profile
from rigctl.workbench.fn_coupling import applied_normal_force, coupling_ratio


def _run(kappa: float, seed: int = 5):
    effects = ["normal_coupling"] if kappa else []
    params = {"normal_coupling": {"kappa": kappa}} if kappa else {}
    model = build_model("paper", effects=effects, effect_params=params)
    res = Simulator(model, sample_rate_hz=2000.0).run(Drive.constant(300.0, 2e-5, 12.0),
                                                      noise=True, seed=seed, record_elements=False)
    return res.to_measured()


@pytest.mark.parametrize("kappa", [0.1, -0.08])
def test_the_ratio_at_slips_is_the_frames_coupling(kappa):
    run = _run(kappa)
    assert coupling_ratio(run.ft_N, run.fn_N) == pytest.approx(kappa, abs=0.15 * abs(kappa))


def test_without_coupling_the_measured_load_is_the_drive():
    run = _run(0.0)
    assert abs(coupling_ratio(run.ft_N, run.fn_N)) < 0.01
    fn, c = applied_normal_force(run.ft_N, run.fn_N, fn_tol_N=9.0)
    assert c == 0.0 and fn is run.fn_N
    assert drive_profile(run).fn_per_ft == 0.0
    # a coupling whose swing stays within the drive fit's tolerance is left in the measured load
    weak = _run(0.1)
    assert drive_profile(weak).fn_per_ft == 0.0


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
    assert coupling_ratio(10.0 * t, 300.0 + t) == 0.0  # a smooth ramp: no slip steps
