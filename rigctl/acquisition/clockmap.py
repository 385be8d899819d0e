"""Map host monotonic time to the DAQ's device time (the run's time axis).

The DAQ's sample counter is the run's clock (docs/protocols.md): sample times are ``n / rate``. Host
events (a camera frame's capture instant, a step marker) are placed on that axis through pairs
(host instant a block arrived, device time of its last sample), fitted by least squares over a
sliding window: ``t_device = a + b * t_host``. The slope is 1 on the real rig (up to clock drift) and
the speed factor on an accelerated simulated rig. Arrival latency biases the intercept by the
transport delay (milliseconds), which is recorded, not hidden: the raw pairs are in the run file's
``daq/blocks`` table, so analysis can re-fit them.
"""

from __future__ import annotations

import threading
from collections import deque

import numpy as np


class ClockMap:
    """Sliding-window linear fit of device time against host time (thread-safe)."""

    def __init__(self, window: int = 64) -> None:
        self._pairs: deque[tuple[float, float]] = deque(maxlen=window)
        self._lock = threading.Lock()
        self._fit: tuple[float, float] | None = None

    def add(self, host_ns: int, t_device_s: float) -> None:
        with self._lock:
            self._pairs.append((host_ns * 1e-9, float(t_device_s)))
            self._fit = None

    @property
    def ready(self) -> bool:
        with self._lock:
            return len(self._pairs) >= 1

    def device_time(self, host_ns: int) -> float:
        """Device time [s] of a host instant; NaN before the first pair."""
        with self._lock:
            if not self._pairs:
                return float("nan")
            if self._fit is None:
                self._fit = self._solve()
            a, b = self._fit
        return a + b * host_ns * 1e-9

    def _solve(self) -> tuple[float, float]:
        h = np.array([p[0] for p in self._pairs])
        t = np.array([p[1] for p in self._pairs])
        if h.size < 2 or np.ptp(h) < 0.05:
            # too little spread for a slope: unit slope through the latest pair
            return float(t[-1] - h[-1]), 1.0
        h0 = h.mean()
        b = float(np.dot(h - h0, t - t.mean()) / np.dot(h - h0, h - h0))
        return float(t.mean() - b * h0), b
