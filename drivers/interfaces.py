"""Abstract device interfaces: one class per device kind, python-microscope style.

Each public method validates its arguments (finite numbers, limits, interlocks) and then calls a
protected ``_do_...`` hook that a concrete driver (``drivers/``) or simulator
(``sim_devices/``) implements. Validation therefore happens once, here, before anything reaches
a wire: a command beyond a limit raises :class:`~drivers.errors.LimitError` and is never clipped.

Units are SI and in the names (``target_m``, ``velocity_m_s``, ``rate_hz``, ``fx_N``, ``ain_V``).
Host timestamps are ``time.monotonic_ns()`` everywhere (DAQ blocks, probe samples, camera
frames), so streams can be aligned at analysis time.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from types import TracebackType
from typing import Literal, NamedTuple, TypeVar

import numpy as np
from numpy.typing import NDArray

from drivers.errors import (
    DeviceStateError,
    DeviceTimeout,
    InvalidValueError,
    LimitError,
    MotionTimeout,
    NotSupportedError,
    SettingError,
    StageAlarm,
    stage_alarm_name,
)
from drivers.safety import EmergencyStop, Interlock, default_emergency_stop

_log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
T = TypeVar("T")


def finite(device: str, quantity: str, value: object) -> float:
    """``value`` as a float if it is a finite real number, else :class:`InvalidValueError`."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise InvalidValueError(device, quantity, value, "not a real number")
    number = float(value)
    if not math.isfinite(number):
        raise InvalidValueError(device, quantity, value, "not finite")
    return number


