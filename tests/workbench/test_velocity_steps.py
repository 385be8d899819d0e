"""Velocity steps: features do not depend on where in the cycle a step falls (smooth fit landscape)."""

from __future__ import annotations

import numpy as np

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.records.drive_profile import DriveProfile
from rigctl.records.features import _stick_duration
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.model_choice import ModelChoice

BASE = {"mu_s": 0.13, "mu_k": 0.09, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.3e6}


def test_stick_duration_is_stage_travel_over_the_drive_velocity_at_the_drop():
    # 10 um/s for 2 s, then 50 um/s: a drop 0.5 s after the step, the previous one 1 s before it
    drive = DriveProfile(np.array([0.0, 2.0, 4.0]), np.array([0.0, 20e-6, 120e-6]),
                         np.full(3, 300.0), 0.0)
    travel = 10e-6 * 1.0 + 50e-6 * 0.5
    assert np.isclose(_stick_duration(drive, 1.0, 2.5), travel / 50e-6)
    # at constant velocity it is the time between the drops
    assert np.isclose(_stick_duration(drive, 0.2, 1.7), 1.5)
    # the stage at rest at the drop: the time
    hold = DriveProfile(np.array([0.0, 2.0, 4.0]), np.array([0.0, 20e-6, 20e-6]),
                        np.full(3, 300.0), 0.0)
    assert np.isclose(_stick_duration(hold, 1.0, 3.0), 2.0)


def test_error_grows_smoothly_with_a_parameter_offset_across_velocity_steps():
    """Near the parameters that made the data, the error of a velocity-step campaign rises steadily
    with the offset of mu_k on either side. Before the stick duration was read as stage travel and
    the post-slip line against stage position, a slip moving across a step made it jump by tens
    (hidden-Stribeck campaign, mu_k 0.5 % off: 9.4, 0.5 % low: 32, 1 % low: 14.5)."""
    model = build_model("paper", params=BASE)
    runs = simulate_campaign(model, "velocity_steps", seed=31, velocity_m_s=1.6e-5,
                             duration_scale=0.5)
    ds = prepare_dataset(runs)
    choice = ModelChoice("paper").with_values(BASE)
    for sign in (-1.0, 1.0):
        errors = [evaluate(ds, choice.with_values({"mu_k": BASE["mu_k"] * (1 + sign * f)}))
                  .score.error for f in (0.004, 0.008, 0.016, 0.032)]
        assert all(b > a for a, b in zip(errors, errors[1:], strict=False)), (sign, errors)
