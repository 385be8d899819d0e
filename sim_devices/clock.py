"""The virtual rig's clock: simulated time as a function of the host's monotonic clock.

Three modes:

- real time (``speed=1``): simulated time advances with the host clock;
- accelerated (``speed > 1``): simulated time runs ``speed`` times faster than the host clock;
- manual (``speed=None``): simulated time only moves when a test calls ``VirtualRig.advance_to``, or
  when a pacer advances it (``rigctl.rigs.Pacer``: an accelerated run whose clock waits for the
  recorder); the pacer pins each simulated time it reached to the host instant (:meth:`SimClock.pin`).

Every device timestamp on the host side (camera frames) is taken on ``time.monotonic_ns`` like the
real devices; :meth:`SimClock.host_ns_at` maps a simulated time to the host instant at which the clock
reached it, so camera timestamps and DAQ arrival times stay mutually consistent when accelerated.
"""

from __future__ import annotations

import bisect
import math
import threading
import time

MAX_PINS = 1 << 16
"""Pins kept by a paced manual clock (the oldest half goes when full): minutes of host time."""


class SimClock:
    """Maps host monotonic time to simulated time ``t_s = speed * (host - host0)``."""

    def __init__(self, speed: float | None = 1.0) -> None:
        if speed is not None and (not math.isfinite(speed) or speed <= 0.0):
            raise ValueError(f"clock speed must be a positive finite factor or None, got {speed!r}")
        self.speed = speed
        self._host0_ns = time.monotonic_ns()
        self._pins_t: list[float] = []
        self._pins_ns: list[int] = []
        self._pins_lock = threading.Lock()

    @property
    def manual(self) -> bool:
        """True when simulated time is advanced only by explicit calls."""
        return self.speed is None

    def now_s(self) -> float:
        """Simulated time the clock has reached; 0 forever in manual mode (the rig keeps its own)."""
        if self.speed is None:
            return 0.0
        return self.speed * (time.monotonic_ns() - self._host0_ns) * 1e-9

    def pin(self, t_s: float, host_ns: int | None = None) -> None:
        """Manual mode: simulated time ``t_s`` was reached at host instant ``host_ns`` (default now).

        A pacer calls this after each advance, so :meth:`host_ns_at` follows the rig's actual,
        uneven progress. Pins must move forward; one at or before the last is ignored.
        """
        if self.speed is not None:
            raise RuntimeError("only a manual clock is pinned (a running clock maps time itself)")
        ns = time.monotonic_ns() if host_ns is None else int(host_ns)
        with self._pins_lock:
            if self._pins_t and (t_s <= self._pins_t[-1] or ns < self._pins_ns[-1]):
                return
            self._pins_t.append(float(t_s))
            self._pins_ns.append(ns)
            if len(self._pins_t) > MAX_PINS:
                del self._pins_t[: MAX_PINS // 2]
                del self._pins_ns[: MAX_PINS // 2]

    def host_ns_at(self, t_s: float) -> int:
        """Host monotonic instant (ns) at which the clock reaches simulated time ``t_s``.

        In manual mode simulated time is mapped one to one onto the host clock from the start, unless
        the clock was pinned: then linearly between pins (one to one before the first, the last
        pin's instant after it: the rig reached that time no later).
        """
        if self.speed is None and self._pins_t:
            with self._pins_lock:
                ts, ns = self._pins_t, self._pins_ns
                i = bisect.bisect_right(ts, t_s)
                if i == 0:
                    return ns[0] - round((ts[0] - t_s) * 1e9)
                if i == len(ts):
                    return ns[-1]
                w = (t_s - ts[i - 1]) / (ts[i] - ts[i - 1])
                return ns[i - 1] + round(w * (ns[i] - ns[i - 1]))
        speed = 1.0 if self.speed is None else self.speed
        return self._host0_ns + round(t_s / speed * 1e9)

    def host_delay_s(self, t_s: float) -> float:
        """Host seconds until the clock reaches ``t_s`` (<= 0 if already reached; inf if manual)."""
        if self.speed is None:
            return math.inf
        return (self.host_ns_at(t_s) - time.monotonic_ns()) * 1e-9
