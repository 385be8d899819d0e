"""Residual maps and their wording, from comparisons built by hand."""

from __future__ import annotations

import numpy as np

from rigctl.records.dataset import Dataset, PreparedRun, _blocks
from rigctl.records.drive_profile import DriveProfile
from rigctl.records.events import DetectionSettings
from rigctl.records.features import COVARIATES, EVENT_FEATURES, INIT_BANDS, EventTable, ReadSettings
from rigctl.workbench.metrics import RunComparison
from rigctl.workbench.residual_map import discrepancies, residual_map


def _case(peak_residual, hold_s, extra_cov=None):
    n = len(hold_s)
    rng = np.random.default_rng(0)
    feats = {name: np.ones(n) for name in EVENT_FEATURES}
    cov = {name: rng.uniform(1, 2, n) for name in COVARIATES}
    cov["hold_s"] = np.asarray(hold_s, float)
    cov["stick_time_s"] = 30.0 + np.asarray(hold_s, float)  # a 30 s loading ramp plus the hold
    cov["t_s"] = np.arange(n, dtype=np.float64) * 4.0 + 2.0
    if extra_cov:
        cov.update(extra_cov)
    ev = EventTable(cov["t_s"], np.zeros(n, int), np.ones(n, np.int8), feats, cov,
                    np.full(len(INIT_BANDS), np.nan))
    drive = DriveProfile(np.array([0.0, 400.0]), np.array([0.0, 4e-3]), np.array([300.0, 300.0]), 0)
    run = PreparedRun("r", 1024.0, 400 * 1024, drive, ReadSettings(DetectionSettings(0.5)), ev,
                      _blocks(ev))
    sigma = {name: 0.1 for name in EVENT_FEATURES}
    ds = Dataset((run,), sigma, {k: 1.0 for k in sigma})
    residual = {name: rng.normal(0, 0.1, n) for name in EVENT_FEATURES}
    residual["peak_N"] = np.asarray(peak_residual, float) + rng.normal(0, 0.1, n)
    missing = {name: np.zeros(n, bool) for name in EVENT_FEATURES}
    comp = RunComparison(np.arange(n), residual, missing, np.full(len(INIT_BANDS), np.nan),
                         np.zeros(1, int))
    return ds, [comp]


def test_peaks_after_long_holds_are_named_with_log_hold_time():
    hold = np.tile([0.0, 1.0, 3.0, 10.0, 30.0, 100.0], 5)
    resid = -0.8 * np.log1p(hold)  # the model falls short more and more after long holds
    ds, comps = _case(resid, hold)
    rmap = residual_map(ds, comps)
    text = discrepancies(rmap)
    assert text, "a strong structure must be reported"
    first = text[0]
    assert first.startswith("peaks")
    assert "under-predicted" in first
    assert "hold" in first and "log" in first


def test_a_constant_offset_is_reported_as_throughout():
    hold = np.zeros(30)
    ds, comps = _case(np.full(30, 0.5), hold)
    text = discrepancies(residual_map(ds, comps))
    assert any(t.startswith("peaks are over-predicted by 0.5 N throughout") for t in text)


def test_nothing_is_reported_for_residuals_within_the_scatter():
    ds, comps = _case(np.zeros(30), np.zeros(30))
    rmap = residual_map(ds, comps)
    assert discrepancies(rmap) == []
    assert rmap.by_phase["stick"] < 2.0 and rmap.by_phase["slip"] < 2.0


def test_a_ratio_many_times_off_is_said_as_a_factor():
    from rigctl.workbench.residual_map import _amount
    assert _amount("k_stick_N_per_m", np.full(5, np.log(364.0))) == "a factor of 364"
    assert _amount("k_stick_N_per_m", np.full(5, -np.log(10.0))) == "a factor of 10"
    assert _amount("k_stick_N_per_m", np.full(5, np.log(1.5))) == "50 %"
    assert _amount("k_stick_N_per_m", np.full(5, np.log(0.6))) == "40 %"


def test_a_delay_is_said_in_milliseconds():
    from rigctl.workbench.residual_map import _amount
    assert _amount("drop_delay_s", np.full(5, -1.3e-3)) == "1.3 ms"
    assert _amount("slip_m", np.full(5, 2.0e-5)) == "20 um"


def test_a_feature_matched_exactly_has_no_bias(recwarn):
    """Residuals all exactly 0 (a feature the model reproduces to the bit, or one only a constant
    fills) have no scatter to judge a bias by: none is reported, and no NaN is made."""
    ds, comps = _case(np.zeros(30), np.zeros(30))
    comps[0].residual["drop_N"] = np.zeros(30)
    comps[0].residual["slip_m"] = np.full(30, 0.3)
    rmap = residual_map(ds, comps)
    assert rmap.bias["drop_N"] == (0.0, 0.0)
    assert rmap.bias["slip_m"][1] == np.inf
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)]
