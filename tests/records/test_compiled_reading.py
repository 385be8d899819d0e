"""The compiled slip scan and window reads read every record as the Python reader did.

The reference is the reader as it was (tests/records/reference_events.py, frozen). On simulated
campaigns of three rigs at 500 Hz to 5 kHz, with and without sensor noise, over four protocols,
on the models' own noise-free outputs read with the measured records' settings (as a fit reads
them), on the real records of other labs and with probes over range: the same slips, sample for
sample, and the same features to rounding (1e-9 of the value, or of the signal the feature is a
difference of: a normal-force swing of 1e-14 N at 20 N is rounding in either reader).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.io.load import load_runs
from rigctl.model import Drive, ModelSpec, Simulator, build_model
from rigctl.model.noise import NoiseModel
from rigctl.records import sample_stats
from rigctl.records.drive_profile import DriveProfile, drive_profile
from rigctl.records.events import DetectionSettings, SlipIndices, detect_slips
from rigctl.records.features import EventTable, ReadSettings, extract_events
from rigctl.records.time_base import sliding_velocity
from rigctl.workbench.campaigns import simulate_campaign
from tests.records import reference_events as ref

REAL = Path(__file__).resolve().parents[1] / "data" / "real"
RTOL = 1e-9

LIGHT_RIG = dict(k0_N_per_m=2.0e4, kts_N_per_m=8e4, m_kg=0.05, mu_s=0.45, mu_k=0.36, mu_smax=0.5,
                 kt0_N_per_m=1.2e5, c0_N_s_per_m=2 * 0.01 * (2e4 * 0.05) ** 0.5, n_elements=20)
"""A light, lightly damped slider at 20 N (long ringing: ring chains, ring swings)."""
LIGHT_FN_N, LIGHT_V_M_S = 20.0, 4.4e-4


def _light_noise() -> NoiseModel:
    return NoiseModel(ft_rms_N=0.045, fn_rms_N=0.04, force_lsb_N=1e-3, probe_rms_m=4.4e-7,
                      probe_lsb_m=1.1e-7, stage_lsb_m=4.4e-8)


def _same_slips(a: SlipIndices, b: SlipIndices, tag: str) -> None:
    for name in ("i_peak", "i_end", "sign"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), (tag, name)


def _close(new: np.ndarray, old: np.ndarray, scale: float, tag: str) -> None:
    assert np.array_equal(np.isnan(new), np.isnan(old)), (tag, new, old)
    ok = np.isfinite(old)
    tol = RTOL * np.maximum(np.abs(old[ok]), scale)
    assert np.all(np.abs(new[ok] - old[ok]) <= tol), (tag, np.max(np.abs(new[ok] - old[ok])))


def _same_table(new: EventTable, old: EventTable, t: np.ndarray, ft: np.ndarray,
                delta: np.ndarray, fn: np.ndarray, drive: DriveProfile, tag: str) -> None:
    assert np.array_equal(new.i_peak, old.i_peak), tag
    assert np.array_equal(new.segment, old.segment), tag
    assert np.array_equal(new.stage, old.stage), tag
    span_t = float(t[-1] - t[0])
    f_scale = float(np.max(np.abs(ft)))
    d_scale = float(np.max(np.abs(delta))) + float(np.max(np.abs(drive.x_stage_m)))
    # what each feature is a difference of: its rounding is that of the signal
    scale = {"peak_N": f_scale, "trough_N": f_scale, "drop_N": f_scale, "ft_N": f_scale,
             "fn_swing_N": float(np.max(np.abs(fn))), "fn_N": float(np.max(np.abs(fn))),
             "slip_m": d_scale, "lag_m": d_scale, "cum_slip_m": d_scale,
             "x_drive_m": d_scale,
             "drop_delay_s": span_t, "t_s": span_t, "hold_s": span_t, "stick_time_s": span_t,
             "stick_s": span_t}
    _close(new.t_drop_s, old.t_drop_s, span_t, f"{tag} t_drop")
    _close(new.init_k_N_per_m, old.init_k_N_per_m, 0.0, f"{tag} init_k")
    for group in ("features", "covariates", "se"):
        for name, old_v in getattr(old, group).items():
            _close(getattr(new, group)[name], old_v, scale.get(name, 0.0), f"{tag} {name}")


def _check_record(t: np.ndarray, ft: np.ndarray, delta: np.ndarray, fn: np.ndarray,
                  drive: DriveProfile, read: ReadSettings, valid: np.ndarray | None,
                  tag: str) -> int:
    """Both readers on one record: slips, then the whole event table; returns the slip count."""
    t_rel = t - t[0]
    v = drive.sliding_velocity_at(t_rel)
    old = ref.detect_slips(t_rel, ft, delta, read.detection, valid, v_drive_m_s=v, fn_N=fn)
    new = detect_slips(t_rel, ft, delta, read.detection, valid, v_drive_m_s=v, fn_N=fn)
    _same_slips(new, old, tag)
    # without a drive, without delta (the detector's other branches)
    _same_slips(detect_slips(t_rel, ft, None, read.detection),
                ref.detect_slips(t_rel, ft, None, read.detection), f"{tag} (force only)")
    table_old = ref.extract_events(t, ft, delta, fn, drive, read, delta_valid=valid)
    table_new = extract_events(t, ft, delta, fn, drive, read, delta_valid=valid)
    _same_table(table_new, table_old, t, ft, delta, fn, drive, tag)
    return old.n


def _measured_and_model(runs: list[MeasuredRun], model: ModelSpec | None,
                        tag: str) -> Iterator[int]:
    """Each measured run read as measured, then the model on its drive read with its settings
    (as an evaluation reads the model)."""
    for run in runs:
        drive = drive_profile(run)
        det = DetectionSettings.from_signal(run.ft_N, delta_m=run.delta_m)
        read = ReadSettings(det)
        yield _check_record(run.t_s, run.ft_N, run.delta_m, run.fn_N, drive, read, None,
                            f"{tag} {run.source} measured")
        if model is None:
            continue
        res = Simulator(model, sample_rate_hz=run.sample_rate_hz).run(
            Drive(drive.t_s, drive.x_stage_m, drive.fn_N), record_elements=False)
        yield _check_record(res.t_s, res.ft_N, res.d1_m - res.d2_m, res.fn_N, drive, read, None,
                            f"{tag} {run.source} model")


CASES = [
    # rig, protocol, sample rate, noise, model read on its drive
    ("paper", "tlre", 500.0, True, "light"),
    ("paper", "velocity_steps", 1024.0, True, "paper"),
    ("paper", "slide_hold_slide", 2000.0, False, "classic"),
    ("light", "velocity_steps", 2000.0, True, "paper_light"),
    ("light", "slide_hold_slide", 5000.0, True, "light"),
    ("light", "tlre", 1024.0, False, "light"),
    ("classic", "force_sweep", 2000.0, True, "paper"),
    ("classic", "tlre", 5000.0, False, "classic"),
]


def _model(name: str) -> ModelSpec:
    if name == "light":
        return build_model("paper", params=LIGHT_RIG)
    if name == "paper_light":  # far from the light rig's data: the preset's slips on its drive
        return build_model("paper", params={**LIGHT_RIG, "mu_k": 0.40, "m_kg": 0.02})
    return build_model(name)


@pytest.mark.parametrize(("rig", "protocol", "rate_hz", "noisy", "reader"), CASES)
@pytest.mark.slow
def test_simulated_campaigns_read_the_same(rig: str, protocol: str, rate_hz: float, noisy: bool,
                                           reader: str) -> None:
    light = rig == "light"
    noise: bool | NoiseModel = (_light_noise() if light else True) if noisy else False
    runs = simulate_campaign(
        _model(rig), protocol, seed=3, noise=noise, sample_rate_hz=rate_hz,
        fn_N=LIGHT_FN_N if light else 300.0, velocity_m_s=LIGHT_V_M_S if light else 1e-5,
        duration_scale=0.3 if protocol != "tlre" else 0.5)[:2]
    counts = list(_measured_and_model(runs, _model(reader), f"{rig}/{protocol}/{rate_hz:g}"))
    assert sum(counts) > 0


@pytest.mark.slow
def test_the_real_records_read_the_same() -> None:
    runs = load_runs([REAL / "ens_k168_velocity_campaign", REAL / "tribometer_frictionmodels.csv"])
    counts = list(_measured_and_model(runs, None, "real"))
    assert all(c > 0 for c in counts), counts


def test_a_real_record_with_probes_over_range_reads_the_same() -> None:
    """delta invalid over a stretch: the delta confirmation and the delta features skip it."""
    run = load_runs([REAL / "ens_k168_velocity_campaign" / "k168_v42_60s.csv"])[0]
    valid = np.ones(run.n_samples, dtype=bool)
    valid[run.n_samples // 5 : run.n_samples // 3] = False
    valid[run.n_samples // 2 :: 97] = False
    drive = drive_profile(run)
    det = DetectionSettings.from_signal(run.ft_N, delta_m=run.delta_m, delta_valid=valid)
    n = _check_record(run.t_s, run.ft_N, run.delta_m, run.fn_N, drive, ReadSettings(det), valid,
                      "ens over range")
    assert n > 10


def test_a_force_record_with_a_gap_is_scanned_the_same() -> None:
    """NaN samples (a gap) propagate through the window's extreme as in numpy."""
    run = simulate_campaign(_model("light"), "tlre", seed=2, noise=_light_noise(),
                            sample_rate_hz=2000.0, fn_N=LIGHT_FN_N, velocity_m_s=LIGHT_V_M_S,
                            duration_scale=0.2)[0]
    ft = run.ft_N.copy()
    ft[ft.shape[0] // 3 : ft.shape[0] // 3 + 40] = np.nan
    det = DetectionSettings.from_signal(run.ft_N)
    t = run.t_s - run.t_s[0]
    old = ref.detect_slips(t, ft, run.delta_m, det)
    _same_slips(detect_slips(t, ft, run.delta_m, det), old, "gap")
    assert old.n > 3


def test_the_drive_velocity_by_phase_is_the_drives_own_per_sample() -> None:
    """The detector's drive velocity, repeated per phase, is DriveProfile.sliding_velocity_at:
    velocity steps and holds, a reciprocating tribometer's 200 strokes."""
    runs = simulate_campaign(build_model("paper"), "slide_hold_slide", seed=1,
                             duration_scale=0.3)
    runs += load_runs([REAL / "tribometer_frictionmodels.csv"])
    for run in runs:
        drive = drive_profile(run)
        t = run.t_s - run.t_s[0]
        assert np.array_equal(sliding_velocity(drive, t), drive.sliding_velocity_at(t))


@pytest.mark.parametrize("n", [1, 2, 7, 8, 9, 127, 128, 129, 130, 257, 1000, 4099, 30011])
def test_sample_stats_are_numpys_bit_for_bit(n: int) -> None:
    rng = np.random.default_rng(n)
    for a in (rng.normal(3e2, 2.0, n), np.round(rng.normal(0.0, 40.0, n)),
              np.cumsum(rng.normal(0.0, 1e-6, n))):
        b = rng.normal(1.0, 1.0, n)
        assert sample_stats.np_sum(a) == np.sum(a)
        assert sample_stats.np_mean(a) == np.mean(a)
        assert sample_stats.np_var(a) == np.var(a)
        assert sample_stats.np_median(a) == np.median(a)
        for q in (0.1, 0.5, 0.75):
            assert sample_stats.np_quantile(a, q) == np.quantile(a, q)
        assert abs(sample_stats.np_dot(a, b) - float(a @ b)) <= 1e-12 * float(np.abs(a) @ np.abs(b))
    with_nan = rng.normal(0.0, 1.0, n)
    with_nan[n // 2] = np.nan
    assert np.isnan(sample_stats.np_median(with_nan))
    assert np.isnan(sample_stats.np_quantile(with_nan, 0.1))
