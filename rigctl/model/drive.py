"""Input histories of a simulation: stage position x_stage(t) and normal force Fn(t).

Both are piecewise linear through knots (t_s, x_stage_m, fn_N). Constant drives and segment lists
(duration_s, velocity_m_s; 0 = hold) become a few knots; a measured run gives one knot per sample.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from drivers.ratings import RATED_NORMAL_FORCE_N
from rigctl.model.params import ParameterError

MAX_NORMAL_FORCE_N = RATED_NORMAL_FORCE_N
"""This rig's normal stage maximum load (paper Sec. 2.1; written once, in :mod:`drivers.ratings`).
It bounds commands to this rig (the simulated rig, ``rigctl simulate``), never a model of measured
data: a record from another rig (a 20 MPa rock biax, a 0.3 N spring-slider) is simulated at its
own scale."""


def _finite(name: str, value: float) -> float:
    v = float(value)
    if not np.isfinite(v):
        raise ParameterError(f"{name} must be finite, got {value!r}")
    return v


def check_fn(fn_N: float) -> float:
    """A model's normal force: finite and not negative (no rig limit: see MAX_NORMAL_FORCE_N)."""
    v = _finite("fn_N", fn_N)
    if v < 0.0:
        raise ParameterError(f"normal force {v:g} N is negative")
    return v


@dataclass(frozen=True)
class Drive:
    """Piecewise-linear input histories."""

    t_s: np.ndarray
    x_stage_m: np.ndarray
    fn_N: np.ndarray

    def __post_init__(self) -> None:
        t = np.ascontiguousarray(self.t_s, dtype=np.float64)
        x = np.ascontiguousarray(self.x_stage_m, dtype=np.float64)
        f = np.ascontiguousarray(self.fn_N, dtype=np.float64)
        if t.ndim != 1 or t.size < 2 or x.shape != t.shape or f.shape != t.shape:
            raise ParameterError("a drive needs at least two knots with matching t, x and Fn")
        for name, arr in (("t_s", t), ("x_stage_m", x), ("fn_N", f)):
            if not np.all(np.isfinite(arr)):
                raise ParameterError(f"drive {name} contains NaN or infinite values")
        if np.any(np.diff(t) <= 0.0):
            raise ParameterError("drive times must be strictly increasing")
        if np.any(f < 0.0):
            raise ParameterError(f"drive normal force is negative (min {f.min():g} N)")
        object.__setattr__(self, "t_s", t)
        object.__setattr__(self, "x_stage_m", x)
        object.__setattr__(self, "fn_N", f)

    @property
    def duration_s(self) -> float:
        return float(self.t_s[-1] - self.t_s[0])

    @classmethod
    def constant(cls, fn_N: float, velocity_m_s: float, duration_s: float) -> Drive:
        """Constant normal force and stage velocity from t = 0 (the paper's TLRE drive)."""
        return cls.segments(fn_N, [(duration_s, velocity_m_s)])

    @classmethod
    def segments(
        cls, fn_N: float, segments: Sequence[tuple[float, float]], x0_m: float = 0.0
    ) -> Drive:
        """Consecutive (duration_s, velocity_m_s) segments at constant Fn; velocity 0 holds."""
        fn = check_fn(fn_N)
        if not segments:
            raise ParameterError("at least one segment is needed")
        t = [0.0]
        x = [float(x0_m)]
        for i, (dur, vel) in enumerate(segments):
            d = _finite(f"segment {i + 1} duration", dur)
            v = _finite(f"segment {i + 1} velocity", vel)
            if d <= 0.0:
                raise ParameterError(f"segment {i + 1}: duration must be positive, got {d:g} s")
            t.append(t[-1] + d)
            x.append(x[-1] + v * d)
        return cls(np.array(t), np.array(x), np.full(len(t), fn))

    @classmethod
    def from_samples(cls, t_s: np.ndarray, x_stage_m: np.ndarray, fn_N: np.ndarray) -> Drive:
        """Measured (or any) histories, re-based to start at t = 0; Fn below 0 is treated as 0."""
        t = np.asarray(t_s, dtype=np.float64)
        return cls(t - t[0], np.asarray(x_stage_m, dtype=np.float64),
                   np.clip(np.asarray(fn_N, dtype=np.float64), 0.0, None))