def positive_int(device: str, quantity: str, value: object) -> int:
    """``value`` as an int if it is an integer >= 1, else :class:`InvalidValueError`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidValueError(device, quantity, value, "must be an integer >= 1")
    return int(value)


def timeout(device: str, value: object) -> float:
    """A wait in seconds: finite and >= 0."""
    seconds = finite(device, "timeout_s", value)
    if seconds < 0:
        raise InvalidValueError(device, "timeout_s", value, "must be >= 0")
    return seconds


class Device(ABC):  # noqa: B024 - an ABC for shared naming/closing; abstract hooks live below
    """Shared by every device: a name (used in every error) and idempotent ``close()``."""

    def __init__(self, name: str) -> None:
        if not isinstance(name, str) or not name.strip():
            raise ValueError(f"a device needs a non-empty name, got {name!r}")
        self._name = name
        self._closed = False

    @property
    def name(self) -> str:
        """The device name used in errors and logs (e.g. ``"normal_stage"``)."""
        return self._name

    @property
    def closed(self) -> bool:
        """True after :meth:`close`."""
        return self._closed

    def close(self) -> None:
        """Release the connection; a second call does nothing."""
        if not self._closed:
            self._closed = True
            self._do_close()

    def _do_close(self) -> None:  # noqa: B027 - optional hook
        """Hook: release the transport. Default: nothing to release."""

    def _check_open(self) -> None:
        if self._closed:
            raise DeviceStateError(self._name, "closed")

    def __enter__(self: T) -> T:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


# --------------------------------------------------------------------------------------------------
# Loading stages
# --------------------------------------------------------------------------------------------------


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
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise SettingError("StageLimits", key, value, "must be a number")
            if not math.isfinite(value):
                raise SettingError("StageLimits", key, value, "must be finite")
        if not self.min_position_m < self.max_position_m:
            raise SettingError(
                "StageLimits", "max_position_m", self.max_position_m,
                f"must be above min_position_m ({self.min_position_m:g} m), "
                f"got {self.max_position_m:g} m",
            )
        if not self.max_velocity_m_s > 0:
            raise SettingError("StageLimits", "max_velocity_m_s", self.max_velocity_m_s, "must be > 0")

    def check_target(self, device: str, target_m: object) -> float:
        """``target_m`` as a float if it is a finite position within the travel, else an error."""
        target = finite(device, "target_m", target_m)
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
        velocity = finite(device, quantity, velocity_m_s)
        if velocity <= 0:
            raise InvalidValueError(device, quantity, velocity_m_s, "must be > 0")
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
        delta = finite(self.name, "delta_m", delta_m)
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
        limit_s = timeout(self.name, timeout_s)
        poll_s = max(timeout(self.name, poll_interval_s), 1e-4)
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


# --------------------------------------------------------------------------------------------------
# DAQ (force sensor and analog channels)
# --------------------------------------------------------------------------------------------------

ForceAxis = Literal["fx", "fy", "fz"]


@dataclass(frozen=True, eq=False)
class DaqBlock:
    """Samples read in one call, in SI units.

    ``t_s`` is rebuilt from the unwrapped sample counter, ``t = (counter - counter_origin) /
    rate_hz`` with the origin at the first sample after ``start()`` (docs/protocols.md: never host
    arrival times). ``host_monotonic_ns`` is the host time the block's last sample arrived (block
    assembly time for an empty block): pairs of (last counter, host time) let the acquisition layer
    fit the device clock against the host clock. ``dropped_total`` counts samples lost so far
    (never invented).
    """

    counter: IntArray
    t_s: FloatArray
    fx_N: FloatArray
    fy_N: FloatArray
    fz_N: FloatArray
    ain_V: FloatArray
    host_monotonic_ns: int
    dropped_total: int
    rate_hz: float

    def __post_init__(self) -> None:
        n = self.counter.shape[0]
        if self.counter.ndim != 1 or self.counter.dtype != np.int64:
            raise ValueError("DaqBlock.counter must be a 1-D int64 array")
        for key in ("t_s", "fx_N", "fy_N", "fz_N"):
            arr = getattr(self, key)
            if arr.shape != (n,) or arr.dtype != np.float64:
                raise ValueError(f"DaqBlock.{key} must be float64 of shape ({n},), got {arr.shape}")
        if self.ain_V.shape != (n, 3) or self.ain_V.dtype != np.float64:
            raise ValueError(f"DaqBlock.ain_V must be float64 of shape ({n}, 3)")

    def __len__(self) -> int:
        return int(self.counter.shape[0])

    @classmethod
    def from_counts(
        cls,
        counter: IntArray,
        force_counts: NDArray[np.integer],
        ain_counts: NDArray[np.integer],
        *,
        force_N_per_count: float,
        volts_per_count: float,
        rate_hz: float,
        host_monotonic_ns: int,
        dropped_total: int,
        counter_origin: int = 0,
    ) -> DaqBlock:
        """Build a block from raw counts (n x 3 each) with the protocol's scales.

        ``t_s = (counter - counter_origin) / rate_hz`` (docs/protocols.md, "t = t0 + n / rate").
        """
        counter = np.asarray(counter, dtype=np.int64)
        forces = np.asarray(force_counts, dtype=np.float64).reshape(-1, 3) * force_N_per_count
        ain = np.asarray(ain_counts, dtype=np.float64).reshape(-1, 3) * volts_per_count
        return cls(
            counter=counter,
            t_s=(counter - counter_origin).astype(np.float64) / rate_hz,
            fx_N=np.ascontiguousarray(forces[:, 0]),
            fy_N=np.ascontiguousarray(forces[:, 1]),
            fz_N=np.ascontiguousarray(forces[:, 2]),
            ain_V=np.ascontiguousarray(ain),
            host_monotonic_ns=host_monotonic_ns,
            dropped_total=dropped_total,
            rate_hz=rate_hz,
        )

    @classmethod
    def empty(cls, *, rate_hz: float, host_monotonic_ns: int, dropped_total: int) -> DaqBlock:
        """A block with no samples (a read that timed out while streaming)."""
        none = np.zeros(0, dtype=np.int64)
        return cls.from_counts(
            none,
            np.zeros((0, 3), dtype=np.int64),
            np.zeros((0, 3), dtype=np.int64),
            force_N_per_count=1.0,
            volts_per_count=1.0,
            rate_hz=rate_hz,
            host_monotonic_ns=host_monotonic_ns,
            dropped_total=dropped_total,
        )


@dataclass(frozen=True)
class ChannelMap:
    """Which sensor axis is Ft / Fn (with sign) and which analog channel is D1 / D2 (with scale).

    ``ft_N = ft_sign * f<ft_axis>_N``, likewise Fn; ``d1_m = d1_m_per_V * ain_V[:, d1_channel]``.
    Default probe scale 7.4e-6 m/V: 74 um over 10 V (docs/protocols.md).
    """

    ft_axis: ForceAxis = "fx"
    ft_sign: int = 1
    fn_axis: ForceAxis = "fz"
    fn_sign: int = 1
    d1_channel: int = 0
    d1_m_per_V: float = 7.4e-6
    d2_channel: int = 1
    d2_m_per_V: float = 7.4e-6
    probe_rail_V: float = 9.99
    """A probe's analog output at or beyond this many volts is over range (it sits at the rail)."""

    def __post_init__(self) -> None:
        for key in ("ft_axis", "fn_axis"):
            axis = getattr(self, key)
            if axis not in ("fx", "fy", "fz"):
                raise ValueError(f"ChannelMap.{key} must be 'fx', 'fy' or 'fz', got {axis!r}")
        if self.ft_axis == self.fn_axis:
            raise ValueError(f"ChannelMap: Ft and Fn cannot both be {self.ft_axis}")
        for key in ("ft_sign", "fn_sign"):
            if getattr(self, key) not in (1, -1) or isinstance(getattr(self, key), bool):
                raise ValueError(f"ChannelMap.{key} must be +1 or -1, got {getattr(self, key)!r}")
        for key in ("d1_channel", "d2_channel"):
            value = getattr(self, key)
            if isinstance(value, bool) or value not in (0, 1, 2):
                raise ValueError(f"ChannelMap.{key} must be 0, 1 or 2, got {value!r}")
        for key in ("d1_m_per_V", "d2_m_per_V"):
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"ChannelMap.{key} must be a number, got {value!r}")
            if not (math.isfinite(value) and value != 0):
                raise ValueError(f"ChannelMap.{key} must be finite and non-zero, got {value!r}")

    def ft_N(self, block: DaqBlock) -> FloatArray:
        """Tangential (friction) force [N]."""
        return float(self.ft_sign) * getattr(block, f"{self.ft_axis}_N")

    def fn_N(self, block: DaqBlock) -> FloatArray:
        """Normal force [N]."""
        return float(self.fn_sign) * getattr(block, f"{self.fn_axis}_N")

    def d1_m(self, block: DaqBlock) -> FloatArray:
        """Displacement probe 1 [m] from its analog output."""
        return self.d1_m_per_V * block.ain_V[:, self.d1_channel]

    def d2_m(self, block: DaqBlock) -> FloatArray:
        """Displacement probe 2 [m] from its analog output."""
        return self.d2_m_per_V * block.ain_V[:, self.d2_channel]

    def probe_over_range(self, block: DaqBlock) -> dict[str, np.ndarray]:
        """Per probe (``d1_m``, ``d2_m``), the samples whose analog output sits at the rail."""
        return {
            "d1_m": np.abs(block.ain_V[:, self.d1_channel]) >= self.probe_rail_V,
            "d2_m": np.abs(block.ain_V[:, self.d2_channel]) >= self.probe_rail_V,
        }


