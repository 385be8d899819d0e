"""Slip detection and per-event features on hand-made records with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.records.drive_profile import drive_profile
from rigctl.records.events import DetectionSettings, detect_slips
from rigctl.records.features import ReadSettings, extract_events
from tests.workbench.synth import sawtooth_run


def _read(run):
    det = DetectionSettings.from_signal(run.ft_N)
    prof = drive_profile(run)
    return extract_events(run.t_s, run.ft_N, run.delta_m, run.fn_N, prof, ReadSettings(det, 0.12))


def test_every_slip_is_found_once_despite_ringing_and_noise():
    run, true = sawtooth_run(ring_N=6.0, noise_N=0.08)
    det = DetectionSettings.from_signal(run.ft_N)
    slips = detect_slips(run.t_s, run.ft_N, run.delta_m, det)
    assert slips.n == true.size
    t_peak = run.t_s[slips.i_peak]
    assert np.max(np.abs(t_peak - true)) < 3.0 / 1024


@pytest.mark.parametrize("ring_N", [3.0, 5.0])
def test_a_long_slow_ringing_is_one_slip_not_many(ring_N):
    """A lightly damped slider rings at 30 Hz for seconds after each slip: its swings are slower
    than the merge gap, and some pass the threshold on their own. They belong to the slip."""
    run, true = sawtooth_run(ring_N=ring_N, ring_hz=30.0, ring_tau_s=0.5)
    det = DetectionSettings.from_signal(run.ft_N)
    slips = detect_slips(run.t_s, run.ft_N, run.delta_m, det)
    assert slips.n == true.size
    assert np.max(np.abs(run.t_s[slips.i_peak] - true)) < 3.0 / 1024


def test_slips_inside_a_ringing_are_still_found():
    """Sticks of 1 s while the previous slip still rings above the threshold (tau 0.5 s), and
    slips of half the size: each is a slip, not a ring swing."""
    for peak_N, rate in ((45.0, 20.0), (35.0, 10.0)):
        run, true = sawtooth_run(peak_N=peak_N, rate_N_per_s=rate, ring_N=3.0, ring_hz=30.0,
                                 ring_tau_s=0.5, duration_s=12.0)
        det = DetectionSettings.from_signal(run.ft_N)
        slips = detect_slips(run.t_s, run.ft_N, run.delta_m, det)
        assert slips.n == true.size
        # a ring swing on top of the ramp may carry the peak up to a ring period early
        assert np.max(np.abs(run.t_s[slips.i_peak] - true)) < 1.0 / 30.0


def test_drop_times_peaks_and_settled_troughs_match_the_construction():
    run, true = sawtooth_run(ring_N=5.0)
    ev = _read(run)
    assert ev.n == true.size
    assert np.max(np.abs(ev.t_drop_s - true)) < 2.0 / 1024
    stable = ev.stage == 1
    # the record ends before the stick after the last slip: its settled level is not read
    assert np.isnan(ev.features["trough_N"][-1])
    stable[-1] = False
    # the settled post-slip level, not the ringing minimum (25 - 5 N)
    assert np.allclose(ev.features["trough_N"][stable], 25.0, atol=0.1)
    assert np.allclose(ev.features["peak_N"][stable], 45.0, atol=0.1)
    assert np.allclose(ev.features["drop_N"][stable], 20.0, atol=0.15)


def test_stick_features_rates_and_stiffness():
    run, _ = sawtooth_run(rate_N_per_s=4.0, k_N_per_m=8e5, ring_N=1.0)
    ev = _read(run)
    stable = ev.stage == 1
    assert np.allclose(ev.features["stick_s"][stable][1:], 20.0 / 4.0, rtol=0.01)
    assert np.allclose(ev.features["rate_N_per_s"][stable], 4.0, rtol=0.01)
    assert np.allclose(ev.features["k_stick_N_per_m"][stable], 8e5, rtol=0.02)
    assert np.allclose(ev.features["rounding"][stable], 1.0, atol=0.05)
    # delta jumps by the slip less the elastic unloading of the interface
    assert np.allclose(ev.features["slip_m"][stable], (1.5 - 1.0) * 20.0 / 8e5, rtol=0.02)


def test_first_event_of_a_run_loaded_from_rest_is_the_initial_stage():
    run, _ = sawtooth_run(t_load_start_s=2.0)
    ev = _read(run)
    assert ev.stage[0] == 0 and np.all(ev.stage[1:] == 1)
    # a straight initial loading: the same stiffness in every band
    k = ev.init_k_N_per_m
    assert np.all(np.isfinite(k))
    assert np.ptp(k) / np.mean(k) < 0.05


def test_ringing_feature_sees_the_ring_amplitude():
    quiet = _read(sawtooth_run(ring_N=0.0)[0]).features["ring_N"]
    some = _read(sawtooth_run(ring_N=2.0)[0]).features["ring_N"]
    loud = _read(sawtooth_run(ring_N=5.0)[0]).features["ring_N"]
    assert np.nanmedian(quiet) < 0.05  # the white noise is taken out
    assert np.nanmedian(loud) / np.nanmedian(some) == pytest.approx(2.5, rel=0.1)


def test_reversed_loading_is_read_like_forward_loading():
    fwd = _read(sawtooth_run(sign=1.0)[0])
    rev = _read(sawtooth_run(sign=-1.0)[0])
    assert rev.n == fwd.n
    assert np.allclose(rev.features["drop_N"][1:], fwd.features["drop_N"][1:], atol=0.1,
                       equal_nan=True)


@pytest.mark.parametrize("seed", [1, 2])
def test_pure_noise_and_ramps_give_no_slips(seed):
    run, _ = sawtooth_run(peak_N=1e9, duration_s=20.0, seed=seed)  # never slips
    det = DetectionSettings.from_signal(run.ft_N)
    assert detect_slips(run.t_s, run.ft_N, run.delta_m, det).n == 0


def test_a_small_drop_without_a_delta_jump_is_not_a_slip():
    run, _ = sawtooth_run(peak_N=1e9, duration_s=10.0, noise_N=0.01)
    ft = run.ft_N.copy()
    ft[5000:] -= 0.5  # an unloading step: Ft falls, the interface relaxes elastically
    d_unload = run.delta_m.copy()
    d_unload[5000:] -= 0.5 / 1e6
    det = DetectionSettings(threshold_N=0.3)
    assert detect_slips(run.t_s, ft, d_unload, det).n == 0
    d = run.delta_m.copy()
    d[5000:] += 2e-6  # the same drop with the interface jumping forward is a slip
    assert detect_slips(run.t_s, ft, d, det).n == 1


def _reciprocating(rate_hz: float = 200.0, with_slips: bool = False) -> tuple[np.ndarray, ...]:
    """A stroke back and forth with elastic loading to a plateau and fast unloading at each reversal
    (as on a reciprocating tribometer): Ft falls through zero within a few samples as the stage
    turns back, a drop far beyond the threshold that is no slip. With ``with_slips``, forward
    strokes carry stick-slip drops of 0.4 N."""
    t = np.arange(0.0, 20.0, 1.0 / rate_hz)
    v = np.where((t // 2.0) % 2 == 0, 1e-4, -1e-4)  # 2 s strokes at 0.1 mm/s
    ft = np.empty_like(t)
    f, k, level = 0.0, 2e5, 2.0  # 200 N/mm: the reversal unloads 4 N in 20 um of travel (0.2 s)
    for i in range(t.size):
        f = float(np.clip(f + k * v[i] / rate_hz, -level, level))
        if with_slips and v[i] > 0 and f >= level - 1e-9 and (i % int(0.5 * rate_hz)) == 0:
            f -= 0.4
        ft[i] = f
    rng = np.random.default_rng(3)
    return t, ft + 0.003 * rng.standard_normal(t.size), v


@pytest.mark.parametrize("rate_hz", [200.0, 2000.0])
def test_a_stroke_reversal_is_an_unloading_not_a_slip(rate_hz):
    t, ft, v = _reciprocating(rate_hz)
    det = DetectionSettings(threshold_N=0.1)
    assert detect_slips(t, ft, None, det).n > 0  # without the drive each reversal reads as a slip
    assert detect_slips(t, ft, None, det, v_drive_m_s=v).n == 0


def test_slips_of_a_reciprocating_record_are_still_found():
    t, ft, v = _reciprocating(2000.0, with_slips=True)
    det = DetectionSettings(threshold_N=0.1)
    slips = detect_slips(t, ft, None, det, v_drive_m_s=v)
    assert slips.n >= 8
    assert np.all(v[slips.i_peak] > 0) and np.all(slips.sign > 0)


def test_a_slow_slip_that_starts_at_a_noise_spike_is_a_slip_not_a_ring_swing():
    """A spike-prone record (as the ENS spring-slider's): a slow slip (half-cosine fall of 10 mN
    over 60 ms, each 6 ms of it below the threshold) begins at an upward one-sample spike, so the
    detector's cluster is the spike and the start of the fall, small against the 20 mN slip
    before it and rising and falling like a swing. The force stays down after it: a slip."""
    fs = 2000.0
    t = np.arange(int(4.0 * fs)) / fs
    rng = np.random.default_rng(5)

    def fall(t0: float, dur: float) -> np.ndarray:
        x = np.clip((t - t0) / dur, 0.0, 1.0)
        return 0.5 * (1.0 - np.cos(np.pi * x))

    # stick from 0.08 N rising 10 mN/s; a 20 mN slip at 1 s (30 ms); a 10 mN slow slip at 3 s
    ft = 0.08 + 0.01 * t - 0.02 * fall(1.0, 0.03) - 0.01 * fall(3.0, 0.06)
    ft = ft + 0.0002 * rng.standard_normal(t.size)
    ft[int(3.0 * fs)] += 0.004
    det = DetectionSettings(threshold_N=0.0026)
    slips = detect_slips(t, ft, np.zeros_like(t), det)
    assert slips.n == 2
    assert abs(t[slips.i_peak[1]] - 3.0) < 0.005


def test_a_model_record_is_confirmed_against_the_measured_probe_noise():
    """Same eyes for delta: a small drop whose noise-free delta jump would confirm it on its own
    is not confirmed where the measured record's delta noise makes such a jump unreadable."""
    run, _ = sawtooth_run(peak_N=1e9, duration_s=10.0, noise_N=0.01)
    ft = run.ft_N.copy()
    ft[5000:] -= 0.5
    d = np.linspace(0.0, 1e-4, ft.size)  # a noise-free model's delta: stick creep ...
    d[5000:] += 2e-6  # ... and the slip's 2 um jump
    noisy = d + 1e-6 * np.random.default_rng(1).standard_normal(d.size)
    measured = DetectionSettings.from_signal(ft, delta_m=noisy)
    assert measured.delta_sigma_m == pytest.approx(1e-6, rel=0.1)
    settings = DetectionSettings(threshold_N=0.3, delta_sigma_m=measured.delta_sigma_m)
    assert detect_slips(run.t_s, ft, d, settings).n == 0  # 2 um < 3 x 1 um
    assert detect_slips(run.t_s, ft, d, DetectionSettings(threshold_N=0.3)).n == 1


def test_a_lone_dip_whose_force_rises_past_its_drop_window_is_no_slip():
    """A single drop candidate whose highest sample comes after its drop window (a gentle dip of
    more than the threshold on a rising ramp, each step under the 'clear fall'): the force rises on,
    there is no slip to read (this once raised on an empty slice)."""
    dt, w = 1e-3, 4
    ft = 40.0 + 0.3 * (np.arange(300) - 100.0)
    ft[100:106] = [40.0, 39.6, 39.2, 38.8, 38.9, 40.5]
    ft[106:] = 40.5 + 0.3 * np.arange(1, 195)
    det = DetectionSettings(threshold_N=1.0, drop_window_s=w * dt)
    slips = detect_slips(np.arange(300) * dt, ft, None, det)
    assert slips.n == 0
