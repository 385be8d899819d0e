"""Delta stitched across the probes' re-centrings: continuous where a mount moved, from the recorded
move or, where the event states none, from the jump measured at rest."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.records.delta_stitch import (
    STITCHED_KEY,
    record_file,
    stitch_record,
    stitch_run,
    unsteady_windows,
)
from rigctl.storage.probe_events import RECENTRE_EVENT, moving_masks, recentre_message
from rigctl.storage.reader import RunEvent

RATE = 1024.0


def _run() -> tuple[MeasuredRun, np.ndarray]:
    t = np.arange(int(10 * RATE)) / RATE
    true_d1 = np.where(t < 4.0, 5e-6 * t, 20e-6)  # slides, then rests from 4 s
    true_d1 = np.where(t > 6.0, 20e-6 + 5e-6 * (t - 6.0), true_d1)
    mount = np.where(t > 5.0, 30e-6, 0.0)  # the mount moved at 5 s, the boss at rest
    rng = np.random.default_rng(1)
    d1 = true_d1 - mount + rng.normal(0.0, 0.005e-6, t.shape)
    run = MeasuredRun(t, 1.3e-6 * t, np.full_like(t, 300.0), np.zeros_like(t), d1,
                      np.zeros_like(t), source="synthetic.h5")
    return run, true_d1


@pytest.mark.parametrize("stated", [30e-6, math.nan])
def test_delta_is_continuous_across_a_recentring(stated: float) -> None:
    run, true_d1 = _run()
    event = RunEvent(5.2, RECENTRE_EVENT, recentre_message("d1_m", stated, 20e-6, -10e-6))
    out = stitch_run(run, [RunEvent(1.0, "step 3", "slide"), event])
    assert np.max(np.abs(out.delta_m - true_d1)) < 0.1e-6
    assert np.max(np.abs(np.diff(out.delta_m))) < 0.1e-6  # no jump left
    assert out.d2_m is run.d2_m or np.array_equal(out.d2_m, run.d2_m)


def test_no_recentring_leaves_the_run_alone() -> None:
    run, _ = _run()
    assert stitch_run(run, [RunEvent(1.0, "probe_over_range", "d1_m: probe over range")]) is run


def test_a_move_mid_slide_uses_the_recorded_move_not_the_jump() -> None:
    """The boss slips by 20 um while the mount moves 30 um over 60 ms: the stated move is added
    after the window, the window's samples are marked, and nothing is measured from the jump."""
    t = np.arange(int(10 * RATE)) / RATE
    true_d1 = 1e-6 * t + np.where(t > 5.02, 20e-6, 0.0)  # slides, slips 20 um at 5.02 s
    mount = 30e-6 * np.clip((t - 5.0) / 0.03, 0.0, 1.0)  # the mount moves from 5.0 s to 5.03 s
    run = MeasuredRun(t, 1.3e-6 * t, np.full_like(t, 300.0), np.zeros_like(t), true_d1 - mount,
                      np.zeros_like(t), source="synthetic.h5")
    event = RunEvent(5.2, RECENTRE_EVENT,
                     recentre_message("d1_m", 30e-6, 5e-6, -5e-6, t_start_s=4.99, duration_s=0.06))
    out = stitch_run(run, [event])
    window = moving_masks(t, [event])["d1_m"]
    assert np.array_equal(unsteady_windows(run, [event])["d1_m"], window)  # a slip: not read
    assert np.array_equal(unsteady_windows(out, [event])["d1_m"], window)
    assert window.sum() == pytest.approx(0.06 * RATE, abs=1)
    np.testing.assert_allclose(out.d1_m[~window], true_d1[~window], atol=1e-12)
    assert np.all(np.abs(np.diff(out.d1_m[window])) < 21e-6 / window.sum() + 1e-9)  # bridged


def test_a_move_in_a_steady_stick_is_bridged_and_read() -> None:
    """The boss creeps at 1 um/s while the mount moves: the bridge is what it did, no sample of
    the window is left out."""
    t = np.arange(int(10 * RATE)) / RATE
    true_d1 = 1e-6 * t
    mount = 30e-6 * np.clip((t - 5.0) / 0.03, 0.0, 1.0)
    run = MeasuredRun(t, 1.3e-6 * t, np.full_like(t, 300.0), np.zeros_like(t), true_d1 - mount,
                      np.zeros_like(t), source="synthetic.h5")
    event = RunEvent(5.2, RECENTRE_EVENT,
                     recentre_message("d1_m", 30e-6, 5e-6, -25e-6, t_start_s=4.99, duration_s=0.06))
    assert unsteady_windows(run, [event]) == {}
    np.testing.assert_allclose(stitch_run(run, [event]).d1_m, true_d1, atol=1e-12)


def test_stitching_twice_adds_nothing() -> None:
    run, _true_d1 = _run()
    event = RunEvent(5.2, RECENTRE_EVENT, recentre_message("d1_m", 30e-6, 20e-6, -10e-6))
    once = stitch_run(run, [event])
    assert once.metadata[STITCHED_KEY] == "d1_m: 1 mount move(s) added back"
    assert STITCHED_KEY not in run.metadata  # the run read is left as it was
    assert stitch_run(once, [event]) is once
    assert stitch_record(once) is once


def test_a_window_of_a_long_record_reads_its_record_file(tmp_path) -> None:
    path = tmp_path / "long.h5"
    path.write_bytes(b"")
    run, _ = _run()
    assert record_file(MeasuredRun(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, run.d1_m,
                                   run.d2_m, source=f"{path}#w3")) == path
    assert record_file(run) is None  # no such file
    assert record_file(MeasuredRun(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, run.d1_m,
                                   run.d2_m, source=str(tmp_path / "x.csv"))) is None


def test_a_move_as_the_slip_dies_out_is_bridged_and_read() -> None:
    """The move starts 80 ms after a 14 um slip whose relaxation (20 ms) is still under way (the
    line before the move, carried over it, would miss by 1 um); the specimen moves 0.25 um across
    the window: the level is met and the window read."""
    t = np.arange(int(10 * RATE)) / RATE
    true_d1 = 14e-6 * np.clip(1.0 - np.exp(-(t - 5.0) / 0.02), 0.0, None)
    mount = 30e-6 * np.clip((t - 5.08) / 0.03, 0.0, 1.0)
    run = MeasuredRun(t, 1.3e-6 * t, np.full_like(t, 300.0), np.zeros_like(t), true_d1 - mount,
                      np.zeros_like(t), source="synthetic.h5")
    event = RunEvent(5.3, RECENTRE_EVENT,
                     recentre_message("d1_m", 30e-6, 14e-6, -16e-6, t_start_s=5.075, duration_s=0.08))
    assert unsteady_windows(run, [event]) == {}
    out = stitch_run(run, [event])
    assert np.max(np.abs(out.d1_m - true_d1)) < 0.3e-6
