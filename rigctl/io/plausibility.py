"""Data that are legal but implausible: the likely unit or sign mistake, named before any analysis.

A record can parse cleanly and still say something no rig measured: times in milliseconds in the
``t_s`` column, a compressive normal force recorded negative, a value of 1e300 from a broken
export. :func:`check_plausible` refuses what no computation can use (values beyond
:data:`ABSURD`, which overflow every square and sum) and returns warnings for the rest; the
loader logs them, the user reads them on stderr, and nothing is silently "corrected".
"""

from __future__ import annotations

import logging
import math

import numpy as np

from rigctl.data import REQUIRED_COLUMNS, DataError, MeasuredRun

_log = logging.getLogger(__name__)

ABSURD = 1e30
"""No SI force (N), displacement (m) or time (s) of a friction rig comes near this; squares of
such values overflow float64 in the analyses."""
RATE_MISMATCH = 2.0
"""Factor by which the measured sample rate may differ from a stated ``sample_rate_hz``."""


def checked(run: MeasuredRun, name: str) -> MeasuredRun:
    """``run`` once :func:`check_plausible` has passed it, its warnings logged: what every reader of
    measured data (analyse, import, info, the workbench) calls before using the numbers."""
    for warning in check_plausible(run, name):
        _log.warning("%s", warning)
    return run


def check_plausible(run: MeasuredRun, name: str) -> list[str]:
    """Refuse absurd values (DataError naming the column); warnings for likely unit or sign
    mistakes (empty when none)."""
    for column in REQUIRED_COLUMNS:
        values = np.asarray(getattr(run, column))
        big = np.flatnonzero(np.abs(values) > ABSURD)
        if big.size:
            i = int(big[0])
            raise DataError(f"{values[i]:.3g} in {column} (sample {i + 1}) is beyond any "
                            "physical value: a broken export or a unit error", path=name,
                            column=column)
    warnings: list[str] = []
    stated = run.metadata.get("sample_rate_hz", "").strip()
    rate = run.sample_rate_hz
    if stated and run.n_samples > 1 and math.isfinite(rate) and rate > 0:
        try:
            said = float(stated)
        except ValueError:
            said = math.nan
        if said > 0 and not 1.0 / RATE_MISMATCH <= rate / said <= RATE_MISMATCH:
            hint = ""
            if abs(math.log10(said / rate) - 3.0) < 0.1:
                hint = " - is t_s in milliseconds? (it must be in seconds)"
            warnings.append(f"{name}: the times give {rate:.4g} Hz but the file states "
                            f"sample_rate_hz {said:g}{hint}")
    fn = np.asarray(run.fn_N)
    if fn.size and float(np.median(fn)) < 0.0 and float(np.percentile(fn, 95)) <= 0.0:
        warnings.append(f"{name}: Fn is negative (median {float(np.median(fn)):.4g} N): a "
                        "pressing load is positive in the exchange format - is its sign flipped?")
    return warnings
