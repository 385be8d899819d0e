"""Every reader of a run file reads delta stitched across the probes' re-centrings (issue 35).

A simulated TLRE (60 s, 13 slips) is written as a run file whose D1 mount was moved by 35 um
after each slip but the first, 0.2 s into the settled stick (where the re-centring of the default
TLRE lands: the slip carries D1 past its headroom, and the mount moves as soon as the reading is
steady), each move recorded as a ``probe_recentre`` event with its 80 ms window. The workbench's
prepared run (``rigctl model compare``), the analysis and the CSV export must read the same slips,
slip distances and lag as from the record without moves: no lag "misfit" of the mount's jumps, no
slip distance lost to a move in its post-slip window, an exported delta continuous across every
move.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigctl.data import MeasuredRun
from rigctl.io.csv_format import read_csv
from rigctl.io.export import export_csv
from rigctl.io.load import load_runs
from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset, prepare_run
from rigctl.records.delta_stitch import STITCHED_KEY
from rigctl.records.probe_range import probe_range
from rigctl.storage import RunWriter, read_run
from rigctl.storage.layout import DaqLayout, RunDescription
from rigctl.storage.probe_events import RECENTRE_EVENT, recentre_message
from rigctl.workbench.campaigns import simulate_campaign

TRUTH = {"mu_s": 0.17, "mu_k": 0.12, "kts_N_per_m": 1.1e6, "k0_N_per_m": 1.25e6,
         "mu_smax": 0.21, "kt0_N_per_m": 1.7e6, "p_slope": 0.8}
MOVE_M = 35e-6
MOVE_S = 0.08
AFTER_SLIP_S = 0.2


@pytest.fixture(scope="module")
def record(tmp_path_factory: pytest.TempPathFactory) -> tuple[MeasuredRun, Path, np.ndarray]:
    """The simulated record, its re-centred run file and the moves' start times."""
    (run,) = simulate_campaign(build_model("paper", params=TRUTH), "tlre", seed=11)
    drops = prepare_run(run, "plain").events.t_drop_s + run.t_s[0]
    starts = drops[1:] + AFTER_SLIP_S
    mount = np.zeros(run.n_samples)
    for t0 in starts:
        mount += MOVE_M * np.clip((run.t_s - t0) / MOVE_S, 0.0, 1.0)
    path = tmp_path_factory.mktemp("recentred") / "tlre.h5"
    daq = DaqLayout(channels=("x_stage_m", "fn_N", "ft_N", "d1_m", "d2_m"))
    with RunWriter(path, RunDescription(protocol="tlre"), daq) as w:
        w.append_daq({"t_s": run.t_s, "x_stage_m": run.x_stage_m, "fn_N": run.fn_N,
                      "ft_N": run.ft_N, "d1_m": run.d1_m - mount, "d2_m": run.d2_m})
        for t0 in starts:
            w.add_event(float(t0) + 0.3, RECENTRE_EVENT,
                        recentre_message("d1_m", MOVE_M, 5e-6, 5e-6 - MOVE_M, float(t0) - 0.005,
                                         MOVE_S + 0.01))
    return run, path, starts


def test_model_compare_reads_no_lag_or_slip_from_the_mount_moves(record) -> None:
    """What ``rigctl model compare`` prepares (load_runs, prepare_dataset) from the re-centred
    file: the plain record's slips, lag and slip distances."""
    run, path, _starts = record
    plain = prepare_dataset([run]).runs[0].events
    moved = prepare_dataset(load_runs([path])).runs[0].events
    assert moved.n == plain.n
    for name, atol in (("lag_m", 0.2e-6), ("slip_m", 0.2e-6), ("k_stick_N_per_m", 2e4)):
        a, b = plain.features[name], moved.features[name]
        assert np.array_equal(np.isfinite(a), np.isfinite(b)), name  # no slip lost to a move
        np.testing.assert_allclose(b[np.isfinite(b)], a[np.isfinite(a)], atol=atol, err_msg=name)


def test_a_move_made_in_a_steady_stick_leaves_delta_valid(record) -> None:
    _run, path, _starts = record
    (loaded,) = load_runs([path])
    assert probe_range(loaded).delta_valid.all()


def test_the_export_carries_the_stitched_delta_and_the_recorded_readings(record, tmp_path) -> None:
    run, path, starts = record
    out = tmp_path / "tlre.csv"
    export_csv(path, out)
    csv = read_csv(out)
    outside = np.ones(run.n_samples, dtype=bool)
    for t0 in starts:
        outside &= ~((run.t_s > t0 - 0.005) & (run.t_s <= t0 + MOVE_S + 0.005))
    np.testing.assert_allclose(csv.d1_m[outside], run.d1_m[outside], atol=1e-12)
    assert np.max(np.abs(np.diff(csv.delta_m))) <= np.max(np.abs(np.diff(run.delta_m))) + 1e-9
    np.testing.assert_array_equal(csv.extra["d1_recorded_m"], read_run(path).d1_m)
    assert "d2_recorded_m" not in csv.extra  # D2's mount never moved
    assert csv.metadata[STITCHED_KEY].startswith(f"d1_m: {starts.size} mount move")


def test_the_analysis_reads_the_same_slips(record) -> None:
    from rigctl.analysis.source import open_source

    run, path, _starts = record
    src = open_source(path)
    assert STITCHED_KEY in src.run.metadata
    np.testing.assert_allclose(prepare_run(src.run, "x").events.features["lag_m"],
                               prepare_run(run, "x").events.features["lag_m"], atol=0.2e-6)


def test_the_comparison_s_figures_read_the_stitched_runs(record) -> None:
    """``compare`` keeps the runs its report draws (the Ft-delta loops): stitched, as the dataset
    it scores is, not the readings with the mount's jumps."""
    from rigctl.workbench.compare import compare
    from rigctl.workbench.model_choice import ModelChoice

    run, path, _starts = record
    cmp = compare(load_runs([path]), ModelChoice("paper").with_values(TRUTH), identify=False)
    (shown,) = cmp.runs
    assert STITCHED_KEY in shown.metadata
    drawn = shown.d1_m - shown.d2_m
    np.testing.assert_allclose(drawn, run.d1_m - run.d2_m, atol=0.5e-6)  # the record, no jumps
