"""write_measured_run: CSV -> HDF5 -> CSV is exact; nothing half-written is left behind."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.io.csv_format import read_csv, write_csv
from rigctl.model import Drive, Simulator, build_model
from rigctl.storage import RunReader, StorageError, read_run, write_measured_run
from rigctl.storage import preflight as preflight_module
from rigctl.storage import writer as writer_module
from tests.io.conftest import make_run


def test_csv_to_h5_to_csv_is_byte_exact(tmp_path: Path) -> None:
    original = tmp_path / "original.csv"
    write_csv(original, make_run(5000))
    run_file = write_measured_run(
        tmp_path / "run.h5", read_csv(original), protocol="import", parameters={"source": "original.csv"}
    )
    write_csv(tmp_path / "back.csv", read_run(run_file))
    assert (tmp_path / "back.csv").read_bytes() == original.read_bytes()
    with RunReader(run_file) as r:
        s = r.summary()
    assert (s.protocol, s.status, s.n_samples) == ("import", "completed", 5000)
    assert s.parameters == {"source": "original.csv"}
    assert s.operator == "A. Tester"  # taken from the CSV's metadata
    assert s.sample_rate_hz == 1024.0
    assert s.channels["temp_C"] == "degC" and s.channels["fx_N"] == "N"


def test_a_simulated_run_round_trips(tmp_path: Path) -> None:
    sim = Simulator(build_model(), sample_rate_hz=1024.0)
    measured = sim.run(Drive.constant(fn_N=300.0, velocity_m_s=1e-5, duration_s=2.0)).to_measured()
    path = write_measured_run(tmp_path / "sim.h5", measured, protocol="simulate")
    back = read_run(path)
    for name, values in measured.columns().items():
        np.testing.assert_array_equal(back.columns()[name], values, err_msg=name)
    assert back.metadata == measured.metadata


def test_invalid_runs_and_failures_leave_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    bad = make_run(100)
    bad.t_s[50] = bad.t_s[49]
    with pytest.raises(DataError, match="strictly increasing"):
        write_measured_run(tmp_path / "bad.h5", bad)

    def broken_append(self: object, *args: object, **kwargs: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(writer_module.RunWriter, "append_daq", broken_append)
    with pytest.raises(StorageError, match="No space left"):
        write_measured_run(tmp_path / "full.h5", make_run(100))
    assert list(tmp_path.iterdir()) == []


def test_existing_files_are_kept_unless_overwrite(tmp_path: Path) -> None:
    path = write_measured_run(tmp_path / "run.h5", make_run(10))
    with pytest.raises(StorageError, match="already exists"):
        write_measured_run(path, make_run(20))
    assert read_run(path).n_samples == 10
    write_measured_run(path, make_run(20), overwrite=True)
    assert read_run(path).n_samples == 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.h5"]


def test_a_read_only_folder_is_refused_up_front(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # as root every folder is writable, so emulate a read-only one at the permission check
    monkeypatch.setattr(preflight_module.os, "access", lambda path, mode: False)
    with pytest.raises(StorageError, match="is not writable"):
        write_measured_run(tmp_path / "run.h5", make_run(10))
    assert list(tmp_path.iterdir()) == []
