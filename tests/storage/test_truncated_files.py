"""Truncated run files are refused at once with one line, never hang (docs/reliability.md).

An HDF5 open for SWMR does not compare the file's size with the end its superblock declares and
retried its metadata reads for more than 20 minutes, ignoring Ctrl-C, on a file cut to 100 bytes
or 4 kB; a half file opened and read missing chunks as zeros.
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


@pytest.mark.parametrize("keep", [0, 100, 4096, "half"])
def test_a_truncated_file_is_refused_at_once(whole: Path, tmp_path: Path, keep: int | str) -> None:
    data = whole.read_bytes()
    n = len(data) // 2 if keep == "half" else int(keep)
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
