"""Outputs of a simulation at the sensor sample rate, and the list of global slip events."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigctl.data import MeasuredRun


@dataclass(frozen=True)
class SlipEvent:
    """One global slip: the whole interface slides until the specimen stops (docs/model.md)."""

    t_start_s: float
    t_end_s: float
    peak_N: float
    """Drive (sensor-path) force when the slip starts."""
    trough_N: float
    """Lowest drive force during the slip (highest for a backward slip)."""
    slip_m: float
    """Specimen displacement during the slip."""
    stage: str
    """'initial' for the slip that ends the initial stage, else 'stable'."""
    fn_N: float

    @property
    def drop_N(self) -> float:
        return self.peak_N - self.trough_N


@dataclass
class SimResult:
    """Per-sample outputs (SI units). ``ft_N`` is what the force sensor in the drive path reads."""

    t_s: np.ndarray
    x_stage_m: np.ndarray
    fn_N: np.ndarray
    ft_N: np.ndarray
    f_interface_N: np.ndarray
    x_specimen_m: np.ndarray
    v_specimen_m_s: np.ndarray
    delta_m: np.ndarray
    d1_m: np.ndarray
    d2_m: np.ndarray
    stage: np.ndarray
    """0 initial, 1 stable (uint8)."""
    slipping: np.ndarray
    """True where a global slip ran since the previous sample (the slip phase)."""
    element_mode: np.ndarray
    """(n, N) int8: 0 stuck, +1/-1 sliding forward/backward (all sliding during a global slip)."""
    p_tables: np.ndarray
    """(2, N): the normal-load shares P of each element in the initial (0) and stable (1) stage."""
    events: list[SlipEvent] = field(default_factory=list)
    metadata: dict[str, str] = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def p_elements(self) -> np.ndarray:
        """(n, N) equivalent stress distribution P(x, t) per element, element 0 = back end."""
        return self.p_tables[self.stage.astype(np.intp)]

    @property
    def sliding_elements(self) -> np.ndarray:
        """(n, N) bool: element sliding (presliding or in a global slip)."""
        return self.element_mode != 0

    def slice(self, start: int, stop: int) -> SimResult:
        """Samples [start, stop) with the events that start inside that span."""
        t0 = self.t_s[start] if stop > start else np.inf
        t1 = self.t_s[stop - 1] if stop > start else -np.inf
        arrays = {n: getattr(self, n)[start:stop] for n in _ARRAYS}
        return SimResult(
            **arrays,
            p_tables=self.p_tables,
            events=[e for e in self.events if t0 <= e.t_start_s <= t1],
            metadata=dict(self.metadata),
        )

    def to_measured(self) -> MeasuredRun:
        """The run as the rig would record it (exchange-format columns plus model extras)."""
        return MeasuredRun(
            t_s=self.t_s.copy(),
            x_stage_m=self.x_stage_m.copy(),
            fn_N=self.fn_N.copy(),
            ft_N=self.ft_N.copy(),
            d1_m=self.d1_m.copy(),
            d2_m=self.d2_m.copy(),
            extra={},
            metadata=dict(self.metadata),
            source=self.metadata.get("source", "simulation"),
        )


_ARRAYS = (  # the per-sample arrays of a SimResult, in the order of docs/model.md section 5
    "t_s", "x_stage_m", "fn_N", "ft_N", "f_interface_N", "x_specimen_m", "v_specimen_m_s",
    "delta_m", "d1_m", "d2_m", "stage", "slipping", "element_mode",
)


def concatenate(parts: list[SimResult]) -> SimResult:
    """Join consecutive results (e.g. the chunks of a stepper)."""
    if not parts:
        raise ValueError("nothing to concatenate")
    first = parts[0]
    arrays = {n: np.concatenate([getattr(p, n) for p in parts]) for n in _ARRAYS}
    return SimResult(
        **arrays,
        p_tables=first.p_tables,
        events=[e for p in parts for e in p.events],
        metadata=dict(first.metadata),
    )
