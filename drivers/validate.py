"""One check of a number: a real number, finite, within its bounds, unit in the message.

A configured number (a setting) is refused with :class:`SettingError`; a command argument (a move's
target, a rate, a timeout) with :class:`InvalidValueError` (``check_argument``, ``check_count``),
by the same tests. Used by the device interfaces' commands and ``StageLimits``
(``drivers.interfaces``), by the drivers' and simulators' configuration classes (``StageConfig``,
``CanDaqConfig``, ``ProbeConfig``, ``CameraConfig``, the virtual rig's ``RigConfig``), by the rig
configuration's :func:`rigctl.config.fields.setting` bounds, by the model's ``ParamSpec`` and by
the protocols' ``ParamDef``, so that all of them refuse the same values with the same words::

    timeout_s = check_number("probe 'd1'", "timeout_s", 0.3, unit="s", gt=0.0)   # 0.3
    check_number("probe 'd1'", "timeout_s", -1, unit="s", gt=0.0)
    # SettingError: probe 'd1': timeout_s = -1: must be > 0 s
    check_integer("probe 'd1'", "retries", 5, 0, 3)
    # SettingError: probe 'd1': retries = 5: must be an integer in 0..3
"""

from __future__ import annotations

import math

import numpy as np

from drivers.errors import InvalidValueError, SettingError


def real_number(value: object) -> float | None:
    """``value`` as a float if it is a real number (``bool`` is not), else None."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        return None
    return float(value)


def bound_problem(
    value: float,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    integer: bool = False,
) -> str | None:
    """What is wrong with ``value`` as one phrase (``"must be > 0 s"``), or None if nothing.

    Checked in this order: finite, whole (if ``integer``), ``gt``, ``ge``, ``le``, ``lt``.
    """
    u = f" {unit}" if unit else ""
    if not math.isfinite(value):
        return "must be finite"
    if integer and value != int(value):
        return "must be a whole number"
    if gt is not None and not value > gt:
        return f"must be > {gt:g}{u}"
    if ge is not None and not value >= ge:
        return f"must be >= {ge:g}{u}"
    if le is not None and not value <= le:
        return f"must be <= {le:g}{u}"
    if lt is not None and not value < lt:
        return f"must be < {lt:g}{u}"
    return None


def check_number(
    owner: str,
    key: str,
    value: object,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
) -> float:
    """``value`` as a float if it is a finite real number within the bounds, else :class:`SettingError`."""
    number = real_number(value)
    if number is None:
        raise SettingError(owner, key, value, "must be a number")
    problem = bound_problem(number, unit=unit, gt=gt, ge=ge, le=le, lt=lt)
    if problem:
        raise SettingError(owner, key, value, problem)
    return number


def check_integer(owner: str, key: str, value: object, low: int, high: int) -> int:
    """``value`` if it is an ``int`` (not ``bool``) in ``low..high``, else :class:`SettingError`."""
    if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
        raise SettingError(owner, key, value, f"must be an integer in {low}..{high}")
    return value


def refused(owner: str, config: object, key: str, reason: str) -> SettingError:
    """The :class:`SettingError` for ``config.key`` (its current value), for checks that are not numbers."""
    return SettingError(owner, key, getattr(config, key), reason)


def check_argument(
    device: str,
    quantity: str,
    value: object,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
) -> float:
    """A command argument as a float if it is a finite real number within the bounds, else
    :class:`InvalidValueError` (``"not a real number"``, ``"not finite"``, ``"must be > 0"``)."""
    number = real_number(value)
    if number is None:
        raise InvalidValueError(device, quantity, value, "not a real number")
    if not math.isfinite(number):
        raise InvalidValueError(device, quantity, value, "not finite")
    problem = bound_problem(number, unit=unit, gt=gt, ge=ge, le=le, lt=lt)
    if problem:
        raise InvalidValueError(device, quantity, value, problem)
    return number


def check_count(device: str, quantity: str, value: object) -> int:
    """A count argument (``max_samples``) as an int if it is an integer >= 1, else
    :class:`InvalidValueError`."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise InvalidValueError(device, quantity, value, "must be an integer >= 1")
    return int(value)


def check_timeout(device: str, value: object, quantity: str = "timeout_s") -> float:
    """A wait in seconds (a command argument): finite and >= 0, else :class:`InvalidValueError`."""
    return check_argument(device, quantity, value, ge=0.0)
