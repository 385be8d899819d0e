"""A displacement probe over range (at its rail) must not feed delta features or the fit.

A simulated TLRE run has D1 clipped at a rail over the later part of the record, as the rig's
acquisition records it (the rail value, exactly). As a bare MeasuredRun (a CSV from another rig) the
workbench must find the saturation itself; as a run file it reads the ``probe_over_range`` /
``probe_in_range`` events (the rail there carries noise, so only the events can tell).
"""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset
from rigctl.records.probe_range import probe_range
from rigctl.storage import RunWriter
from rigctl.storage.layout import DaqLayout, RunDescription
from rigctl.workbench.campaigns import simulate_campaign
from rigctl.workbench.compare import Comparison, compare
from rigctl.workbench.model_choice import ModelChoice

TRUTH = {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
         "mu_smax": 0.21, "kt0_N_per_m": 1.7e6, "p_slope": 0.8}
OVER_FROM = 0.45
"""D1 goes over range at this fraction of its travel and stays there."""


def _clipped(run: MeasuredRun) -> tuple[MeasuredRun, float]:
    d1 = run.d1_m
    rail = float(np.min(d1) + OVER_FROM * np.ptp(d1))
    over = np.flatnonzero(d1 >= rail)
    t_over = float(run.t_s[over[0]])
    clipped = np.where(run.t_s >= t_over, rail, d1)
    out = MeasuredRun(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, clipped, run.d2_m,
                      dict(run.extra), dict(run.metadata), "tlre_clipped.csv")
    return out, t_over


@pytest.fixture(scope="module")
def runs() -> tuple[MeasuredRun, MeasuredRun, float]:
    (run,) = simulate_campaign(build_model("paper", params=TRUTH), "tlre", seed=11)
    clipped, t_over = _clipped(run)
    return run, clipped, t_over


def _write_h5(path, run: MeasuredRun, t_over: float) -> None:
    # the rail with a little noise on it: saturation alone cannot find it, the events must
    rng = np.random.default_rng(3)
    d1 = np.where(run.t_s >= t_over, run.d1_m + rng.normal(0.0, 2e-8, run.n_samples), run.d1_m)
    layout = DaqLayout(channels=("x_stage_m", "fn_N", "ft_N", "d1_m", "d2_m"))
    with RunWriter(path, RunDescription(protocol="tlre"), layout) as w:
        w.append_daq({"t_s": run.t_s, "x_stage_m": run.x_stage_m, "fn_N": run.fn_N,
                      "ft_N": run.ft_N, "d1_m": d1, "d2_m": run.d2_m})
        w.add_event(t_over, "probe_over_range", "d1_m: probe over range (analog output at the "
                    "rail; the recorded value is the rail, not a displacement)")


def _check_recovered(cmp: Comparison) -> None:
    v = cmp.fit.choice.values
    assert v["kts_N_per_m"] == pytest.approx(TRUTH["kts_N_per_m"], rel=0.05)
    assert v["mu_k"] == pytest.approx(TRUTH["mu_k"], rel=0.03)
    assert "kts_N_per_m" not in cmp.fit.undetermined
    # K(i), slip distances and the lag are read only where D1 was in range
    ev = cmp.dataset.runs[0].events
    t_over = ev.t_drop_s[~np.isfinite(ev.features["slip_m"])]
    assert t_over.size and np.isfinite(ev.features["peak_N"]).sum() >= ev.n - 1


def test_saturation_is_found_in_a_bare_record(runs):
    raw, clipped, t_over = runs
    pr = probe_range(clipped)
    over = ~pr.delta_valid
    assert over.any() and not probe_range(raw).any_over
    # the stretch at the rail, nothing before it
    assert not over[clipped.t_s < t_over - 1e-9].any()
    assert over.mean() == pytest.approx(np.mean(clipped.t_s >= t_over), abs=0.02)


@pytest.mark.slow
def test_compare_excludes_the_saturated_delta_and_recovers_kts_and_mu_k(runs):
    _raw, clipped, t_over = runs
    cmp = compare([clipped], ModelChoice("paper"))
    pct = round(100 * float(np.mean(clipped.t_s >= t_over)))
    assert any(n.startswith(f"D1 over range for {pct} % of tlre_clipped.csv (saturation)")
               and "delta features excluded" in n for n in cmp.dataset.notes), cmp.dataset.notes
    _check_recovered(cmp)


@pytest.mark.slow
def test_a_run_file_is_read_with_its_over_range_events(runs, tmp_path):
    _raw, clipped, t_over = runs
    path = tmp_path / "tlre.h5"
    _write_h5(path, clipped, t_over)
    from rigctl.io.load import load_runs

    loaded = load_runs([path])
    ds = prepare_dataset(loaded)
    assert any("D1 over range" in n and "(events)" in n for n in ds.notes), ds.notes
    cmp = compare(loaded, ModelChoice("paper"), dataset=ds)
    _check_recovered(cmp)
