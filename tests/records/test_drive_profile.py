"""The measured drive becomes a few exact segments: constant, holds, steps; no motion is refused."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.data import DataError, MeasuredRun
from rigctl.records.drive_profile import drive_profile


def _run(x, fn, fs=1024.0, source="drive.csv"):
    t = np.arange(x.size) / fs
    z = np.zeros_like(t)
    return MeasuredRun(t, x, fn, z, z, z, source=source)


def _quantise(x, lsb=0.32e-6):
    return np.round(x / lsb) * lsb


def test_slide_hold_slide_gives_exact_holds_and_the_velocity():
    fs = 1024.0
    t = np.arange(int(40 * fs)) / fs
    v = np.where((t > 15) & (t < 25), 0.0, 1e-5)
    x = _quantise(np.concatenate([[0.0], np.cumsum(v[:-1]) / fs]))
    rng = np.random.default_rng(0)
    prof = drive_profile(_run(x, 300.0 + rng.normal(0, 0.2, t.size)))
    assert prof.n_segments() == 3
    assert prof.is_hold.tolist() == [False, True, False]
    assert prof.velocity_m_per_s[1] == 0.0  # a hold is exactly a hold
    assert np.allclose(prof.moving_velocities, 1e-5, rtol=2e-3)
    assert np.allclose(prof.t_s[1:3], [15.0, 25.0], atol=0.1)
    assert np.ptp(prof.fn_N) == 0.0  # a constant load stays exactly constant
    assert prof.fn_N[0] == pytest.approx(300.0, abs=0.01)
    assert prof.hold_time_between(10.0, 30.0) == pytest.approx(10.0, abs=0.1)


def test_velocity_steps_and_a_load_step_are_kept():
    fs = 1024.0
    t = np.arange(int(30 * fs)) / fs
    v = np.where(t < 10, 1e-5, np.where(t < 20, 5e-5, 2e-6))
    x = _quantise(np.concatenate([[0.0], np.cumsum(v[:-1]) / fs]))
    fn = np.where(t < 15, 250.0, 350.0)
    prof = drive_profile(_run(x, fn))
    assert np.allclose(sorted(set(np.round(prof.moving_velocities, 7))), [2e-6, 1e-5, 5e-5],
                       rtol=0.02)
    assert prof.fn_at(np.array([5.0]))[0] == pytest.approx(250.0, abs=1.0)
    assert prof.fn_at(np.array([25.0]))[0] == pytest.approx(350.0, abs=1.0)


def test_a_stage_that_never_moves_is_a_data_error_naming_the_file():
    x = _quantise(np.random.default_rng(1).normal(0, 1e-8, 5000))
    with pytest.raises(DataError, match=r"still\.csv.*does not move"):
        drive_profile(_run(x, np.full(5000, 300.0), source="still.csv"))


def test_corner_times_are_refined_off_the_samples_and_a_slow_step_is_no_hold():
    fs = 1024.0
    t = np.arange(int(40 * fs)) / fs
    # two decades: 2, 200, 20 um/s; corners between samples
    v = np.where(t < 14.9973, 2e-6, np.where(t < 16.0031, 2e-4, 2e-5))
    x_true = np.concatenate([[0.0], np.cumsum(v[:-1]) / fs])
    x = _quantise(x_true + np.random.default_rng(3).normal(0, 6e-8, t.size), lsb=0.02e-6)
    prof = drive_profile(_run(x, np.full(t.size, 300.0)))
    assert not prof.is_hold.any()  # 1 % of the fastest velocity is still a slide
    assert np.allclose(prof.velocity_at(np.array([5.0, 15.5, 30.0])), [2e-6, 2e-4, 2e-5],
                       rtol=0.01)
    # the corners are placed between samples: the drive stays within the noise of the stage
    assert np.max(np.abs(np.interp(t, prof.t_s, prof.x_stage_m) - x_true)) < 1.2e-7


def test_a_released_load_is_zero_in_the_drive_so_the_next_contact_starts_anew():
    """A release reads as noise and offset around 0 N; the line fit of Fn may leave newtons there.
    The drive must say 0 (specimens apart) for the engine to start a new initial stage."""
    fs = 1024.0
    t = np.arange(int(60 * fs)) / fs
    fn = np.where((t > 20) & (t < 35), 0.0, 300.0)
    fn = np.where((t > 19.8) & (t <= 20), 300.0 * (20 - t) / 0.2, fn)  # a 0.2 s unloading ramp
    rng = np.random.default_rng(3)
    fn_meas = fn + 0.3 + rng.normal(0, 0.2, t.size)  # offset and noise, as a tared sensor reads
    x = _quantise(1e-5 * t)
    prof = drive_profile(_run(x, fn_meas))
    gap = (t > 20.5) & (t < 34.5)
    assert np.all(prof.fn_at(t[gap]) == 0.0)
    loaded = (t > 40)
    assert np.allclose(prof.fn_at(t[loaded]), 300.3, atol=1.0)
