"""Legal but implausible data: the likely mistake is named (rigctl/io/plausibility.py)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

from rigctl.data import DataError, MeasuredRun
from rigctl.io.csv_format import write_csv
from rigctl.io.load import load_run


def _run(t_s: np.ndarray, fn: float = 300.0, ft_extra: float | None = None,
         rate_meta: str = "1024") -> MeasuredRun:
    n = t_s.size
    ft = np.abs(np.sin(np.arange(n) / 50.0)) * 100.0
    if ft_extra is not None:
        ft[n // 2] = ft_extra
    return MeasuredRun(t_s=t_s, x_stage_m=np.arange(n) * 1e-9, fn_N=np.full(n, fn), ft_N=ft,
                       d1_m=np.zeros(n), d2_m=np.zeros(n),
                       metadata={"sample_rate_hz": rate_meta} if rate_meta else {})


def _load(tmp_path: Path, run: MeasuredRun, caplog: pytest.LogCaptureFixture) -> str:
    path = tmp_path / "r.csv"
    write_csv(path, run)
    with caplog.at_level(logging.WARNING):
        load_run(path)
    return caplog.text


def test_times_in_milliseconds_are_named(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    text = _load(tmp_path, _run(np.arange(2000) * 1000.0 / 1024.0), caplog)
    assert "states sample_rate_hz 1024" in text and "milliseconds" in text


def test_a_negative_normal_force_is_named(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    text = _load(tmp_path, _run(np.arange(2000) / 1024.0, fn=-300.0), caplog)
    assert "Fn is negative" in text and "sign flipped" in text


def test_plausible_data_raise_no_warning(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    assert _load(tmp_path, _run(np.arange(2000) / 1024.0), caplog) == ""


def test_an_absurd_value_is_refused_naming_the_column(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    write_csv(path, _run(np.arange(2000) / 1024.0, ft_extra=1e300))
    with pytest.raises(DataError, match=r"1e\+300 in ft_N \(sample 1001\) is beyond any physical"):
        load_run(path)
