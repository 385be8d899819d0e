"""Protocol phases of a drive: what the protocol did, not every wiggle of the recorded stage."""

from __future__ import annotations

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.records.drive_profile import DriveProfile, drive_profile


def _profile(t_knots, v_knots, fn=300.0, jitter_m=0.0, seed=3):
    t = np.asarray(t_knots, dtype=float)
    x = np.concatenate([[0.0], np.cumsum(np.asarray(v_knots) * np.diff(t))])
    x = x + np.random.default_rng(seed).uniform(-jitter_m, jitter_m, t.size)
    return DriveProfile(t, x, np.full(t.size, fn), 0.0)


def test_a_jittery_slide_is_one_phase_and_a_velocity_step_starts_one():
    # 1.3 um/s for 200 s, knots every 0.5 s off the line by up to 0.4 um (polled positions: their
    # pieces' speeds scatter by +-120 %)
    t = np.arange(0.0, 200.01, 0.5)
    v = np.full(t.size - 1, 1.3e-6)
    assert _profile(t, v, jitter_m=0.4e-6).n_segments() == 1
    # the same with a step to 4 um/s at 100 s
    prof = _profile(t, np.where(t[:-1] < 100.0, 1.3e-6, 4e-6), jitter_m=0.4e-6)
    assert prof.n_segments() == 2
    assert abs(prof.last_change_before(150.0) - 100.0) < 1.0
    assert np.allclose(prof.moving_velocities, [1.3e-6, 4e-6], rtol=0.05)


def test_holds_are_phases_but_a_stall_of_the_stage_inside_a_slide_is_not():
    # slide 20 s, hold 3 s, slide 20 s, stall 0.2 s, slide 20 s
    t = [0.0, 20.0, 23.0, 43.0, 43.2, 63.0]
    v = [2e-5, 0.0, 2e-5, 0.0, 2e-5]
    prof = _profile(t, v)
    assert prof.n_segments() == 3
    assert prof.phase_is_hold.tolist() == [False, True, False]


def test_a_load_change_starts_a_phase():
    t = np.array([0.0, 10.0, 20.0, 30.0])
    x = np.array([0.0, 1e-4, 2e-4, 3e-4])
    fn = np.array([300.0, 300.0, 250.0, 250.0])
    assert DriveProfile(t, x, fn, 0.0).n_segments() == 3


def test_a_fast_repositioning_stroke_does_not_turn_the_slow_slide_into_holds():
    """The TLRE returns the stage at 1.4 mm/s between its 1.3 um/s slides: judged against the fastest
    segment (0.2 % of 1.4 mm/s = 2.9 um/s), the slide would become a staircase of 'holds' up to
    10 um off the measured stage and the model would slip at the wrong times."""
    fs = 1024.0
    t = np.arange(int(200 * fs)) / fs
    v = np.where(t < 150.0, 1.3e-6, np.where(t < 150.2, -1.4e-3, 0.0))
    x = np.concatenate([[0.0], np.cumsum(v[:-1]) / fs])
    x = x + np.random.default_rng(1).normal(0, 2e-9, t.size)
    run = MeasuredRun(t, x, np.full(t.size, 300.0), np.zeros_like(t), np.zeros_like(t),
                      np.zeros_like(t), source="tlre.csv")
    prof = drive_profile(run)
    slide = t < 149.0
    assert np.max(np.abs(prof.x_at(t[slide]) - x[slide])) < 0.05e-6
    assert not prof.phase_is_hold[0]
    assert np.isclose(prof.velocity_at(np.array([50.0]))[0], 1.3e-6, rtol=0.01)
