"""The virtual rig's clock: simulated time as a function of the host's monotonic clock.

Three modes:

- real time (``speed=1``): simulated time advances with the host clock;
- accelerated (``speed > 1``): simulated time runs ``speed`` times faster than the host clock;
- manual (``speed=None``): simulated time only moves when a test calls ``VirtualRig.advance_to``.

Every device timestamp on the host side (camera frames) is taken on ``time.monotonic_ns`` like the
real devices; :meth:`SimClock.host_ns_at` maps a simulated time to the host instant at which the clock
reached it, so camera timestamps and DAQ arrival times stay mutually consistent when accelerated.
"""

from __future__ import annotations

import math
import time


class SimClock:
    """Maps host monotonic time to simulated time ``t_s = speed * (host - host0)``."""

    def __init__(self, speed: float | None = 1.0) -> None:
        if speed is not None and (not math.isfinite(speed) or speed <= 0.0):
            raise ValueError(f"clock speed must be a positive finite factor or None, got {speed!r}")
        self.speed = speed
        self._host0_ns = time.monotonic_ns()

    @property
    def manual(self) -> bool:
        """True when simulated time is advanced only by explicit calls."""
        return self.speed is None

    def now_s(self) -> float:
        """Simulated time the clock has reached; 0 forever in manual mode (the rig keeps its own)."""
        if self.speed is None:
            return 0.0
        return self.speed * (time.monotonic_ns() - self._host0_ns) * 1e-9

    def host_ns_at(self, t_s: float) -> int:
        """Host monotonic instant (ns) at which the clock reaches simulated time ``t_s``.

        In manual mode simulated time is mapped one to one onto the host clock from the start.
        """
        speed = 1.0 if self.speed is None else self.speed
        return self._host0_ns + round(t_s / speed * 1e9)

    def host_delay_s(self, t_s: float) -> float:
        """Host seconds until the clock reaches ``t_s`` (<= 0 if already reached; inf if manual)."""
        if self.speed is None:
            return math.inf
        return (self.host_ns_at(t_s) - time.monotonic_ns()) * 1e-9
