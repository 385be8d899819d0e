"""Loading stages: their limits (the one check of a move), status and the abstract stage."""

from __future__ import annotations

import logging
import threading
import time
from abc import abstractmethod
from collections.abc import Callable
from dataclasses import dataclass

from drivers.errors import (
    DeviceStateError,
    LimitError,
    MotionTimeout,
    SettingError,
    StageAlarm,
    stage_alarm_name,
)
from drivers.interfaces.common import Device
from drivers.safety import EmergencyStop, Interlock, default_emergency_stop
from drivers.validate import check_argument, check_number, check_timeout

_log = logging.getLogger(__name__)


@dataclass(frozen=True)
class StageLimits:
    """Allowed travel and speed of one stage, in metres and metres per second.

    The one description of an axis's limits, and the one place a move is checked against them:
    :meth:`LoadingStage.move_absolute` calls :meth:`check_move` before anything is sent, and the
    dry run of a protocol calls the same methods before anything moves, so the two refuse the
    same moves with the same message::

        limits = StageLimits(min_position_m=0.0, max_position_m=0.2, max_velocity_m_s=5e-3)
        limits.check_move("tangential", 0.25, 1e-5)   # LimitError: target_m = 0.25 refused: ...
    """

    min_position_m: float
    max_position_m: float
    max_velocity_m_s: float

    def __post_init__(self) -> None:
        for key in ("min_position_m", "max_position_m", "max_velocity_m_s"):
            check_number("StageLimits", key, getattr(self, key))
        if not self.min_position_m < self.max_position_m:
            raise SettingError(
                "StageLimits", "max_position_m", self.max_position_m,
                f"must be above min_position_m ({self.min_position_m:g} m), "
                f"got {self.max_position_m:g} m",
            )
        check_number("StageLimits", "max_velocity_m_s", self.max_velocity_m_s, gt=0.0)

    def check_target(self, device: str, target_m: object) -> float:
        """``target_m`` as a float if it is a finite position within the travel, else an error."""
        target = check_argument(device, "target_m", target_m)
        low, high = self.min_position_m, self.max_position_m
        stroke = f"outside the stroke [{low:g}, {high:g}] m"
        if target > high:
            raise LimitError(device, "target_m", target, high, "m",
                             reason=f"target {target:.6g} m is above the maximum {high:.6g} m, {stroke}")
        if target < low:
            raise LimitError(device, "target_m", target, low, "m",
                             reason=f"target {target:.6g} m is below the minimum {low:.6g} m, {stroke}")
        return target

    def check_velocity(self, device: str, velocity_m_s: object, quantity: str = "velocity_m_s") -> float:
        """``velocity_m_s`` as a float if it is finite, > 0 and within the speed limit, else an error."""
        velocity = check_argument(device, quantity, velocity_m_s, gt=0.0)
        high = self.max_velocity_m_s
        if velocity > high:
            raise LimitError(device, quantity, velocity, high, "m/s",
                             reason=f"velocity {velocity:.6g} m/s exceeds the limit {high:.6g} m/s")
        return velocity

    def check_move(self, device: str, target_m: object, velocity_m_s: object) -> tuple[float, float]:
        """The checked ``(target_m, velocity_m_s)`` of a move, or the error refusing it."""
        return self.check_target(device, target_m), self.check_velocity(device, velocity_m_s)


@dataclass(frozen=True)
class StageStatus:
    """Decoded status of a stage controller (bits and alarm code of docs/protocols.md)."""

    enabled: bool
    in_position: bool
    homed: bool
    moving: bool
    fault: bool
    limit: bool
    alarm_code: int = 0

    @property
    def alarm_name(self) -> str:
        """Name of :attr:`alarm_code` ("none" when 0)."""
        return stage_alarm_name(self.alarm_code)


MOTION_COMMANDS = ("enable", "home", "move")
"""Commands that interlocks may refuse. stop, emergency_stop, disable and reads never are."""


