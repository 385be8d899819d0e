"""Interlocks: the process-wide emergency stop and the normal-force guard.

An *interlock* is anything with ``check_command(stage, command)`` that raises to refuse a command.
Every :class:`~drivers.interfaces.LoadingStage` checks its interlocks before it sends ``enable``,
``home`` or a move, and checks them again just after sending: if an interlock tripped in between,
the stage sends an emergency stop straight away, so a trigger racing a command can never leave the
stage moving. ``stop``, ``emergency_stop``, ``disable`` and reads are never refused.

* :class:`EmergencyStop` - every stage registers itself with one (by default the process-wide
  :func:`default_emergency_stop`). ``trigger(reason)`` may be called from any thread; it
  latches, keeps the first reason, and sends ``emergency_stop()`` to every registered stage (a
  stage that fails to answer does not keep the others from being stopped). Motion commands are
  then refused with :class:`~drivers.errors.EmergencyStopActive` until ``reset()``.
* :class:`ForceGuard` - the acquisition layer feeds it normal-force readings; when |Fn| exceeds the
  limit (default 800 N, the rig's maximum load), a reading is saturated (at the force sensor's
  range: it reads "at least this much", so the guard cannot see past it) or a reading is not finite
  (the guard can no longer vouch for the load), it emergency-stops the guarded stage, records a
  :class:`~drivers.errors.ForceLimitError`, and refuses that stage's motion commands until reset.
"""

from __future__ import annotations

import logging
import math
import threading
import time
import weakref
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from drivers.errors import EmergencyStopActive, ForceLimitError, StaleReadingError
from drivers.ratings import RATED_NORMAL_FORCE_N

_log = logging.getLogger(__name__)

DEFAULT_FORCE_LIMIT_N = RATED_NORMAL_FORCE_N
"""The force guard's default limit: the normal stage's rated load (:mod:`drivers.ratings`)."""


class Stoppable(Protocol):
    """What the emergency stop and the stale-reading guard stop: a named stage (any
    :class:`~drivers.interfaces.LoadingStage`). Typing against this, not the stage class, keeps
    this module below the interfaces (they import it; it imports none of them)."""

    @property
    def name(self) -> str: ...

    def stop(self) -> None: ...

    def emergency_stop(self) -> None: ...


class Interlock(Protocol):
    """Something that may refuse a stage command by raising a :class:`DeviceError`."""

    def check_command(self, stage: Stoppable, command: str) -> None:
        """Raise to refuse ``command`` on ``stage``; return to allow it."""
        ...


class GuardedStage(Stoppable, Protocol):
    """What the force guard guards: a stage that also takes interlocks."""

    def add_interlock(self, interlock: Interlock) -> None: ...

    def remove_interlock(self, interlock: Interlock) -> None: ...


@dataclass(frozen=True)
class StopFailure:
    """A stage that could not be told to stop during a trigger, and why."""

    stage_name: str
    error: BaseException


