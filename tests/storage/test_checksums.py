"""Corruption is noticed: every chunk of a run file's growing datasets carries a Fletcher-32
checksum, and a read that fails it names the dataset and the samples (docs/reliability.md)."""

from __future__ import annotations

import logging
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.data import DataError, MeasuredRun
from rigctl.storage import read_run, write_measured_run


@pytest.fixture()
def run_file(tmp_path: Path) -> Path:
    n = 40_000
    t = np.arange(n) / 1024.0
    run = MeasuredRun(t_s=t, x_stage_m=t * 1e-6, fn_N=300.0 + np.sin(t), ft_N=np.cos(t),
                      d1_m=np.zeros(n), d2_m=np.zeros(n), source="x")
    path = tmp_path / "run.h5"
    write_measured_run(path, run)
    return path


def test_every_growing_dataset_has_a_checksum(run_file: Path) -> None:
    with h5py.File(run_file) as f:
        daq = f["entry/daq"]
        for name in ("time", "ft_N", "fn_N", "x_stage_m", "d1_m", "d2_m"):
            assert daq[name].fletcher32, name


@pytest.mark.slow
def test_a_flipped_byte_is_reported_with_its_dataset_and_samples(run_file: Path,
                                                                tmp_path: Path) -> None:
    with h5py.File(run_file) as f:
        ds = f["entry/daq/ft_N"]
        chunk = ds.chunks[0]
        offset = ds.id.get_chunk_info(3).byte_offset
    data = bytearray(run_file.read_bytes())
    data[offset + 100] ^= 0xFF
    run_file.write_bytes(bytes(data))
    with pytest.raises(DataError, match=rf"/entry/daq/ft_N: samples {3 * chunk:,} to "
                                        rf"{4 * chunk:,}: checksum mismatch"):
        read_run(run_file)
    proc = subprocess.run([sys.executable, "-m", "rigctl.cli.main", "export", str(run_file),
                           "--csv", str(tmp_path / "x.csv")], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 2 and "checksum mismatch" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "x.csv").exists()


def test_unequal_lengths_in_a_closed_run_are_reported(run_file: Path,
                                                      caplog: pytest.LogCaptureFixture) -> None:
    with h5py.File(run_file, "r+") as f:
        ds = f["entry/daq/ft_N"]
        ds.resize((ds.shape[0] - 100,))
    with caplog.at_level(logging.WARNING):
        run = read_run(run_file)
    assert run.n_samples == 40_000 - 100
    assert "unequal length" in caplog.text and "/entry/daq/ft_N 39,900" in caplog.text
