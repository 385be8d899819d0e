"""Friction coefficients of a pass (paper Sec. 3.1: "the ratio of the extreme value of the tangential
force to the normal force is defined as the friction coefficient").

* ``mu_s,max`` = Ft threshold of the initial stage / Fn (the first peak of a pass from rest);
* ``mu_s``     = maxima of Ft in the stable stage / Fn (per stable cycle: its peak / its Fn);
* ``mu_k``     = minima of Ft in the stable stage / Fn (per stable cycle: its trough / its Fn).

The maxima and minima are the cycle levels of :mod:`rigctl.analysis.stickslip` (line fits either
side of each drop). The minimum is the *settled* post-slip force: right after a slip the specimen
rings at about 1 kHz and the 1024 Hz samples alias that ringing, so the lowest sample is a matter of
where the samples fall (docs/analysis.md). Each coefficient of the stable stage is the mean over its
cycles with the sample standard deviation as its spread (``std`` = 0 with one cycle, NaN with none).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from rigctl.analysis.stickslip import PassRecord
from rigctl.data import FloatArray


@dataclass(frozen=True)
class Coefficient:
    """Mean, spread (sample standard deviation), range and count of one coefficient."""

    mean: float
    std: float
    min: float
    max: float
    n: int

    @staticmethod
    def of(values: FloatArray) -> Coefficient:
        v = values[np.isfinite(values)]
        if v.size == 0:
            nan = float("nan")
            return Coefficient(nan, nan, nan, nan, 0)
        std = float(np.std(v, ddof=1)) if v.size > 1 else 0.0
        return Coefficient(float(np.mean(v)), std, float(np.min(v)), float(np.max(v)), int(v.size))

    def to_dict(self) -> dict[str, float | int]:
        return asdict(self)


@dataclass(frozen=True)
class FrictionCoefficients:
    """The paper's three coefficients of one pass."""

    mu_s_max: float
    mu_s: Coefficient
    mu_k: Coefficient

    def to_dict(self) -> dict[str, object]:
        return {"mu_s_max": self.mu_s_max, "mu_s": self.mu_s.to_dict(), "mu_k": self.mu_k.to_dict()}


def friction_coefficients(rec: PassRecord) -> FrictionCoefficients:
    """mu_s,max, mu_s and mu_k of one pass (see the module docstring)."""
    c = rec.cycles
    fn = np.where(c.fn_N > 0, c.fn_N, np.nan)
    mu_max = float(c.peak_N[0] / fn[0]) if rec.has_initial and c.n else math.nan
    st = rec.stable
    return FrictionCoefficients(
        mu_max, Coefficient.of(c.peak_N[st] / fn[st]), Coefficient.of(c.trough_N[st] / fn[st])
    )
