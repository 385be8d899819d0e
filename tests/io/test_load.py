"""load_runs: files and folders of CSV and HDF5 runs, with clear errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigctl.data import DataError
from rigctl.io import load_runs
from rigctl.io.csv_format import write_csv
from rigctl.storage import write_measured_run
from tests.io.conftest import make_run


def test_files_and_folders_in_order(tmp_path: Path) -> None:
    campaign = tmp_path / "campaign"
    campaign.mkdir()
    write_csv(campaign / "b_200N.csv", make_run(50, seed=2))
    write_measured_run(campaign / "a_100N.h5", make_run(40, seed=1))
    write_csv(campaign / "c_300N.csv", make_run(30, seed=3))
    (campaign / "notes.txt").write_text("not a run")
    (campaign / ".hidden.csv").write_text("ignored")
    single = tmp_path / "single.csv"
    write_csv(single, make_run(20, seed=4))

    runs = load_runs([single, campaign])

    assert [r.n_samples for r in runs] == [20, 40, 50, 30]
    assert [Path(r.source).name for r in runs] == ["single.csv", "a_100N.h5", "b_200N.csv", "c_300N.csv"]
    np.testing.assert_array_equal(runs[1].ft_N, make_run(40, seed=1).ft_N)
    assert runs[1].extra.keys() == make_run(40, seed=1).extra.keys()


def test_missing_path_empty_folder_unknown_type(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="no such file or folder") as info:
        load_runs([tmp_path / "absent.csv"])
    assert info.value.path == str(tmp_path / "absent.csv")
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "readme.md").write_text("x")
    with pytest.raises(DataError, match=r"no \*\.csv or \*\.h5"):
        load_runs([empty])
    other = tmp_path / "run.xlsx"
    other.write_text("x")
    with pytest.raises(DataError, match="unknown file type"):
        load_runs([other])
    with pytest.raises(DataError, match="no run files"):
        load_runs([])


def test_a_bad_file_in_a_folder_is_named(tmp_path: Path) -> None:
    write_csv(tmp_path / "good.csv", make_run(10))
    (tmp_path / "zbad.csv").write_text("t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m\n0,0,0,0,0,x\n")
    with pytest.raises(DataError) as info:
        load_runs([tmp_path])
    assert info.value.path == str(tmp_path / "zbad.csv")
    assert info.value.line == 2
    assert info.value.column == "d2_m"
