"""The CSV exchange format (docs/csv-format.md): exact round trips, located errors."""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rigctl.data import REQUIRED_COLUMNS, DataError, MeasuredRun
from rigctl.io import csv_format
from rigctl.io.csv_format import read_csv, write_csv
from tests.io.conftest import make_run

HEADER = "t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m"


def _assert_same(a: MeasuredRun, b: MeasuredRun) -> None:
    assert list(a.columns()) == list(b.columns())
    for name, values in a.columns().items():
        np.testing.assert_array_equal(values, b.columns()[name], err_msg=name)
    assert a.metadata == b.metadata


def _write(tmp_path: Path, text: str, name: str = "run.csv") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def test_round_trip_is_exact(tmp_path: Path, run: MeasuredRun) -> None:
    path = tmp_path / "run.csv"
    write_csv(path, run)
    back = read_csv(path)
    _assert_same(run, back)
    assert back.source == str(path)
    # a second pass gives the same bytes: the format is canonical
    write_csv(tmp_path / "again.csv", back)
    assert path.read_bytes() == (tmp_path / "again.csv").read_bytes()


@settings(max_examples=40, deadline=None)
@given(values=st.lists(st.floats(allow_nan=False, allow_infinity=False, width=64), min_size=5, max_size=5))
def test_any_finite_float_round_trips(tmp_path_factory: pytest.TempPathFactory, values: list[float]) -> None:
    path = tmp_path_factory.mktemp("rt") / "one.csv"
    v = np.array(values)
    run = MeasuredRun(np.array([0.0]), v[:1], v[1:2], v[2:3], v[3:4], v[4:5])
    write_csv(path, run)
    back = read_csv(path)
    for name in REQUIRED_COLUMNS:
        assert getattr(back, name).tobytes() == getattr(run, name).tobytes()


def test_metadata_and_extra_columns_are_kept(tmp_path: Path) -> None:
    text = (
        "# sample_rate_hz: 1024\n"
        "# operator: Han\n"
        "# a plain comment without a key\n"
        "# custom_key: value with: colon\n"
        f"{HEADER},temp_C,fx_N\n"
        "0,0,300,1,1e-6,2e-6,21.5,0.5\n"
        "0.1,1e-6,300,2,1e-6,2e-6,nan,0.25\n"
    )
    run = read_csv(_write(tmp_path, text))
    assert run.metadata == {
        "sample_rate_hz": "1024",
        "operator": "Han",
        "custom_key": "value with: colon",
    }
    assert list(run.extra) == ["temp_C", "fx_N"]
    assert np.isnan(run.extra["temp_C"][1])  # NaN is allowed outside the required columns
    np.testing.assert_array_equal(run.delta_m, [-1e-6, -1e-6])


def test_column_order_is_free_and_crlf_bom_blank_lines_are_accepted(tmp_path: Path) -> None:
    text = (
        "\ufeff# operator: x\r\n"
        "ft_N, t_s ,x_stage_m,fn_N,d2_m,d1_m\r\n\r\n"
        "1,0,0,300,2,1\r\n2,1,0,300,2,1\r\n\r\n"
    )
    run = read_csv(_write(tmp_path, text))
    np.testing.assert_array_equal(run.t_s, [0.0, 1.0])
    np.testing.assert_array_equal(run.ft_N, [1.0, 2.0])
    np.testing.assert_array_equal(run.d1_m, [1.0, 1.0])
    assert run.metadata == {"operator": "x"}


