"""The measured-run container shared by storage, import/export, the simulator and the workbench.

A :class:`MeasuredRun` holds what the rig records at the sensor sample rate, in SI units, with the
column names of the CSV exchange format (docs/csv-format.md): ``t_s``, ``x_stage_m``,
``fn_N``, ``ft_N``, ``d1_m``, ``d2_m``. Extra columns ride along in ``extra``; ``metadata`` keeps the
``# key: value`` lines (unknown keys included) and anything a run file records about the run.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from rigctl.errors import InputError

FloatArray = NDArray[np.float64]

REQUIRED_COLUMNS: tuple[str, ...] = ("t_s", "x_stage_m", "fn_N", "ft_N", "d1_m", "d2_m")
"""Required columns of the exchange format, in their canonical order."""

COLUMN_UNITS: dict[str, str] = {
    "t_s": "s",
    "x_stage_m": "m",
    "fn_N": "N",
    "ft_N": "N",
    "d1_m": "m",
    "d2_m": "m",
}


class DataError(InputError):
    """Measured data that cannot be used, with the file (and where known, line and column) named."""

    def __init__(
        self,
        message: str,
        *,
        path: str | Path | None = None,
        line: int | None = None,
        column: str | None = None,
    ) -> None:
        self.path = None if path is None else str(path)
        self.line = line
        self.column = column
        where = []
        if self.path is not None:
            where.append(self.path)
        if line is not None:
            where.append(f"line {line}")
        if column is not None:
            where.append(f"column '{column}'")
        prefix = ", ".join(where)
        super().__init__(f"{prefix}: {message}" if prefix else message)


@dataclass
class MeasuredRun:
    """One run sampled on a common time base (SI units throughout)."""

    t_s: FloatArray
    x_stage_m: FloatArray
    fn_N: FloatArray
    ft_N: FloatArray
    d1_m: FloatArray
    d2_m: FloatArray
    extra: dict[str, FloatArray] = field(default_factory=dict)
    metadata: dict[str, str] = field(default_factory=dict)
    source: str = ""

    def __post_init__(self) -> None:
        for name in REQUIRED_COLUMNS:
            setattr(self, name, np.ascontiguousarray(getattr(self, name), dtype=np.float64))
        n = self.t_s.shape[0]
        for name in REQUIRED_COLUMNS:
            arr = getattr(self, name)
            if arr.ndim != 1 or arr.shape[0] != n:
                raise DataError(
                    f"column '{name}' has shape {arr.shape}, expected ({n},)", path=self.source
                )
        for name, arr in self.extra.items():
            if np.asarray(arr).shape != (n,):
                raise DataError(f"extra column '{name}' has the wrong length", path=self.source)

    @property
    def delta_m(self) -> FloatArray:
        """Relative interface displacement delta = d1 - d2 (import-format.md)."""
        return self.d1_m - self.d2_m

    @property
    def n_samples(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0]) if self.n_samples > 1 else 0.0

    @property
    def sample_rate_hz(self) -> float:
        """Median sample rate of the time base."""
        if self.n_samples < 2:
            return float("nan")
        return float(1.0 / np.median(np.diff(self.t_s)))

    def columns(self) -> dict[str, FloatArray]:
        """All columns, required first, then extras, in a stable order."""
        cols = {name: getattr(self, name) for name in REQUIRED_COLUMNS}
        cols.update(self.extra)
        return cols

    def validate(self) -> None:
        """Raise :class:`DataError` naming the first column that is NaN/inf or a non-increasing time."""
        for name in REQUIRED_COLUMNS:
            arr = getattr(self, name)
            bad = np.flatnonzero(~np.isfinite(arr))
            if bad.size:
                raise DataError(
                    f"NaN or infinite value at sample {int(bad[0])}", path=self.source, column=name
                )
        if self.n_samples >= 2:
            steps = np.diff(self.t_s)
            bad = np.flatnonzero(steps <= 0)
            if bad.size:
                raise DataError(
                    f"time is not strictly increasing at sample {int(bad[0]) + 1}",
                    path=self.source,
                    column="t_s",
                )
