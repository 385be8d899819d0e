"""Where a streaming device is in the rig's history: sample n is at ``t0 + n / rate``.

Shared by every streaming simulator (CAN DAQ, probes; wire-level and in-process), so they all
produce a sample exactly when the rig's simulated time reaches it, resample the rig's history
linearly onto their own rate, and skip (never invent) samples that fell out of the history.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sim_devices.sample_ring import RigSamples, SamplesLostError
from sim_devices.virtual_rig import VirtualRig


class StreamCursor:
    """Sample clock of one device stream started at the rig's next sample."""

    def __init__(self, rig: VirtualRig, rate_hz: float) -> None:
        if not 0 < rate_hz <= rig.rate_hz:
            raise ValueError(f"stream rate must be in (0, {rig.rate_hz:g}] Hz, got {rate_hz!r}")
        self.rig = rig
        self.rate_hz = float(rate_hz)
        self.t0_s = (rig.k + 1) / rig.rate_hz
        self.n_next = 0

    def t_of(self, n: int) -> float:
        return self.t0_s + n / self.rate_hz

    def wait_next(self, timeout_s: float) -> bool:
        """Block until the rig reaches the next sample (False on timeout)."""
        return self.rig.wait_until(self.t_of(self.n_next), timeout_s)

    def due(self, max_samples: int) -> tuple[int, NDArray[np.float64]]:
        """(n0, times) of the samples the rig has reached, at most ``max_samples`` (not consumed)."""
        n_avail = math.floor((self.rig.t_s - self.t0_s) * self.rate_hz + 1e-9) + 1 - self.n_next
        n = min(max(n_avail, 0), max_samples)
        n0 = self.n_next
        return n0, self.t0_s + (n0 + np.arange(n)) / self.rate_hz

    def window(self, t_s: NDArray[np.float64]) -> RigSamples:
        """Rig samples bracketing ``t_s`` (SamplesLostError if they left the history)."""
        r = self.rig.rate_hz
        return self.rig.samples(
            math.floor(float(t_s[0]) * r + 1e-9), math.ceil(float(t_s[-1]) * r - 1e-9) + 1
        )

    def consume(self, n: int) -> None:
        self.n_next += n

    def skip_lost(self, lost: SamplesLostError) -> int:
        """Jump past samples that left the rig's history; returns how many were skipped."""
        first = math.ceil((lost.first_available / self.rig.rate_hz - self.t0_s) * self.rate_hz)
        new_next = max(self.n_next, first + 1)
        skipped = new_next - self.n_next
        self.n_next = new_next
        return skipped


def interp(t_s: NDArray[np.float64], s: RigSamples, column: NDArray[np.float64]) -> NDArray[
    np.float64
]:
    """A rig column resampled linearly at ``t_s``."""
    return np.interp(t_s, s.t_s, column)
