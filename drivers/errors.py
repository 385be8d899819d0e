"""Named errors of every device driver (and of the simulators, which raise the same ones).

Every error carries the name of the device it concerns (``err.device``) so that a log line or
a CLI message says which stage, DAQ or probe misbehaved. Errors a user can fix by changing a
command or a configuration value (a target beyond a limit, a NaN velocity) also derive from
:class:`InputError` (a ``ValueError``), which the CLI prints as one line with exit status 2.

Hierarchy::

    DeviceError
    +-- DeviceTimeout            the device did not answer in time
    +-- ProtocolError            malformed / short / corrupt frame or line (keeps the bytes)
    +-- DeviceRejected           the device answered with an error code
    |   +-- UnknownCommand       code 1 ("01")
    |   +-- BadParameter         code 2 ("02")
    |   +-- DeviceBusy           code 3 ("03")
    +-- InvalidValueError        (also InputError) NaN, inf, wrong type, non-positive count
    |   +-- LimitError           beyond a configured limit, refused before anything is sent
    +-- ForceLimitError          |Fn| above the force limit: the normal stage was emergency-stopped
    +-- StageAlarm               the stage controller reports an alarm (code and name)
    +-- OverRangeError           a displacement probe is outside its measuring range
    +-- NotSupportedError        the device cannot do this (e.g. camera exposure)
    +-- EmergencyStopActive      the emergency stop is latched: command refused until reset
    +-- DeviceStateError         command not valid in the current state (e.g. set_rate while
    |                            streaming)
    +-- MotionTimeout            a stage did not finish its move within the time asked for

    InputError                   (a ValueError) what the user gave cannot be used: CLI exit 2
    +-- SettingError             a configuration value out of its bounds (names its key)
"""

from __future__ import annotations

import math

STAGE_ALARM_NAMES: dict[int, str] = {
    0: "none",
    1: "over-travel (limit)",
    2: "following error",
    3: "over-load",
    4: "driver fault",
    5: "emergency stop",
}
"""Alarm codes of the stage controller's ``alarm_code`` register (docs/protocols.md)."""

DEVICE_STATUS_NAMES: dict[int, str] = {
    0: "ok",
    1: "unknown command",
    2: "bad parameter",
    3: "busy",
}
"""Status / error codes shared by the CAN DAQ replies and the probe ``ER,<cmd>,<code>`` lines."""


def stage_alarm_name(code: int) -> str:
    """Name of a stage alarm code; unknown codes are named as such, never hidden."""
    return STAGE_ALARM_NAMES.get(code, f"unknown alarm {code}")


class DeviceError(Exception):
    """Base of all driver errors; ``device`` names the device concerned."""

    def __init__(self, device: str, message: str) -> None:
        self.device = device
        super().__init__(message if message.startswith(device) else f"{device}: {message}")


class DeviceTimeout(DeviceError):  # noqa: N818 - name fixed by the contract
    """The device did not answer within ``timeout_s`` (retries included)."""

    def __init__(self, device: str, timeout_s: float, *, detail: str = "") -> None:
        self.timeout_s = timeout_s
        message = f"{device} did not answer within {timeout_s:.2g} s"
        super().__init__(device, f"{message} ({detail})" if detail else message)


class ProtocolError(DeviceError):
    """A frame or line that does not follow the protocol; ``data`` holds the offending bytes."""

    def __init__(self, device: str, reason: str, data: bytes | bytearray = b"") -> None:
        self.reason = reason
        self.data = bytes(data)
        super().__init__(device, f"protocol error: {reason}: {self.data!r}")


class DeviceRejected(DeviceError):  # noqa: N818 - named like its contract siblings
    """The device answered a command with an error code."""

    def __init__(self, device: str, command: str, code: int) -> None:
        self.command = command
        self.code = code
        self.code_name = DEVICE_STATUS_NAMES.get(code, f"unknown code {code}")
        super().__init__(device, f"rejected {command!r}: {self.code_name} (code {code})")


class UnknownCommand(DeviceRejected):
    """Error code 1: the device does not know the command."""


class BadParameter(DeviceRejected):
    """Error code 2: a parameter of the command is invalid."""


class DeviceBusy(DeviceRejected):
    """Error code 3: the device is busy (e.g. a single reading asked for while streaming)."""


def rejected(device: str, command: str, code: int) -> DeviceRejected:
    """The :class:`DeviceRejected` subclass for an error code (1, 2, 3; others the base class)."""
    cls: type[DeviceRejected] = {1: UnknownCommand, 2: BadParameter, 3: DeviceBusy}.get(code, DeviceRejected)
    return cls(device, command, code)


