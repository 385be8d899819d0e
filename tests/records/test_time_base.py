"""A record's time base (rigctl.records.time_base): made once per run for the model's readings, the
same reading bit for bit; one made for other times is not used."""

from __future__ import annotations

import numpy as np

from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.records.features import extract_events
from rigctl.records.time_base import TimeBase
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.evaluate import model_time_base, read_result, simulate_run


def _same(a, b) -> None:
    assert a.t_drop_s.tobytes() == b.t_drop_s.tobytes()
    for name, col in a.features.items():
        assert col.tobytes() == b.features[name].tobytes(), name
    assert a.init_k_N_per_m.tobytes() == b.init_k_N_per_m.tobytes()


def test_the_model_reading_of_a_run_reuses_its_time_base_and_reads_the_same() -> None:
    runs = simulate_campaign(build_model("paper"), "velocity_steps", seed=2, duration_scale=0.3)
    ds = prepare_dataset(runs)
    run = ds.runs[0]
    res = simulate_run(build_model("paper"), run)
    base = model_time_base(run, res.t_s)
    assert model_time_base(run, res.t_s) is base  # made once
    fresh = extract_events(res.t_s, res.ft_N, res.d1_m - res.d2_m, res.fn_N, run.drive, run.read)
    _same(read_result(res, run), fresh)
    assert base.dt_s == float(np.median(np.diff(res.t_s - res.t_s[0])))


def test_a_time_base_of_other_times_is_not_used() -> None:
    runs = simulate_campaign(build_model("paper"), "velocity_steps", seed=2, duration_scale=0.3)
    run = prepare_dataset(runs).runs[0]
    res = simulate_run(build_model("paper"), run)
    other = TimeBase.of(res.t_s[:-1], run.drive)
    assert not other.fits(res.t_s, run.drive)
    shifted = TimeBase.of(res.t_s * 1.001, run.drive)
    assert not shifted.fits(res.t_s, run.drive)
    read = extract_events(res.t_s, res.ft_N, res.d1_m - res.d2_m, res.fn_N, run.drive, run.read,
                          time_base=shifted)
    _same(read, extract_events(res.t_s, res.ft_N, res.d1_m - res.d2_m, res.fn_N, run.drive,
                               run.read))