class EmergencyStop:
    """A latched emergency stop over a set of registered stages (thread-safe, idempotent)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._stages: list[weakref.ref[Stoppable]] = []
        self._reason: str | None = None
        self._triggered_monotonic_ns: int | None = None
        self._failures: list[StopFailure] = []

    # registration -------------------------------------------------------------------------------
    def register(self, stage: Stoppable) -> None:
        """Add ``stage`` (held by a weak reference; registering twice is harmless)."""
        with self._lock:
            self._prune()
            if all(ref() is not stage for ref in self._stages):
                self._stages.append(weakref.ref(stage))

    def unregister(self, stage: Stoppable) -> None:
        """Remove ``stage`` (no error if it was not registered)."""
        with self._lock:
            self._stages = [ref for ref in self._stages if ref() not in (None, stage)]

    def stages(self) -> list[Stoppable]:
        """The stages currently registered."""
        with self._lock:
            self._prune()
            return [s for s in (ref() for ref in self._stages) if s is not None]

    def _prune(self) -> None:
        self._stages = [ref for ref in self._stages if ref() is not None]

    # trigger / reset ----------------------------------------------------------------------------
    def trigger(self, reason: str) -> list[StopFailure]:
        """Latch and emergency-stop every registered stage; returns the stages that failed.

        Safe from any thread and idempotent: the first reason is kept, later triggers send the
        stop again (harmless on a stopped stage).
        """
        with self._lock:
            if self._reason is None:
                self._reason = reason
                self._triggered_monotonic_ns = time.monotonic_ns()
                _log.critical("emergency stop: %s", reason)
            self._prune()
            stages = [s for s in (ref() for ref in self._stages) if s is not None]
        failures = _stop_all(stages)
        with self._lock:
            self._failures.extend(failures)
        return failures

    def reset(self) -> None:
        """Unlatch: motion commands are accepted again (stages stay stopped until commanded)."""
        with self._lock:
            if self._reason is not None:
                _log.warning("emergency stop reset (was: %s)", self._reason)
            self._reason = None
            self._triggered_monotonic_ns = None
            self._failures = []

    @property
    def latched(self) -> bool:
        """True from a trigger until reset."""
        return self._reason is not None

    @property
    def reason(self) -> str | None:
        """The reason given to the first trigger since the last reset."""
        return self._reason

    @property
    def triggered_monotonic_ns(self) -> int | None:
        """``time.monotonic_ns()`` of the first trigger since the last reset."""
        return self._triggered_monotonic_ns

    @property
    def failures(self) -> list[StopFailure]:
        """Stages that raised when told to stop since the last reset."""
        with self._lock:
            return list(self._failures)

    def check_command(self, stage: Stoppable, command: str) -> None:
        """Interlock hook: refuse every motion command while latched."""
        reason = self._reason
        if reason is not None:
            raise EmergencyStopActive(stage.name, reason)


def _stop_all(stages: Iterable[Stoppable]) -> list[StopFailure]:
    failures = []
    for stage in stages:
        try:
            stage.emergency_stop()
        except Exception as exc:  # one dead stage must not keep the others moving
            _log.critical("emergency stop of %s failed: %s", stage.name, exc)
            failures.append(StopFailure(stage.name, exc))
    return failures


_DEFAULT = EmergencyStop()


def default_emergency_stop() -> EmergencyStop:
    """The process-wide emergency stop every stage registers with unless given another."""
    return _DEFAULT


SATURATION_RTOL = 1e-9
"""A reading within this relative distance of the sensor's range is at the range (saturated): the
range and the readings are the same count times the same scale, so only rounding separates them."""


class ForceGuard:
    """Emergency-stops a (normal) stage when |Fn| exceeds ``limit_N`` or reaches the force sensor's
    range ``range_N`` (a saturated reading means "at least this much"); refuses its commands after.

    Feed it every block of normal-force readings (``feed(fn_N)``, from any thread). The guard
    attaches itself as an interlock of ``stage``. ``range_N`` is the DAQ's
    :attr:`~drivers.interfaces.Daq.force_range_N` (infinite: a sensor that cannot saturate).
    ``also_trigger`` optionally latches an :class:`EmergencyStop` as well (stopping every stage,
    e.g. the tangential one too).
    """

    def __init__(
        self,
        stage: GuardedStage,
        limit_N: float = DEFAULT_FORCE_LIMIT_N,
        *,
        range_N: float = math.inf,
        also_trigger: EmergencyStop | None = None,
    ) -> None:
        if not (isinstance(limit_N, int | float) and math.isfinite(limit_N) and limit_N > 0):
            raise ValueError(f"force limit must be a finite positive number of N: {limit_N!r}")
        if not (isinstance(range_N, int | float) and range_N > 0) or math.isnan(range_N):
            raise ValueError(f"force sensor range must be a positive number of N: {range_N!r}")
        self._stage = stage
        self._limit_N = float(limit_N)
        self._range_N = float(range_N)
        self._saturated_N = self._range_N * (1.0 - SATURATION_RTOL)
        self._also_trigger = also_trigger
        self._lock = threading.Lock()
        self._trip: ForceLimitError | None = None
        self._release_ceiling_N: float | None = None
        self._release_margin = 0.05
        stage.add_interlock(self)

    @property
    def limit_N(self) -> float:
        """The force limit in newtons (applies to |Fn|)."""
        return self._limit_N

    @property
    def range_N(self) -> float:
        """The force sensor's range [N]: a reading of |Fn| at it is saturated and trips the guard."""
        return self._range_N

    @property
    def trips_above_N(self) -> float:
        """Where the guard trips: the lower of the limit and the sensor's range."""
        return min(self._limit_N, self._range_N)

    @property
    def tripped(self) -> bool:
        """True from a trip until :meth:`reset`."""
        return self._trip is not None

    @property
    def trip(self) -> ForceLimitError | None:
        """The error recorded at the trip (force, limit, stage), if tripped."""
        return self._trip

    def feed(self, fn_N: float | Iterable[float] | np.ndarray) -> ForceLimitError | None:
        """Check normal-force readings [N]; on the first excess stop the stage and return the error.

        Returns None when no new trip happened (also while already tripped). Never raises for an
        excess, so an acquisition loop keeps recording; the error is also kept in :attr:`trip`.
        """
        values = np.asarray(fn_N, dtype=np.float64).ravel()
        if values.size == 0:
            return None
        ceiling = self._release_ceiling_N
        size = np.abs(values)
        if ceiling is None:
            # a saturated reading is at least the range: past it the guard would be blind
            saturated = size >= self._saturated_N
            bad = ~np.isfinite(values) | (size > self._limit_N) | saturated
        else:  # a release starts where the trip was, saturated perhaps: only its ceiling counts
            saturated = np.zeros(values.shape, dtype=bool)
            bad = ~np.isfinite(values) | (size > ceiling)
        if not bad.any():
            if ceiling is not None and bool(
                    np.all(size <= self.trips_above_N * (1.0 - self._release_margin))):
                with self._lock:
                    # released (clearly below the limit, not hovering at it): back to the normal
                    # limit; at the limit itself noise would re-trip and stop the release
                    self._release_ceiling_N = None
            return None
        first = int(np.argmax(bad))
        worst = float(values[first])
        range_N = self._range_N if bool(saturated[first]) and math.isfinite(worst) else None
        with self._lock:
            if self._trip is not None:
                return None
            self._trip = ForceLimitError(self._stage.name, worst, self._limit_N, range_N=range_N)
        _log.critical("%s", self._trip)
        try:
            self._stage.emergency_stop()
        except Exception as exc:  # the guard stays tripped; the trigger below still runs
            _log.critical("force guard could not stop %s: %s", self._stage.name, exc)
        if self._also_trigger is not None:
            self._also_trigger.trigger(str(self._trip))
        return self._trip

    def reset(self) -> None:
        """Accept commands again (the next reading above the limit trips again)."""
        with self._lock:
            self._trip = None
            self._release_ceiling_N = None

    def allow_release(self, margin: float = 0.05) -> None:
        """Accept commands again for a load release after a trip.

        The force is still above the limit (or saturated) when the release starts, so until a block
        of readings is back below ``(1 - margin)`` times :attr:`trips_above_N` the guard trips only
        above ``(1 + margin)`` times
        the larger of the limit and the force that tripped it (the hysteresis keeps a force hovering
        at the limit, with its noise, from re-tripping and stopping the release half-way): a
        release that does not lower the force (wrong direction, a
        jammed stage) is still stopped, a working one is not interrupted by its own starting force.
        """
        if not (math.isfinite(margin) and 0.0 <= margin <= 0.5):
            raise ValueError(f"release margin must be within 0..0.5: {margin!r}")
        with self._lock:
            trip = self._trip
            start_N = abs(trip.force_N) if trip is not None and math.isfinite(trip.force_N) else 0.0
            self._release_ceiling_N = max(self._limit_N, start_N) * (1.0 + margin)
            self._release_margin = margin
            self._trip = None

    @property
    def releasing(self) -> bool:
        """True between :meth:`allow_release` and the first block of readings within the limit."""
        return self._release_ceiling_N is not None

    def check_command(self, stage: Stoppable, command: str) -> None:
        """Interlock hook: refuse motion commands of the guarded stage while tripped."""
        trip = self._trip
        if trip is not None and stage is self._stage:
            raise ForceLimitError(trip.device, trip.force_N, trip.limit_N, range_N=trip.range_N)

    def detach(self) -> None:
        """Stop guarding the stage (removes the interlock)."""
        self._stage.remove_interlock(self)


