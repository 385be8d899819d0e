"""A fixed-size history of the rig's true state at the sample clock, indexed by absolute sample number.

The virtual rig appends every engine output sample; devices read spans of it by sample index
(``k`` is the sample at ``t = k / rate``). Old samples are overwritten after ``capacity`` samples; a
reader that falls that far behind gets :class:`SamplesLostError` naming what is gone, so a device reports
the loss (a counter gap) instead of inventing data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray


class SamplesLostError(LookupError):
    """Requested samples were overwritten (the reader fell behind by more than the capacity)."""

    def __init__(self, requested: int, first_available: int) -> None:
        self.requested = requested
        self.first_available = first_available
        super().__init__(
            f"samples from {requested} were overwritten; the oldest kept is {first_available}"
        )


@dataclass(frozen=True)
class RigSamples:
    """True rig state for samples ``k0 .. k0 + n - 1`` (SI units)."""

    k0: int
    t_s: NDArray[np.float64]
    x_stage_m: NDArray[np.float64]
    """Absolute tangential stage position."""
    z_normal_m: NDArray[np.float64]
    fn_N: NDArray[np.float64]
    ft_N: NDArray[np.float64]
    d1_m: NDArray[np.float64]
    d2_m: NDArray[np.float64]
    stage: NDArray[np.uint8]
    slipping: NDArray[np.bool_]
    sliding_elements: NDArray[np.bool_]
    """(n, N) elements sliding at each sample."""

    def __len__(self) -> int:
        return int(self.t_s.shape[0])


_SCALARS = ("t_s", "x_stage_m", "z_normal_m", "fn_N", "ft_N", "d1_m", "d2_m")


class SampleRing:
    """Ring buffer of :class:`RigSamples` columns (not thread-safe: the rig's lock guards it)."""

    def __init__(self, capacity: int, n_elements: int) -> None:
        if capacity < 16 or n_elements < 1:
            raise ValueError("ring capacity must be >= 16 samples and N >= 1")
        self.capacity = capacity
        self._cols = {name: np.zeros(capacity) for name in _SCALARS}
        self._stage = np.zeros(capacity, dtype=np.uint8)
        self._slipping = np.zeros(capacity, dtype=bool)
        self._sliding = np.zeros((capacity, n_elements), dtype=bool)
        self.next_k = 0  # one past the newest sample

    @property
    def first_k(self) -> int:
        """Oldest sample still held."""
        return max(0, self.next_k - self.capacity)

    def append(self, k0: int, columns: dict[str, NDArray[np.float64]], stage: NDArray[np.uint8],
               slipping: NDArray[np.bool_], sliding: NDArray[np.bool_]) -> None:
        """Store samples k0.. (k0 must be ``next_k``: the history has no holes)."""
        n = stage.shape[0]
        if k0 != self.next_k:
            raise ValueError(f"samples must be appended in order: got {k0}, expected {self.next_k}")
        if n == 0:
            return
        if n > self.capacity:  # only the newest `capacity` samples can be kept
            cut = n - self.capacity
            k0, n = k0 + cut, self.capacity
            columns = {k: v[cut:] for k, v in columns.items()}
            stage, slipping, sliding = stage[cut:], slipping[cut:], sliding[cut:]
        idx = np.arange(k0, k0 + n) % self.capacity
        for name in _SCALARS:
            self._cols[name][idx] = columns[name]
        self._stage[idx] = stage
        self._slipping[idx] = slipping
        self._sliding[idx] = sliding
        self.next_k = k0 + n

    def read(self, k0: int, k1: int) -> RigSamples:
        """Samples k0 <= k < k1 (clamped to what exists; SamplesLostError if k0 was overwritten)."""
        if k0 < self.first_k:
            raise SamplesLostError(k0, self.first_k)
        k1 = min(k1, self.next_k)
        k0 = min(k0, k1)
        idx = np.arange(k0, k1) % self.capacity
        c = self._cols
        return RigSamples(
            k0=k0,
            t_s=c["t_s"][idx],
            x_stage_m=c["x_stage_m"][idx],
            z_normal_m=c["z_normal_m"][idx],
            fn_N=c["fn_N"][idx],
            ft_N=c["ft_N"][idx],
            d1_m=c["d1_m"][idx],
            d2_m=c["d2_m"][idx],
            stage=self._stage[idx],
            slipping=self._slipping[idx],
            sliding_elements=self._sliding[idx],
        )
