"""Fault injection, one :class:`Faults` object per simulated device, settable while it runs.

Like python-microscope's ``_error_percent``, but each kind of failure a real rig shows has its own
switch, and every simulator documents which apply to it:

=================  =========================================================================
field              effect
=================  =========================================================================
``silent``         the device stops answering (no replies, no data, no frames)
``corrupt_pct``    percentage of replies / frames / lines corrupted on the wire
``short_pct``      percentage of replies / frames / lines cut short
``drop_pct``       percentage of CAN data frames or camera frames lost
``stuck``          readings freeze at their value when the fault was set (sample clocks run on)
``blind``          the force sensor reads no load: its noise about zero, whatever the contact
                   carries (a broken bridge or cable; the sample clock and the analog channels
                   run on)
``alarm_code``     a stage controller alarm to raise (consumed when the device latches it)
=================  =========================================================================

Probabilistic faults draw from a seeded generator, so a test run is reproducible. Field writes are
single attribute assignments (atomic in CPython), so any thread may set them at run time.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Generic, TypeVar

import numpy as np

T = TypeVar("T")


def _check_pct(name: str, value: float) -> None:
    if not 0.0 <= value <= 100.0:
        raise ValueError(f"{name} must be a percentage in [0, 100], got {value!r}")


@dataclass
class Faults:
    """Switches for one simulated device (module docstring)."""

    silent: bool = False
    corrupt_pct: float = 0.0
    short_pct: float = 0.0
    drop_pct: float = 0.0
    stuck: bool = False
    blind: bool = False
    alarm_code: int = 0
    seed: int = 0
    _rng: np.random.Generator = field(init=False, repr=False)
    _lock: threading.Lock = field(init=False, repr=False, default_factory=threading.Lock)

    def __post_init__(self) -> None:
        self._rng = np.random.default_rng(self.seed)
        for name in ("corrupt_pct", "short_pct", "drop_pct"):
            _check_pct(name, getattr(self, name))

    def __setattr__(self, name: str, value: object) -> None:
        if name in ("corrupt_pct", "short_pct", "drop_pct"):
            _check_pct(name, float(value))  # type: ignore[arg-type]
        if name == "alarm_code" and not (isinstance(value, int) and 0 <= value <= 0xFFFF):
            raise ValueError(f"alarm_code must be a 16-bit code, got {value!r}")
        object.__setattr__(self, name, value)

    def roll(self, pct: float) -> bool:
        """True with probability ``pct`` percent."""
        if pct <= 0.0:
            return False
        with self._lock:
            return bool(self._rng.random() * 100.0 < pct)

    def take_alarm(self) -> int:
        """The pending alarm code (0 if none), cleared so it is latched once."""
        with self._lock:
            code = self.alarm_code
            object.__setattr__(self, "alarm_code", 0)
        return code

    def random_bytes(self, n: int) -> bytes:
        with self._lock:
            return self._rng.integers(0, 256, n, dtype=np.uint8).tobytes()

    def clear(self) -> None:
        """All faults off."""
        self.silent = False
        self.corrupt_pct = self.short_pct = self.drop_pct = 0.0
        self.stuck = False
        self.alarm_code = 0


class StuckReading(Generic[T]):
    """The ``stuck`` fault of one reading, shared by the wire and in-process simulators.

    Every reading passes through :meth:`hold` (or :meth:`hold_array`): while ``faults.stuck`` is on,
    the reading seen when it came on is returned again; once it is off, readings pass unchanged.
    """

    def __init__(self, faults: Faults) -> None:
        self.faults = faults
        self._held: T | None = None

    def hold(self, reading: T) -> T:
        """``reading``, or the one held since the fault came on."""
        if not self.faults.stuck:
            self._held = None
            return reading
        if self._held is None:
            self._held = reading
        return self._held

    def hold_array(self, values: np.ndarray) -> np.ndarray:
        """A block of readings: all equal to the held one while stuck (its first value then)."""
        if not self.faults.stuck:
            self._held = None
            return values
        if self._held is None:
            self._held = float(values[0])  # type: ignore[assignment]
        return np.full_like(values, self._held)
