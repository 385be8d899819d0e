"""Two repetitions in one record, the load released in between under tangential load (as the TLRE
protocol does): the model must restart its initial stage, and the slips set off by the release are
paired but not compared."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.model import Simulator, build_model
from rigctl.model.drive import Drive
from rigctl.records.dataset import prepare_dataset
from rigctl.workbench.compare import compare
from rigctl.workbench.model_choice import ModelChoice


def _two_repetitions() -> MeasuredRun:
    fs = 1024.0
    t = np.arange(int(70 * fs)) / fs
    v = 2e-5
    # slide 0-30 s, release at 30 s (0.2 s ramp), stage back at 33-36 s, reload at 38 s, slide 40-70 s
    x = np.where(t < 30, v * t, v * 30)
    x = np.where((t >= 33) & (t < 36), v * 30 * (1 - (t - 33) / 3), x)
    x = np.where(t >= 36, 0.0, x)
    x = np.where(t >= 40, v * (t - 40), x)
    fn = np.full(t.size, 300.0)
    fn = np.where((t >= 30) & (t < 30.2), 300.0 * (30.2 - t) / 0.2, fn)
    fn = np.where((t >= 30.2) & (t < 38), 0.0, fn)
    fn = np.where((t >= 38) & (t < 38.5), 300.0 * (t - 38) / 0.5, fn)
    model = build_model("paper")
    res = Simulator(model).run(Drive.from_samples(t, x, fn))
    rng = np.random.default_rng(11)
    ft = res.ft_N + rng.normal(0, 0.05, t.size)
    fn_meas = fn + 0.2 + rng.normal(0, 0.2, t.size)  # a released load reads noise and offset
    d1 = res.delta_m + rng.normal(0, 0.01e-6, t.size)
    return MeasuredRun(t, x, fn_meas, ft, d1, np.zeros_like(t), source="two_reps.csv")


def test_a_release_restarts_the_initial_stage_and_release_slips_are_not_compared():
    run = _two_repetitions()
    ds = prepare_dataset([run])
    ev = ds.runs[0].events
    t_drop = ev.t_drop_s
    assert np.any(t_drop > 40)  # slips in both repetitions
    near_release = np.abs(t_drop - 30.1) < 0.3
    if near_release.any():  # a slip set off by the release: paired, not compared
        assert np.all(np.isnan(ev.features["peak_N"][near_release]))
    cmp = compare([run], ModelChoice("paper"), identify=False)
    # the second repetition starts from rest: the model's first slip after the reload is an
    # initial-stage peak (mu_s,max Fn = 60 N), as measured; without the release it would be ~45 N
    assert cmp.fit.error < 2.0, cmp.fit.error
    second = t_drop > 40
    assert np.nanmax(ev.features["peak_N"][second]) == pytest.approx(60.0, abs=1.5)
