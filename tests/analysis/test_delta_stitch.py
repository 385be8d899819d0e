"""Delta stitched across the probes' re-centrings: continuous where a mount moved, from the recorded
move or, where the event states none, from the jump measured at rest."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.analysis.delta_stitch import stitch_run
from rigctl.data import MeasuredRun
from rigctl.storage.probe_events import RECENTRE_EVENT, recentre_message
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
