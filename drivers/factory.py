"""Build drivers from plain dict configuration (what a TOML file parses to), with clear errors.

Each device is a mapping with a ``kind`` (``modbus_stage``, ``can_daq``, ``serial_probe``,
``opencv_camera``, or any kind added with :func:`register_driver`) and the fields of that driver's
config dataclass. Nested mappings fill nested dataclasses (``limits``, ``registers``,
``channel_map``). Every mistake raises :class:`ConfigError` (a ``ValueError``) naming the key path,
e.g. ``devices.normal_stage.limits.max_position_m: expected a number, got 'abc'``; unknown keys are
errors too (a typo must not silently fall back to a default).

``modbus_stage`` takes a ``role`` (``"normal"`` or ``"tangential"``) that presets ``counts_per_m``
and ``limits`` from the paper's rig (Han et al. 2022); a partial ``limits`` mapping overrides only
what it names.
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable, Mapping
from typing import Any, TypeVar

from drivers.can_daq import CanDaq, CanDaqConfig
from drivers.interfaces import Device, StageLimits
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    NORMAL_LIMITS,
    TANGENTIAL_COUNTS_PER_M,
    TANGENTIAL_LIMITS,
    ModbusStage,
    StageConfig,
)
from drivers.opencv_camera import CameraConfig, OpenCvCamera
from drivers.safety import EmergencyStop
from drivers.serial_probe import ProbeConfig, SerialProbe

D = TypeVar("D")


class ConfigError(ValueError):
    """A configuration mistake; the message starts with the key path."""

    def __init__(self, path: str, message: str) -> None:
        self.path = path
        super().__init__(f"{path}: {message}" if path else message)


Builder = Callable[[Mapping[str, Any], str, "EmergencyStop | None"], Device]
_BUILDERS: dict[str, Builder] = {}


def register_driver(kind: str, builder: Builder) -> None:
    """Make ``kind`` buildable: ``builder(mapping_without_kind, key_path, emergency_stop)``."""
    if not kind or not isinstance(kind, str):
        raise ValueError(f"driver kind must be a non-empty string, got {kind!r}")
    _BUILDERS[kind] = builder


def driver_kinds() -> list[str]:
    """The kinds :func:`build_device` knows."""
    return sorted(_BUILDERS)


def build_device(
    config: Mapping[str, Any], *, path: str = "device", emergency_stop: EmergencyStop | None = None
) -> Device:
    """One driver from its mapping (``kind`` plus the fields of the driver's config)."""
    if not isinstance(config, Mapping):
        raise ConfigError(path, f"expected a table of settings, got {type(config).__name__}")
    kind = config.get("kind")
    if kind is None:
        raise ConfigError(f"{path}.kind", f"missing; one of {driver_kinds()}")
    builder = _BUILDERS.get(kind) if isinstance(kind, str) else None
    if builder is None:
        raise ConfigError(f"{path}.kind", f"unknown driver kind {kind!r}; one of {driver_kinds()}")
    settings = {k: v for k, v in config.items() if k != "kind"}
    return builder(settings, path, emergency_stop)


def build_devices(
    devices: Mapping[str, Mapping[str, Any]],
    *,
    path: str = "devices",
    emergency_stop: EmergencyStop | None = None,
) -> dict[str, Device]:
    """Several drivers keyed by name (the name is the default device name); all or none.

    If one fails, those already built are closed before the error propagates.
    """
    if not isinstance(devices, Mapping):
        raise ConfigError(path, f"expected a table of devices, got {type(devices).__name__}")
    built: dict[str, Device] = {}
    try:
        for key, entry in devices.items():
            sub = f"{path}.{key}"
            if not isinstance(entry, Mapping):
                raise ConfigError(sub, f"expected a table, got {type(entry).__name__}")
            named = dict(entry) if "name" in entry else {**entry, "name": key}
            built[key] = build_device(named, path=sub, emergency_stop=emergency_stop)
    except BaseException:
        for device in built.values():
            device.close()
        raise
    return built


# --------------------------------------------------------------------------------------------------
# dataclasses from mappings
# --------------------------------------------------------------------------------------------------


def dataclass_from_mapping(cls: type[D], values: Mapping[str, Any], path: str) -> D:
    """An instance of dataclass ``cls`` from ``values``, checking keys and simple types."""
    if not isinstance(values, Mapping):
        raise ConfigError(path, f"expected a table, got {type(values).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    hints = typing.get_type_hints(cls)
    unknown = sorted(set(values) - set(fields))
    if unknown:
        raise ConfigError(f"{path}.{unknown[0]}", f"unknown key; known keys: {sorted(fields)}")
    kwargs = {name: _coerce(hints[name], value, f"{path}.{name}") for name, value in values.items()}
    missing = [
        name
        for name, f in fields.items()
        if name not in kwargs
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise ConfigError(f"{path}.{missing[0]}", "missing required key")
    try:
        return cls(**kwargs)
    except ValueError as exc:
        raise ConfigError(path, str(exc)) from exc


_DESCRIPTIONS: dict[Any, str] = {
    float: "a number",
    int: "an integer",
    str: "a string",
    bool: "true or false",
    type(None): "nothing (omit the key)",
}


def _describe(hint: Any) -> str:
    if typing.get_origin(hint) is typing.Literal:
        return f"one of {list(typing.get_args(hint))}"
    if dataclasses.is_dataclass(hint):
        return "a table"
    return _DESCRIPTIONS.get(hint, repr(hint))


def _coerce(hint: Any, value: Any, path: str) -> Any:
    origin = typing.get_origin(hint)
    if origin is typing.Union or origin is types.UnionType:
        options = typing.get_args(hint)
        if value is None and type(None) in options:
            return None
        for option in options:
            if option is type(None):
                continue
            try:
                return _coerce(option, value, path)
            except ConfigError:
                continue
        wanted = " or ".join(_describe(option) for option in options)
        raise ConfigError(path, f"expected {wanted}, got {value!r}")
    if origin is typing.Literal:
        allowed = typing.get_args(hint)
        if value not in allowed:
            raise ConfigError(path, f"expected one of {list(allowed)}, got {value!r}")
        return value
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return dataclass_from_mapping(hint, value, path)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ConfigError(path, f"expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ConfigError(path, f"expected a finite number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(path, f"expected an integer, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(path, f"expected a string, got {value!r}")
        return value
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(path, f"expected true or false, got {value!r}")
        return value
    raise ConfigError(path, f"cannot read a value of type {hint!r} from configuration")


# --------------------------------------------------------------------------------------------------
# built-in drivers
# --------------------------------------------------------------------------------------------------

_ROLES: dict[str, tuple[float, StageLimits]] = {
    "normal": (NORMAL_COUNTS_PER_M, NORMAL_LIMITS),
    "tangential": (TANGENTIAL_COUNTS_PER_M, TANGENTIAL_LIMITS),
}


def _build_modbus_stage(
    settings: Mapping[str, Any], path: str, emergency_stop: EmergencyStop | None
) -> Device:
    values = dict(settings)
    role = values.pop("role", None)
    if role is not None:
        if role not in _ROLES:
            raise ConfigError(f"{path}.role", f"expected one of {sorted(_ROLES)}, got {role!r}")
        counts_per_m, limits = _ROLES[role]
        values.setdefault("counts_per_m", counts_per_m)
        given = values.get("limits", {})
        if not isinstance(given, Mapping):
            raise ConfigError(f"{path}.limits", f"expected a table, got {type(given).__name__}")
        values["limits"] = {**dataclasses.asdict(limits), **given}
        values.setdefault("name", f"{role}_stage")
    config = dataclass_from_mapping(StageConfig, values, path)
    return ModbusStage(config, emergency_stop=emergency_stop)


def _build_can_daq(settings: Mapping[str, Any], path: str, emergency_stop: EmergencyStop | None) -> Device:
    return CanDaq(dataclass_from_mapping(CanDaqConfig, settings, path))


def _build_serial_probe(
    settings: Mapping[str, Any], path: str, emergency_stop: EmergencyStop | None
) -> Device:
    return SerialProbe(dataclass_from_mapping(ProbeConfig, settings, path))


def _build_opencv_camera(
    settings: Mapping[str, Any], path: str, emergency_stop: EmergencyStop | None
) -> Device:
    return OpenCvCamera(dataclass_from_mapping(CameraConfig, settings, path))


register_driver("modbus_stage", _build_modbus_stage)
register_driver("can_daq", _build_can_daq)
register_driver("serial_probe", _build_serial_probe)
register_driver("opencv_camera", _build_opencv_camera)
