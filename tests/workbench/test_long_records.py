"""Long records are compared on windows spread over them (rigctl.records.long_records)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.records.dataset import prepare_dataset
from rigctl.records.long_records import window_long_runs
from rigctl.workbench.compare import compare
from rigctl.workbench.model_choice import ModelChoice
from tests.workbench.synth import ANOTHER_RIG as R
from tests.workbench.synth import another_rig_record as _record

K0, KTS, MU_S, MU_K = R["k0_N_per_m"], R["kts_N_per_m"], R["mu_s"], R["mu_k"]


@pytest.fixture(scope="module")
def long_run():  # type: ignore[no-untyped-def]
    return _record(1200.0)


def test_a_short_record_is_compared_whole() -> None:
    run = _record(20.0)
    assert window_long_runs([run]) == [run]


@pytest.mark.slow
def test_a_long_record_is_cut_into_windows_spread_over_it(long_run) -> None:  # type: ignore[no-untyped-def]
    windows = window_long_runs([long_run], max_slips=480, n_windows=8)
    assert len(windows) == 8
    t0, t1 = long_run.t_s[0], long_run.t_s[-1]
    assert windows[0].t_s[0] - t0 < 2.0 and t1 - windows[-1].t_s[-1] < 2.0
    starts = np.array([w.t_s[0] for w in windows])
    assert np.all(np.diff(starts) > 0.1 * (t1 - t0))  # spread, not bunched
    ds = prepare_dataset(windows)
    n = [r.events.n for r in ds.runs]
    assert all(55 <= k <= 65 for k in n), n
    assert sum(w.n_samples for w in windows) < 0.25 * long_run.n_samples
    assert any("long record" in note and "8 windows of 60 slips" in note for note in ds.notes)


@pytest.mark.slow
def test_a_long_record_of_another_rig_is_fitted_on_its_windows(long_run) -> None:  # type: ignore[no-untyped-def]
    windows = window_long_runs([long_run], max_slips=120, n_windows=4)
    cmp = compare(windows, ModelChoice("paper"))
    v = cmp.fit.choice.values
    keff_fit = 1.0 / (1.0 / v["k0_N_per_m"] + 1.0 / v["kts_N_per_m"])
    assert keff_fit == pytest.approx(1.0 / (1.0 / K0 + 1.0 / KTS), rel=0.1)
    assert v["mu_s"] == pytest.approx(MU_S, rel=0.05)
    assert v["mu_k"] == pytest.approx(MU_K, rel=0.05)