class InputError(ValueError):
    """A value the user gave (a command argument, a configuration value) that cannot be used.

    The base of every error the user fixes by changing what they asked for; the CLI prints it as one
    line with exit status 2. :mod:`rigctl.errors` builds rigctl's own input errors on it.
    """


class InvalidValueError(DeviceError, InputError):
    """A command argument that is not a usable number (NaN, inf, wrong type, non-positive...)."""

    def __init__(self, device: str, quantity: str, value: object, reason: str) -> None:
        self.quantity = quantity
        self.value = value
        super().__init__(device, f"{quantity} = {value!r} refused: {reason}")


class LimitError(InvalidValueError):
    """A command beyond a configured limit; refused before anything is sent, never clipped."""

    def __init__(
        self, device: str, quantity: str, value: float, limit: float, unit: str, *, reason: str = ""
    ) -> None:
        self.limit = limit
        self.unit = unit
        relation = "above the maximum" if value > limit else "below the minimum"
        reason = reason or f"{value:.6g} {unit} is {relation} {limit:.6g} {unit}"
        super().__init__(device, quantity, value, reason)


class SettingError(InputError):
    """A configuration value a device or simulator cannot work with; ``key`` names it.

    Raised by the configuration classes' own checks; a configuration loader reports it under the
    key's full path (``normal_stage.limits.max_position_m: must be above ...``).
    """

    def __init__(self, owner: str, key: str, value: object, reason: str) -> None:
        self.owner = owner
        self.key = key
        self.value = value
        self.reason = reason
        super().__init__(f"{owner}: {key} = {value!r}: {reason}")


class ForceLimitError(DeviceError):
    """|Fn| exceeded the force limit: the guarded stage was emergency-stopped."""

    def __init__(self, device: str, force_N: float, limit_N: float,
                 *, range_N: float | None = None) -> None:
        self.force_N = force_N
        self.limit_N = limit_N
        self.range_N = range_N
        """The force sensor's range when the trip was a saturated reading (at least this much)."""
        if range_N is not None:
            what = (f"the force sensor is saturated: |Fn| >= {range_N:.6g} N, its range (at least "
                    f"this much; the limit is {limit_N:.6g} N)")
        else:
            shown = "non-finite" if not math.isfinite(force_N) else f"|Fn| = {abs(force_N):.6g} N"
            what = f"{shown} exceeds {limit_N:.6g} N"
        super().__init__(
            device,
            f"force limit tripped: {what}; emergency stop sent, commands refused until the guard "
            "is reset",
        )


class StaleReadingError(DeviceError):
    """A force reading stopped changing: the sensor or its DAQ is frozen; the stages were stopped."""

    def __init__(self, device: str, frozen_s: float, since_t_s: float) -> None:
        self.frozen_s = frozen_s
        self.since_t_s = since_t_s
        super().__init__(
            device,
            f"force reading frozen: fx, fy, fz identical for {frozen_s:.2f} s (since device time "
            f"{since_t_s:.2f} s): the force sensor or the DAQ is stuck; stages emergency-stopped",
        )


class StageAlarm(DeviceError):  # noqa: N818 - name fixed by the contract
    """The stage controller reports an alarm (code and name from docs/protocols.md)."""

    def __init__(self, device: str, alarm_code: int) -> None:
        self.alarm_code = alarm_code
        self.alarm_name = stage_alarm_name(alarm_code)
        super().__init__(device, f"stage alarm {alarm_code}: {self.alarm_name}")


class OverRangeError(DeviceError):
    """A displacement probe reading is outside the measuring range (``direction`` +1 or -1)."""

    def __init__(self, device: str, direction: int, range_m: float | None = None) -> None:
        self.direction = direction
        self.range_m = range_m
        side = "above" if direction > 0 else "below"
        span = "" if range_m is None else f" (range {range_m * 1e6:.6g} um centred on the zero)"
        super().__init__(device, f"over range: target {side} the measuring range{span}")


class NotSupportedError(DeviceError):
    """The device does not support this operation or setting."""

    def __init__(self, device: str, what: str) -> None:
        self.what = what
        super().__init__(device, f"{what} is not supported by this device")


class EmergencyStopActive(DeviceError):  # noqa: N818 - name fixed by the contract
    """The emergency stop is latched; motion commands are refused until it is reset."""

    def __init__(self, device: str, reason: str) -> None:
        self.reason = reason
        super().__init__(device, f"command refused: emergency stop latched ({reason})")


class DeviceStateError(DeviceError):
    """The command is not valid in the device's current state."""


class MotionTimeout(DeviceError):  # noqa: N818 - named like DeviceTimeout
    """A stage was still moving when the caller's wait ran out."""

    def __init__(self, device: str, timeout_s: float) -> None:
        self.timeout_s = timeout_s
        super().__init__(device, f"still moving after {timeout_s:.3g} s")