STALE_WINDOW_S = 0.5
"""A force reading whose three channels stay bit-identical this long (device time) is frozen: a
live strain-gauge sensor flickers by at least one count within milliseconds (the simulated one by
0.05-0.2 N RMS on 0.025 N counts), so half a second without any change is a stuck sensor or DAQ."""


class StaleReadingGuard:
    """Stops the stages when the force reading freezes (docs/reliability.md).

    Feed it every block of raw force channels with their device times (``feed(t_s, channels)``,
    from the acquisition thread). When no channel has changed for ``window_s`` of device time it
    returns the :class:`StaleReadingError` naming the DAQ, and :meth:`halt` stops every stage
    given; it stays tripped (later feeds return None). A frozen
    reading is caught whether the DAQ's counter still advances (a stuck sensor) or not (the same
    block repeated): only the values are judged.
    """

    def __init__(self, stages: Iterable[Stoppable], device: str = "daq",
                 window_s: float = STALE_WINDOW_S) -> None:
        if not (math.isfinite(window_s) and window_s > 0):
            raise ValueError(f"stale-reading window must be a positive number of s: {window_s!r}")
        self._stages = tuple(stages)
        self._device = device
        self._window_s = float(window_s)
        self._last: np.ndarray | None = None
        self._last_change_t: float | None = None
        self._trip: StaleReadingError | None = None

    @property
    def window_s(self) -> float:
        return self._window_s

    @property
    def trip(self) -> StaleReadingError | None:
        return self._trip

    def feed(self, t_s: np.ndarray, channels: Iterable[np.ndarray]) -> StaleReadingError | None:
        """Judge one block; returns the error on the block that trips (then call :meth:`halt`
        before making the fault visible: the safe state that follows the fault releases the load,
        and a later halt would stop that release), else None."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        if t.size == 0 or self._trip is not None:
            return None
        block = np.column_stack([np.asarray(c, dtype=np.float64).ravel() for c in channels])
        prev = block[:1] if self._last is None else self._last[None, :]
        changed = np.any(np.diff(np.vstack([prev, block]), axis=0) != 0.0, axis=1)
        if self._last_change_t is None:
            self._last_change_t = float(t[0])
        if changed.any():
            self._last_change_t = float(t[int(np.flatnonzero(changed)[-1])])
        self._last = block[-1].copy()
        frozen = float(t[-1]) - self._last_change_t
        if frozen < self._window_s:
            return None
        self._trip = StaleReadingError(self._device, frozen, self._last_change_t)
        _log.critical("%s", self._trip)
        return self._trip

    def halt(self) -> None:
        """Stop every stage (a controlled stop, not a latched emergency stop: the load release that
        follows is a position move and needs no force reading); an emergency stop where the stop
        fails. Each stage is tried even if another fails."""
        for stage in self._stages:
            try:
                stage.stop()
            except Exception as exc:
                _log.critical("stale-reading guard could not stop %s: %s", stage.name, exc)
                try:
                    stage.emergency_stop()
                except Exception as exc2:  # one dead stage must not keep the others moving
                    _log.critical("stale-reading guard could not e-stop %s: %s", stage.name, exc2)
