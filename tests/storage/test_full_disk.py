"""A disk that fills mid-run never costs the data already written (issue 35 item 4).

Before: the last, failed flush left the datasets' new length recorded but their new chunks
unwritten, so the file's tail read as zeros (t = 0 from sample 4,096 here, 16,384 in the report);
``info`` said "duration 0 s" and ``export``/``analyse`` refused the whole file ("time is not
strictly increasing at sample 4096"). Now the writer records in ``daq/rows_valid`` only rows that a
flush has put on disk, and readers read the valid prefix of any file with a warning naming the
samples left out (also of files written before ``rows_valid`` existed: by the chunks actually in
the file and by the first time that stops increasing).
"""

from __future__ import annotations

import logging
import os
import resource
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.storage import DaqLayout, RunDescription, RunReader, RunWriter, read_run
from tests.storage.conftest import block

ROOT = Path(__file__).resolve().parents[2]
WRITER = Path(__file__).with_name("full_disk_writer_proc.py")
RIGCTL = [sys.executable, "-m", "rigctl.cli.main"]

pytestmark = pytest.mark.skipif(not hasattr(resource, "RLIMIT_FSIZE"), reason="needs RLIMIT_FSIZE")


@pytest.fixture(scope="module")
def full(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    path = tmp_path_factory.mktemp("full") / "full.h5"
    proc = subprocess.run([sys.executable, str(WRITER), str(path), "400000"], capture_output=True,
                          text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert "stopped:" in proc.stdout, (proc.stdout, proc.stderr)
    return path, proc.stdout


def test_the_writer_counts_only_rows_that_reached_the_disk(full: tuple[Path, str]) -> None:
    path, out = full
    appended = int(out.split("appended ")[1].split()[0])
    with h5py.File(path, "r", swmr=True) as f:
        counted = f["entry/daq/time"].shape[0]
        valid_samples = int(f["entry/daq/rows_valid"][0])
        t = f["entry/daq/time"][:counted]
    assert counted > valid_samples > 0  # the failed flush left rows counted but unwritten
    assert appended >= counted
    np.testing.assert_array_equal(t[:valid_samples], np.arange(valid_samples) / 1024.0)


def test_the_valid_part_of_a_full_disk_run_is_read_with_a_warning(
        full: tuple[Path, str], caplog: pytest.LogCaptureFixture) -> None:
    path, _ = full
    with caplog.at_level(logging.WARNING):
        run = read_run(path)
    n = run.n_samples
    assert n >= 4096
    expected = block(0, n)
    np.testing.assert_array_equal(run.t_s, expected["t_s"])
    np.testing.assert_array_equal(run.ft_N, expected["ft_N"])
    assert f"samples {n:,} to" in caplog.text and "left out" in caplog.text
    with RunReader(path) as r:
        s = r.summary()
    assert s.status == "failed"
    assert s.n_samples == n and s.duration_s == pytest.approx((n - 1) / 1024.0)


@pytest.mark.slow
def test_info_and_export_of_a_full_disk_run(full: tuple[Path, str], tmp_path: Path) -> None:
    path, _ = full
    n = read_run(path).n_samples
    info = subprocess.run([*RIGCTL, "info", str(path)], capture_output=True, text=True, timeout=120)
    assert info.returncode == 0, info.stderr
    assert f"duration  {(n - 1) / 1024.0:.6g} s" in info.stdout
    assert f"samples   {n} at 1024 Hz" in info.stdout
    assert "left out" in info.stderr
    out = tmp_path / "full.csv"
    exp = subprocess.run([*RIGCTL, "export", str(path), "--csv", str(out)], capture_output=True,
                         text=True, timeout=120)
    assert exp.returncode == 0, exp.stderr
    assert f"({n} samples" in exp.stdout


def test_a_zero_filled_tail_without_rows_valid_is_left_out(
        tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    """A file written before ``rows_valid`` (format 1.0) whose datasets count rows never written:
    the times end where the writing did."""
    path = tmp_path / "old.h5"
    with RunWriter(path, RunDescription(protocol="t"), DaqLayout(sample_rate_hz=1024.0),
                   min_free_bytes=0) as w:
        w.append_daq(block(0, 1000))
    with h5py.File(path, "r+") as f:
        del f["entry/daq/rows_valid"]
        daq = f["entry/daq"]
        for name in ("time", *DaqLayout().channels):
            daq[name].resize(1500, axis=0)  # rows 1000.. read as the chunk's fill: zeros
    with caplog.at_level(logging.WARNING):
        run = read_run(path)
    assert run.n_samples == 1000
    assert "samples 1,000 to 1,500 left out" in caplog.text