class Daq(Device):
    """Synchronous sampling of Fx, Fy, Fz and three analog inputs at ``rate_hz``. Usage::

        daq.start()
        block = daq.read_block(1024, timeout_s=1.0)    # up to 1024 samples (one second at 1024 Hz)
        fn_N = daq.channel_map.fn_N(block)             # forces and probes through the channel map
        daq.stop()
    """

    DEFAULT_RATE_HZ = 1024.0

    def __init__(
        self,
        name: str,
        rate_hz: float = DEFAULT_RATE_HZ,
        channel_map: ChannelMap | None = None,
    ) -> None:
        super().__init__(name)
        rate = finite(name, "rate_hz", rate_hz)
        if rate <= 0:
            raise InvalidValueError(name, "rate_hz", rate_hz, "must be > 0")
        self._rate_hz = rate
        self._channel_map = channel_map if channel_map is not None else ChannelMap()
        self._streaming = False

    @property
    def rate_hz(self) -> float:
        """Sample rate [Hz]."""
        return self._rate_hz

    @property
    def channel_map(self) -> ChannelMap:
        """How Fx/Fy/Fz and ain0..2 map onto Ft, Fn, D1, D2."""
        return self._channel_map

    @property
    def streaming(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._streaming

    def start(self) -> None:
        """Start streaming samples."""
        self._check_open()
        self._do_start()
        self._streaming = True

    def stop(self) -> None:
        """Stop streaming (samples already received stay readable)."""
        self._check_open()
        self._do_stop()
        self._streaming = False

    def tare(self) -> None:
        """Zero the forces at the current reading."""
        self._check_open()
        self._do_tare()

    def set_rate(self, rate_hz: float) -> None:
        """Change the sample rate (only while stopped: sample times depend on it)."""
        self._check_open()
        rate = finite(self.name, "rate_hz", rate_hz)
        if rate <= 0:
            raise InvalidValueError(self.name, "rate_hz", rate_hz, "must be > 0")
        if self._streaming:
            raise DeviceStateError(self.name, "set_rate refused while streaming: stop() first")
        self._do_set_rate(rate)
        self._rate_hz = rate

    def read_block(self, max_samples: int, timeout_s: float) -> DaqBlock:
        """Up to ``max_samples`` complete samples, waiting at most ``timeout_s`` for the first.

        Returns an empty block if none came in time while streaming.
        """
        self._check_open()
        count = positive_int(self.name, "max_samples", max_samples)
        wait_s = timeout(self.name, timeout_s)
        return self._do_read_block(count, wait_s)

    @property
    @abstractmethod
    def dropped_samples(self) -> int:
        """Samples lost so far (counter gaps, incomplete pairs, overflow), never invented."""

    @property
    @abstractmethod
    def protocol_errors(self) -> int:
        """Malformed frames received so far (counted and skipped)."""

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_tare(self) -> None: ...

    @abstractmethod
    def _do_set_rate(self, rate_hz: float) -> None: ...

    @abstractmethod
    def _do_read_block(self, max_samples: int, timeout_s: float) -> DaqBlock: ...


# --------------------------------------------------------------------------------------------------
# Displacement probes
# --------------------------------------------------------------------------------------------------


class ProbeSamples(NamedTuple):
    """Streamed probe samples: device sequence numbers, values [m], host arrival times [ns].

    An over-range sample is ``+inf`` (above the range) or ``-inf`` (below): flagged, never clipped,
    and its direction kept; ``~np.isfinite(values_m)`` is the over-range mask.
    """

    seq: IntArray
    values_m: FloatArray
    host_ns: IntArray


class DisplacementProbe(Device):
    """A displacement probe read one value at a time or as a stream.

    A single reading beyond the range raises :class:`~drivers.errors.OverRangeError`; a streamed one
    is ``+-inf`` (see :class:`ProbeSamples`). Usage::

        probe.zero()                                   # the current position reads 0 from now on
        d_m = probe.read_m()
        probe.start_stream(1000.0)
        samples = probe.read_stream(1000, timeout_s=1.0)   # seq, values_m, host_ns
        probe.stop_stream()
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._streaming = False

    @property
    @abstractmethod
    def range_m(self) -> float:
        """Full measuring range [m], centred on the zero."""

    @property
    @abstractmethod
    def resolution_m(self) -> float:
        """Resolution (quantisation step) [m]."""

    @property
    def streaming(self) -> bool:
        """True between :meth:`start_stream` and :meth:`stop_stream`."""
        return self._streaming

    def zero(self) -> None:
        """Make the current position the zero."""
        self._check_idle("zero")
        self._do_zero()

    def read_m(self) -> float:
        """One displacement reading [m] relative to the zero; OverRangeError beyond the range."""
        self._check_idle("read_m")
        return self._do_read_m()

    def start_stream(self, rate_hz: float) -> None:
        """Start streaming at ``rate_hz``."""
        self._check_idle("start_stream")
        rate = finite(self.name, "rate_hz", rate_hz)
        if rate <= 0:
            raise InvalidValueError(self.name, "rate_hz", rate_hz, "must be > 0")
        self._do_start_stream(rate)
        self._streaming = True

    def read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples:
        """Up to ``max_samples`` streamed samples, waiting at most ``timeout_s`` for the first."""
        self._check_open()
        count = positive_int(self.name, "max_samples", max_samples)
        wait_s = timeout(self.name, timeout_s)
        return self._do_read_stream(count, wait_s)

    def stop_stream(self) -> None:
        """Stop streaming (samples already received stay readable)."""
        self._check_open()
        self._do_stop_stream()
        self._streaming = False

    def _check_idle(self, command: str) -> None:
        self._check_open()
        if self._streaming:
            raise DeviceStateError(self.name, f"{command} refused while streaming: stop_stream() first")

    @abstractmethod
    def _do_zero(self) -> None: ...

    @abstractmethod
    def _do_read_m(self) -> float: ...

    @abstractmethod
    def _do_start_stream(self, rate_hz: float) -> None: ...

    @abstractmethod
    def _do_read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples: ...

    @abstractmethod
    def _do_stop_stream(self) -> None: ...


# --------------------------------------------------------------------------------------------------
# Camera
# --------------------------------------------------------------------------------------------------


class RawFrame(NamedTuple):
    """What a camera hook returns: image (uint8, H x W), capture time [monotonic ns], sequence."""

    image: NDArray[np.uint8]
    t_monotonic_ns: int
    seq: int
    t_device_s: float = math.nan
    """Capture time on the DAQ's sample clock when the camera is synchronised to it (the simulated
    camera: both run on the rig's clock); NaN when only the host time is known."""


@dataclass(frozen=True, eq=False)
class Frame:
    """A camera frame: uint8 H x W image, host capture time, sequence number, frames lost before."""

    image: NDArray[np.uint8]
    t_monotonic_ns: int
    seq: int
    dropped_before: int
    t_device_s: float = math.nan
    """Capture time on the DAQ's sample clock (NaN: unknown; see :class:`RawFrame`)."""


@dataclass
class FrameDropDetector:
    """Counts frames lost before each frame: a ``seq`` gap or an interval above 1.5 periods.

    Lost frames = max(seq gap, round(interval * frame_rate_hz) - 1 when interval > 1.5 / rate): a
    gap and a long interval usually describe the same loss, so they are not added. The interval is
    taken on the DAQ's clock when frames carry a device time (a synchronised camera: on an
    accelerated simulated rig the host intervals are rig intervals divided by an uneven speed).
    """

    frame_rate_hz: float
    total_dropped: int = 0
    _last_seq: int | None = field(default=None, repr=False)
    _last_t_ns: int | None = field(default=None, repr=False)
    _last_t_device_s: float = field(default=math.nan, repr=False)

    def update(self, seq: int, t_monotonic_ns: int, t_device_s: float = math.nan) -> int:
        """Frames lost between the previous frame and this one.

        Sequence numbers start at 0 at ``start()``, so a first frame numbered n means n were lost.
        """
        dropped = max(seq, 0)
        if self._last_seq is not None and self._last_t_ns is not None:
            gap = max(seq - self._last_seq - 1, 0)
            if math.isfinite(t_device_s) and math.isfinite(self._last_t_device_s):
                interval_s = t_device_s - self._last_t_device_s
            else:
                interval_s = (t_monotonic_ns - self._last_t_ns) * 1e-9
            late = 0
            if interval_s > 1.5 / self.frame_rate_hz:
                late = max(round(interval_s * self.frame_rate_hz) - 1, 1)
            dropped = max(gap, late)
        self._last_seq = seq
        self._last_t_ns = t_monotonic_ns
        self._last_t_device_s = t_device_s
        self.total_dropped += dropped
        return dropped

    def reset(self) -> None:
        """Forget the previous frame (after a stop/start)."""
        self._last_seq = None
        self._last_t_ns = None
        self._last_t_device_s = math.nan


class Camera(Device):
    """A camera delivering timestamped, numbered frames; drops are detected and counted.

    Implementations number frames from 0 at each ``start()`` (``RawFrame.seq``) and stamp them
    with ``time.monotonic_ns()``; the base class fills ``Frame.dropped_before``. Usage::

        camera.start()
        frame = camera.read_frame(timeout_s=1.0)       # frame.image, frame.seq, frame.dropped_before
        camera.stop()
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._drops: FrameDropDetector | None = None
        self._running = False

    @property
    @abstractmethod
    def frame_rate_hz(self) -> float:
        """Nominal frame rate [Hz] (used for drop detection)."""

    @property
    def running(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._running

    @property
    def frames_dropped(self) -> int:
        """Frames lost since :meth:`start`."""
        return 0 if self._drops is None else self._drops.total_dropped

    def start(self) -> None:
        """Start capturing."""
        self._check_open()
        self._drops = None
        self._do_start()
        self._drops = FrameDropDetector(self.frame_rate_hz)
        self._running = True

    def stop(self) -> None:
        """Stop capturing (frames already captured stay readable)."""
        self._do_stop()
        self._running = False

    def read_frame(self, timeout_s: float) -> Frame:
        """The next frame; DeviceTimeout if none arrives within ``timeout_s``."""
        self._check_open()
        if self._drops is None:
            raise DeviceStateError(self.name, "read_frame before start()")
        wait_s = timeout(self.name, timeout_s)
        raw = self._do_read_frame(wait_s)
        if raw is None:
            raise DeviceTimeout(self.name, wait_s, detail="no frame")
        dropped = self._drops.update(raw.seq, raw.t_monotonic_ns, raw.t_device_s)
        return Frame(raw.image, raw.t_monotonic_ns, raw.seq, dropped, raw.t_device_s)

    @property
    def exposure_s(self) -> float:
        """Exposure time [s] (NotSupportedError where the device cannot report it)."""
        return self._do_get_exposure_s()

    @exposure_s.setter
    def exposure_s(self, value: float) -> None:
        exposure = finite(self.name, "exposure_s", value)
        if exposure <= 0:
            raise InvalidValueError(self.name, "exposure_s", value, "must be > 0")
        self._do_set_exposure_s(exposure)

    @property
    def gain(self) -> float:
        """Analog gain (device units; NotSupportedError where unsupported)."""
        return self._do_get_gain()

    @gain.setter
    def gain(self, value: float) -> None:
        gain = finite(self.name, "gain", value)
        if gain < 0:
            raise InvalidValueError(self.name, "gain", value, "must be >= 0")
        self._do_set_gain(gain)

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_read_frame(self, timeout_s: float) -> RawFrame | None:
        """The next frame, or None if none came within ``timeout_s``."""

    def _do_get_exposure_s(self) -> float:
        raise NotSupportedError(self.name, "exposure")

    def _do_set_exposure_s(self, exposure_s: float) -> None:
        raise NotSupportedError(self.name, "exposure")

    def _do_get_gain(self) -> float:
        raise NotSupportedError(self.name, "gain")

    def _do_set_gain(self, gain: float) -> None:
        raise NotSupportedError(self.name, "gain")