CASES = [
    # (file text, expected line, expected column, words in the message)
    ("", None, None, "empty file"),
    ("\n  \n", None, None, "empty file"),
    ("# only: comments\n", None, None, "no header"),
    (f"{HEADER}\n", 1, None, "no data rows"),
    ("t_s,x_stage_m,fn_N,ft_N,d1_m\n0,0,0,0,0\n", 1, "d2_m", "missing required column"),
    ("t_s;x_stage_m;fn_N;ft_N;d1_m;d2_m\n0;0;0;0;0;0\n", 1, None, "semicolon"),
    ("t_s\tx_stage_m\tfn_N\tft_N\td1_m\td2_m\n0\t0\t0\t0\t0\t0\n", 1, None, "tab"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.1,0,abc,0,0,0\n", 3, "fn_N", "non-numeric value 'abc'"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.1,0,,0,0,0\n", 3, "fn_N", "empty value"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.1,0,0,0,0\n", 3, None, "expected 6 comma-separated values"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.1,0,0,0,0,0,7\n", 3, None, "found 7"),
    (f"{HEADER}\n0,0,0,0,0,0\n\n0.1,0,0,nan,0,0\n", 4, "ft_N", "NaN or infinite"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.1,0,0,0,0,-inf\n", 3, "d2_m", "NaN or infinite"),
    (f"{HEADER}\n0,0,0,0,0,0\n0.2,0,0,0,0,0\n0.2,0,0,0,0,0\n", 4, "t_s", "not strictly increasing"),
    (f"{HEADER}\n1,0,0,0,0,0\n0.5,0,0,0,0,0\n", 3, "t_s", "not strictly increasing"),
    ("t_s,x_stage_m,fn_N,ft_N,d1_m,d2_m,ft_N\n0,0,0,0,0,0,0\n", 1, "ft_N", "duplicate"),
    ("t_s,x_stage_m,,fn_N,ft_N,d1_m,d2_m\n0,0,0,0,0,0,0\n", 1, None, "no name"),
    (f"{HEADER}\n0;0;0;0;0;0\n", 2, None, "semicolon"),
]


@pytest.mark.filterwarnings("error")
def test_a_header_without_rows_is_named_without_a_numpy_warning(tmp_path: Path) -> None:
    f = tmp_path / "run.csv"
    f.write_text(f"{HEADER}\n")
    with pytest.raises(DataError, match="no data rows"):
        read_csv(f)


@pytest.mark.parametrize(("text", "line", "column", "words"), CASES)
def test_bad_input_names_file_line_and_column(
    tmp_path: Path, text: str, line: int | None, column: str | None, words: str
) -> None:
    path = _write(tmp_path, text)
    with pytest.raises(DataError) as info:
        read_csv(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == line
    assert err.column == column
    assert words in str(err)
    assert str(path) in str(err)


def test_not_utf8_and_missing_file(tmp_path: Path) -> None:
    path = tmp_path / "latin1.csv"
    path.write_bytes(f"{HEADER}\n0,0,0,0,0,0\n# caf\xe9\n".encode("latin-1"))
    with pytest.raises(DataError, match="not UTF-8") as info:
        read_csv(path)
    assert info.value.line == 3
    with pytest.raises(DataError, match="no such file"):
        read_csv(tmp_path / "absent.csv")


def test_write_refuses_invalid_runs_and_leaves_nothing(tmp_path: Path) -> None:
    bad = make_run(10)
    bad.ft_N[4] = np.nan
    path = tmp_path / "out.csv"
    with pytest.raises(DataError, match="NaN"):
        write_csv(path, bad)
    run = make_run(10)
    run.metadata["two\nlines"] = "x"
    with pytest.raises(DataError, match="metadata key"):
        write_csv(path, run)
    assert list(tmp_path.iterdir()) == []


def test_failed_write_keeps_the_old_file_and_no_temporary(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    path = tmp_path / "out.csv"
    path.write_text("previous content\n")

    def explode(columns: object) -> object:
        yield "0,0,0,0,0,0\n"
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(csv_format, "_format_rows", explode)
    with pytest.raises(DataError, match="No space left"):
        write_csv(path, make_run(10))
    assert path.read_text() == "previous content\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


def test_written_file_is_readable_by_others(tmp_path: Path) -> None:
    path = tmp_path / "out.csv"
    write_csv(path, make_run(5))
    assert os.stat(path).st_mode & 0o044 == 0o044


def test_write_into_missing_folder_is_a_clear_error(tmp_path: Path) -> None:
    with pytest.raises(DataError, match="folder does not exist"):
        write_csv(tmp_path / "nope" / "out.csv", make_run(5))


@pytest.mark.slow
def test_a_200_s_run_at_1024_hz_loads_in_well_under_a_second(tmp_path: Path) -> None:
    run = make_run(200 * 1024, extra=False)
    path = tmp_path / "long.csv"
    write_csv(path, run)
    # CPU time of this process: the parse is single-threaded, and CPU time does not count the
    # time other tests running in parallel take from it (wall time on an idle machine: ~0.45 s)
    start = time.process_time()
    back = read_csv(path)
    elapsed = time.process_time() - start
    assert back.n_samples == 204_800
    np.testing.assert_array_equal(back.ft_N, run.ft_N)
    assert elapsed < 1.0, f"read took {elapsed:.2f} s"
