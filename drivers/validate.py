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
import sys
from dataclasses import dataclass

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


@dataclass(frozen=True)
class _Refusal:
    """How one kind of check refuses a value: its error class and its words."""

    error: type[SettingError] | type[InvalidValueError]
    not_number: str
    not_finite: str
    out_of_bounds: str | None = None
    """One phrase for every bound missed; None: :func:`bound_problem`'s phrase (``"must be > 0 s"``)."""


_SETTING = _Refusal(SettingError, "must be a number", "must be finite")
_ARGUMENT = _Refusal(InvalidValueError, "not a real number", "not finite")
_COUNT = _Refusal(InvalidValueError, "must be an integer >= 1", "must be an integer >= 1",
                  out_of_bounds="must be an integer >= 1")


def _checked(
    refusal: _Refusal,
    owner: str,
    key: str,
    value: object,
    number: float | None,
    *,
    unit: str = "",
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    lt: float | None = None,
) -> float:
    """``number`` (``value`` as a float, None if it is not a number of the wanted kind) if it is
    finite and within the bounds, else ``refusal.error`` naming ``owner``, ``key`` and ``value``."""
    if number is None:
        raise refusal.error(owner, key, value, refusal.not_number)
    if not math.isfinite(number):
        raise refusal.error(owner, key, value, refusal.not_finite)
    problem = bound_problem(number, unit=unit, gt=gt, ge=ge, le=le, lt=lt)
    if problem:
        raise refusal.error(owner, key, value, refusal.out_of_bounds or problem)
    return number


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
    return _checked(_SETTING, owner, key, value, real_number(value),
                    unit=unit, gt=gt, ge=ge, le=le, lt=lt)


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
    return _checked(_ARGUMENT, device, quantity, value, real_number(value),
                    unit=unit, gt=gt, ge=ge, le=le, lt=lt)


def check_count(device: str, quantity: str, value: object) -> int:
    """A count argument (``max_samples``) as an int if it is an integer >= 1, else
    :class:`InvalidValueError`."""
    count = int(value) if isinstance(value, int | np.integer) and not isinstance(value, bool) else None
    # a Python int is unbounded: a count beyond float's range tests as float's largest magnitude
    big = sys.float_info.max
    number = None if count is None else float(min(max(count, -big), big))
    _checked(_COUNT, device, quantity, value, number, ge=1.0)
    assert count is not None  # refused above otherwise
    return count


def check_timeout(device: str, value: object, quantity: str = "timeout_s") -> float:
    """A wait in seconds (a command argument): finite and >= 0, else :class:`InvalidValueError`."""
    return check_argument(device, quantity, value, ge=0.0)
