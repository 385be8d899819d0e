"""Truncated run files are refused with one line within seconds, never hang (docs/reliability.md).

An HDF5 open for SWMR does not compare the file's size with the end its superblock declares and
retried its metadata reads for more than 20 minutes, ignoring Ctrl-C, on a file cut to 100 bytes
or 4 kB. A truncated file is now first opened in a child process killed after
``TRUNCATED_OPEN_TIMEOUT_S``: one cut inside its metadata is refused; one whose flushed part is
whole (a disk that filled mid-run, tests/cli/test_run_cli.py) is read with a warning.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.storage.reader import RunReader

RIGCTL = [sys.executable, "-m", "rigctl.cli.main"]


@pytest.fixture(scope="module")
def whole(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("trunc") / "whole.h5"
    with h5py.File(path, "w", libver="latest") as f:
        f.create_dataset("entry/daq/time", data=np.arange(200_000, dtype=np.float64),
                         chunks=(4096,))
    return path


@pytest.mark.parametrize("keep", [0, 100, 4096])
@pytest.mark.slow
def test_a_truncated_file_is_refused_at_once(whole: Path, tmp_path: Path, keep: int) -> None:
    data = whole.read_bytes()
    n = keep
    cut = tmp_path / f"cut_{keep}.h5"
    cut.write_bytes(data[:n])
    with pytest.raises(DataError, match="truncated file"):
        RunReader(cut)
    for cmd in (["info", str(cut)], ["export", str(cut), "--csv", str(tmp_path / "x.csv")],
                ["model", "compare", str(cut)]):
        proc = subprocess.run([*RIGCTL, *cmd], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 2, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and "truncated file" in lines[0], proc.stderr
    assert not (tmp_path / "x.csv").exists()


def test_a_file_cut_in_half_never_hangs(whole: Path, tmp_path: Path) -> None:
    """Cut in half, the metadata at the file's end is lost: whatever the verdict (refused, or not a
    run file), each command answers with one line within the time limit instead of hanging."""
    data = whole.read_bytes()
    cut = tmp_path / "cut_half.h5"
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(DataError):
        RunReader(cut)
    proc = subprocess.run([*RIGCTL, "info", str(cut)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