class LoadingStage(Device):
    """A linear stage (the normal and the tangential loading stage alike).

    Moves are non-blocking: ``move_absolute`` returns once the controller accepted the command; use
    :meth:`wait_for_motion` to wait. Each stage registers with an :class:`EmergencyStop` (the
    process-wide one unless given another) and refuses motion while it or any added interlock
    (e.g. a :class:`~drivers.safety.ForceGuard`) objects. Usage (any stage, real or simulated)::

        with ModbusStage(config) as stage:
            stage.enable()
            stage.move_absolute(0.010, 10e-6)      # to 10 mm at 10 um/s; beyond a limit: LimitError
            stage.wait_for_motion(timeout_s=1200.0)
            x_m = stage.position_m()
    """

    def __init__(
        self,
        name: str,
        limits: StageLimits,
        *,
        emergency_stop: EmergencyStop | None = None,
    ) -> None:
        super().__init__(name)
        if not isinstance(limits, StageLimits):
            raise TypeError(f"{name}: limits must be a StageLimits, got {type(limits).__name__}")
        self._limits = limits
        self._emergency_stop = emergency_stop if emergency_stop is not None else default_emergency_stop()
        self._interlocks: list[Interlock] = [self._emergency_stop]
        self._interlock_lock = threading.Lock()
        self._emergency_stop.register(self)

    @property
    def limits(self) -> StageLimits:
        """Travel and speed limits enforced before anything is sent."""
        return self._limits

    @property
    def emergency_stop_registry(self) -> EmergencyStop:
        """The emergency stop this stage is registered with."""
        return self._emergency_stop

    # interlocks ---------------------------------------------------------------------------------
    def add_interlock(self, interlock: Interlock) -> None:
        """Add an interlock checked before (and re-checked after) each motion command."""
        with self._interlock_lock:
            if interlock not in self._interlocks:
                self._interlocks.append(interlock)

    def remove_interlock(self, interlock: Interlock) -> None:
        """Remove an interlock added with :meth:`add_interlock`."""
        with self._interlock_lock:
            if interlock in self._interlocks and interlock is not self._emergency_stop:
                self._interlocks.remove(interlock)

    def check_interlocks(self, command: str) -> None:
        """Raise the first interlock's refusal of ``command``; return if all allow it."""
        with self._interlock_lock:
            interlocks = list(self._interlocks)
        for interlock in interlocks:
            interlock.check_command(self, command)

    def _guarded(self, command: str, send: Callable[[], None]) -> None:
        """Check interlocks, send, re-check: a trip racing the send gets an immediate e-stop."""
        self._check_open()
        self.check_interlocks(command)
        send()
        try:
            self.check_interlocks(command)
        except Exception:
            try:
                self._do_emergency_stop()
            except Exception as stop_error:  # keep the interlock's refusal as the error raised
                _log.critical("%s: emergency stop after a racing trip failed: %s", self.name, stop_error)
            raise

    # validation ---------------------------------------------------------------------------------
    def check_move(self, target_m: float, velocity_m_s: float) -> tuple[float, float]:
        """Validate a move without sending it; returns the checked (target, velocity).

        The limits part is :meth:`StageLimits.check_move`, the same check the dry run makes.
        """
        return self._limits.check_move(self.name, target_m, velocity_m_s)

    def _check_ready(self) -> None:
        status = self._do_status()
        if status.fault:
            raise StageAlarm(self.name, status.alarm_code)
        if not status.enabled:
            raise DeviceStateError(self.name, "not enabled: call enable() first")

    # public commands ----------------------------------------------------------------------------
    def enable(self) -> None:
        """Energise the drive."""
        self._guarded("enable", self._do_enable)

    def disable(self) -> None:
        """De-energise the drive (never refused)."""
        self._check_open()
        self._do_disable()

    def home(self) -> None:
        """Start the homing sequence (non-blocking)."""

        def send() -> None:
            self._check_ready()
            self._do_home()

        self._guarded("home", send)

    def move_absolute(self, target_m: float, velocity_m_s: float) -> None:
        """Start a move to ``target_m`` at ``velocity_m_s`` (> 0); beyond a limit: LimitError."""
        target, velocity = self.check_move(target_m, velocity_m_s)

        def send() -> None:
            self._check_ready()
            self._do_move_absolute(target, velocity)

        self._guarded("move", send)

    def move_relative(self, delta_m: float, velocity_m_s: float) -> None:
        """Start a move by ``delta_m`` from the current position (checked like an absolute move)."""
        delta = check_argument(self.name, "delta_m", delta_m)
        self.move_absolute(self.position_m() + delta, velocity_m_s)

    def stop(self) -> None:
        """Decelerate to a stop (never refused)."""
        self._check_open()
        self._do_stop()

    def emergency_stop(self) -> None:
        """Stop immediately (never refused, callable from any thread)."""
        self._do_emergency_stop()

    def reset_alarm(self) -> None:
        """Clear a controller alarm (the cause must be gone, or it comes back)."""
        self._check_open()
        self._do_reset_alarm()

    def position_m(self) -> float:
        """Actual position in metres."""
        self._check_open()
        return self._do_position_m()

    def status(self) -> StageStatus:
        """Decoded controller status (an alarm shows as ``fault`` with its code; not raised)."""
        self._check_open()
        return self._do_status()

    def wait_for_motion(self, timeout_s: float, poll_interval_s: float = 0.02) -> StageStatus:
        """Poll until the stage stops; StageAlarm on a fault, MotionTimeout past ``timeout_s``."""
        limit_s = check_timeout(self.name, timeout_s)
        poll_s = max(check_timeout(self.name, poll_interval_s, "poll_interval_s"), 1e-4)
        deadline = time.monotonic() + limit_s
        while True:
            status = self.status()
            if status.fault:
                raise StageAlarm(self.name, status.alarm_code)
            if not status.moving:
                return status
            if time.monotonic() >= deadline:
                raise MotionTimeout(self.name, limit_s)
            time.sleep(poll_s)

    def _do_close(self) -> None:
        self._emergency_stop.unregister(self)
        self._do_close_transport()

    # hooks --------------------------------------------------------------------------------------
    @abstractmethod
    def _do_enable(self) -> None: ...

    @abstractmethod
    def _do_disable(self) -> None: ...

    @abstractmethod
    def _do_home(self) -> None: ...

    @abstractmethod
    def _do_move_absolute(self, target_m: float, velocity_m_s: float) -> None:
        """Send a move; arguments are already checked against the limits."""

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_emergency_stop(self) -> None:
        """Must work from any thread and while another command is in flight."""

    @abstractmethod
    def _do_reset_alarm(self) -> None: ...

    @abstractmethod
    def _do_position_m(self) -> float: ...

    @abstractmethod
    def _do_status(self) -> StageStatus: ...

    def _do_close_transport(self) -> None:
        """Hook: close the connection. Default: nothing to close."""
