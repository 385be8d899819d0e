"""Campaign preparation: bad data gives DataError naming the file; CSV works like in memory."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.io.load import load_runs
from rigctl.model import build_model
from rigctl.records.dataset import prepare_dataset, protocols_present
from rigctl.workbench.campaigns import simulate_campaign, write_campaign
from tests.workbench.synth import sawtooth_run


def test_nan_in_a_run_is_named():
    run, _ = sawtooth_run(source="lab/run7.csv")
    run.ft_N[100] = np.nan
    with pytest.raises(DataError, match=r"lab/run7.csv.*ft_N"):
        prepare_dataset([run])


def test_a_run_too_short_to_hold_a_slip_is_refused():
    run, _ = sawtooth_run(duration_s=3.0, source="short.csv")
    with pytest.raises(DataError, match=r"short\.csv.*no slip"):
        prepare_dataset([run])


def test_a_handful_of_samples_is_refused():
    run, _ = sawtooth_run(duration_s=0.03, source="tiny.csv")
    with pytest.raises(DataError, match=r"tiny\.csv.*too short"):
        prepare_dataset([run])


def test_a_run_without_slips_in_a_campaign_is_kept_with_a_note():
    good, _ = sawtooth_run(source="a.csv")
    quiet, _ = sawtooth_run(peak_N=1e9, source="b.csv")
    ds = prepare_dataset([good, quiet])
    assert ds.runs[1].events.n == 0
    assert any("b.csv" in n for n in ds.notes)


def test_csv_campaign_reads_exactly_like_the_runs_in_memory(tmp_path):
    model = build_model("paper")
    runs = simulate_campaign(model, "force_sweep", seed=5, duration_scale=0.5)
    write_campaign(runs, tmp_path)
    from_csv = prepare_dataset(load_runs([tmp_path]))
    in_memory = prepare_dataset(runs)
    assert len(from_csv.runs) == 5
    for a, b in zip(from_csv.runs, in_memory.runs, strict=True):
        assert a.events.n == b.events.n
        for name in ("peak_N", "trough_N", "stick_s", "k_stick_N_per_m"):
            assert np.allclose(a.events.features[name], b.events.features[name], equal_nan=True)
    assert protocols_present(from_csv) == protocols_present(in_memory)
    assert "force sweep" in protocols_present(from_csv)


@pytest.mark.slow
def test_hdf5_run_files_read_exactly_like_the_csv_exchange_files(tmp_path):
    from rigctl.storage.convert import write_measured_run

    runs = simulate_campaign(build_model("paper"), "velocity_steps", seed=6, duration_scale=0.4)
    csv_dir, h5_dir = tmp_path / "csv", tmp_path / "h5"
    write_campaign(runs, csv_dir)
    h5_dir.mkdir()
    for i, run in enumerate(runs):
        write_measured_run(h5_dir / f"{i:02d}.h5", run)
    a = prepare_dataset(load_runs([csv_dir]))
    b = prepare_dataset(load_runs([h5_dir]))
    assert a.n_events == b.n_events > 5
    for ra, rb in zip(a.runs, b.runs, strict=True):
        assert np.allclose(ra.drive.t_s, rb.drive.t_s) and np.allclose(ra.drive.fn_N, rb.drive.fn_N)
        for name in ("peak_N", "drop_N", "stick_s", "slip_m"):
            assert np.allclose(ra.events.features[name], rb.events.features[name],
                               equal_nan=True, rtol=1e-6)
    assert a.sigma == pytest.approx(b.sigma, rel=1e-6, nan_ok=True)
