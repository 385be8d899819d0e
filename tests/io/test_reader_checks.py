"""Every reader of measured data checks it the same way (issue 35 item 9 and its "Low" items):
``analyse``, ``import`` and ``info`` refuse values no rig measures as ``model compare`` does, a
run too short to analyse is one line, and messages show plain numbers and no raw control bytes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rigctl.analysis.source import open_source
from rigctl.cli.main import main
from rigctl.data import DataError, MeasuredRun
from rigctl.io.csv_format import read_csv, write_csv


def _csv(path: Path, n: int = 200, **overrides: float) -> Path:
    t = np.arange(n) / 1024.0
    cols = {"x_stage_m": t * 1e-5, "fn_N": 300.0 + 0 * t, "ft_N": 30.0 + np.sin(t),
            "d1_m": 0 * t, "d2_m": 0 * t}
    for name, value in overrides.items():
        cols[name] = cols[name].copy()
        cols[name][n // 2] = value
    write_csv(path, MeasuredRun(t_s=t, **cols))
    return path


@pytest.mark.parametrize("column", ["ft_N", "x_stage_m"])
def test_analyse_import_and_info_refuse_an_absurd_value(tmp_path: Path, column: str,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    bad = _csv(tmp_path / "bad.csv", **{column: 1e308})
    with pytest.raises(DataError, match=rf"1e\+308 in {column} \(sample 101\) is beyond"):
        open_source(bad)
    for argv in (["info", str(bad)], ["import", str(bad), "--out", str(tmp_path / "x.h5")]):
        assert main(argv) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "beyond any physical value" in err[0], err
    assert not (tmp_path / "x.h5").exists()


def test_a_one_row_csv_is_refused_in_one_line(tmp_path: Path) -> None:
    with pytest.raises(DataError, match=r"only 1 sample\(s\): nothing to analyse"):
        open_source(_csv(tmp_path / "one.csv", n=1))


def test_messages_show_plain_numbers(tmp_path: Path) -> None:
    path = tmp_path / "nan.csv"
    path.write_text("t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m\n0,0,1,1,0,0\n0.001,0,nan,1,0,0\n")
    with pytest.raises(DataError) as info:
        read_csv(path)
    assert "nan is not allowed" in str(info.value) and "np.float64" not in str(info.value)


def test_control_bytes_of_a_binary_file_are_never_echoed(tmp_path: Path) -> None:
    path = tmp_path / "binary.csv"
    path.write_bytes(b"\x1b[31mRED\x00\x07,x\n1,2\n")
    with pytest.raises(DataError) as info:
        read_csv(path)
    text = str(info.value)
    assert "\x1b" not in text and "\x00" not in text and "\\x1b[31mRED" in text
