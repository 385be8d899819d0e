"""Read a rig configuration from TOML into the typed, frozen :class:`RigConfig`.

A file only needs the keys it changes: everything else keeps the default (the simulated rig).
Every problem raises :class:`ConfigError` naming the dotted key, e.g.
``normal_stage.limits.max_force_N: expected a number, got "abc"``; an unknown key is an error with a
"did you mean" suggestion, because a misspelt limit silently ignored is a limit not applied.
"""

from __future__ import annotations

import codecs
import dataclasses
import difflib
import json
import math
import os
import tomllib
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar

import tomli_w

from drivers.errors import SettingError
from rigctl.config.checks import check_config
from rigctl.config.errors import ConfigError
from rigctl.config.fields import check_bounds, setting_of
from rigctl.config.schema import RigConfig

UTF8_BOM = "\ufeff"
"""The byte-order mark some editors put first in a UTF-8 file: refused by name (tomllib's own
message, "Invalid statement (at line 1, column 1)", shows nothing wrong there)."""
ENV_VAR = "RIGCTL_CONFIG"
"""Environment variable naming the configuration file used when no ``--config`` is given."""

T = TypeVar("T")


def default_config() -> RigConfig:
    """The built-in configuration: the simulated rig."""
    return RigConfig()


def load_config(path: str | Path | None = None) -> RigConfig:
    """The configuration in ``path`` (over the defaults), or the defaults when ``path`` is None."""
    if path is None:
        return default_config()
    src = Path(path)
    try:
        data = src.read_bytes()
    except FileNotFoundError:
        raise ConfigError(f"{src}: no such configuration file") from None
    except OSError as exc:
        raise ConfigError(f"{src}: cannot read: {exc}") from None
    if data.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        raise ConfigError(f"{src}: is UTF-16 text; TOML is UTF-8: save the file as UTF-8 (without "
                          "a byte-order mark)")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError(f"{src}: cannot read: not UTF-8 text ({exc})") from None
    return parse_config(text, source=str(src))


def resolve_config_path(path: str | Path | None) -> Path | None:
    """``path`` if given, else ``$RIGCTL_CONFIG`` if set and non-empty, else None (the defaults)."""
    if path is not None:
        return Path(path)
    env = os.environ.get(ENV_VAR, "").strip()
    return Path(env) if env else None


def load_effective_config(path: str | Path | None = None) -> tuple[RigConfig, Path | None]:
    """The configuration a command should use, and where it came from (None: the defaults).

    ``path`` (a ``--config`` argument) wins; else ``$RIGCTL_CONFIG``; else the defaults.
    """
    source = resolve_config_path(path)
    return load_config(source), source


def parse_config(text: str, *, source: str = "<config>") -> RigConfig:
    """Parse TOML text into a validated :class:`RigConfig`."""
    if text.startswith(UTF8_BOM):
        raise ConfigError(f"{source}: starts with a UTF-8 byte-order mark (BOM, written by some "
                          "Windows editors), which the TOML reader does not accept: save the file as "
                          "UTF-8 without BOM")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: invalid TOML: {exc}") from None
    try:
        config = from_dict(RigConfig, data)
        check_config(config)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}", key=exc.key) from None
    return config


def from_dict(cls: type[T], data: Mapping[str, Any], prefix: str = "") -> T:
    """Build dataclass ``cls`` from a TOML table; missing keys keep their defaults."""
    fields = {f.name: f for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
    hints = _hints(cls)
    for key in data:
        if key not in fields:
            raise ConfigError(_unknown_key(prefix + key, key, list(fields)), key=prefix + key)
    values: dict[str, Any] = {}
    for name, value in data.items():
        key = prefix + name
        kind: Any = hints[name]
        if isinstance(kind, type) and dataclasses.is_dataclass(kind):
            if not isinstance(value, Mapping):
                raise ConfigError(f"{key}: expected a table, got {_show(value)}", key=key)
            values[name] = from_dict(kind, value, key + ".")
        else:
            values[name] = _convert(key, kind, value)
            if isinstance(values[name], int | float) and not isinstance(values[name], bool):
                info = setting_of(cls, fields[name])
                problem = check_bounds(info, float(values[name]))
                if problem:
                    unit = f" {info.unit}" if info.unit else ""
                    raise ConfigError(f"{key}: {problem}, got {_show(value)}{unit}", key=key)
    try:
        return cls(**values)
    except SettingError as exc:  # a section's own check that names its key
        raise ConfigError(f"{prefix}{exc.key}: {exc.reason}", key=prefix + exc.key) from None
    except ValueError as exc:  # a section's own __post_init__ checks (e.g. the drivers' classes)
        where = prefix.rstrip(".") or "configuration"
        raise ConfigError(f"{where}: {exc}", key=where) from None


def to_dict(config: Any) -> dict[str, Any]:
    """The configuration as plain TOML-ready data (tuples become lists)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(config):
        value = getattr(config, f.name)
        if dataclasses.is_dataclass(value):
            out[f.name] = to_dict(value)
        elif isinstance(value, tuple):
            out[f.name] = list(value)
        else:
            out[f.name] = value
    return out


def to_toml(config: RigConfig) -> str:
    """The configuration as TOML text (every key, defaults included); parses back to ``config``."""
    return tomli_w.dumps(to_dict(config))


# -- conversion of one value -------------------------------------------------------------------


def _hints(cls: Any) -> dict[str, Any]:
    return typing.get_type_hints(cls)


def _convert(key: str, kind: Any, value: Any) -> Any:
    origin = typing.get_origin(kind)
    if origin is Literal:
        choices = typing.get_args(kind)
        if value in choices and type(value) is type(choices[0]):
            return value
        listed = ", ".join(_show(c) for c in choices)
        hint = _suggest(str(value), [str(c) for c in choices]) if isinstance(value, str) else ""
        raise ConfigError(f"{key}: expected one of {listed}, got {_show(value)}{hint}", key=key)
    if origin is tuple:
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{key}: expected an array of strings, got {_show(value)}", key=key)
        return tuple(value)
    if kind is bool:
        if isinstance(value, bool):
            return value
        raise ConfigError(f"{key}: expected true or false, got {_show(value)}", key=key)
    if kind is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        raise ConfigError(f"{key}: expected a whole number, got {_show(value)}", key=key)
    if kind is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            if not math.isfinite(value):
                raise ConfigError(f"{key}: expected a finite number, got {_show(value)}", key=key)
            return float(value)
        raise ConfigError(f"{key}: expected a number, got {_show(value)}", key=key)
    if kind is str:
        if isinstance(value, str):
            return value
        raise ConfigError(f"{key}: expected a string, got {_show(value)}", key=key)
    raise TypeError(f"{key}: unsupported configuration type {kind!r}")  # a schema bug


def _show(value: Any) -> str:
    """A value as the user wrote it in TOML."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return json.dumps(value, ensure_ascii=False)
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return str(value)


def _suggest(word: str, choices: list[str]) -> str:
    match = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    if not match:
        lowered = {c.lower(): c for c in choices}
        match = [lowered[word.lower()]] if word.lower() in lowered else []
    return f' (did you mean "{match[0]}"?)' if match else ""


def _unknown_key(key: str, name: str, known: list[str]) -> str:
    hint = _suggest(name, known)
    return f"{key}: unknown key{hint or '; known keys here: ' + ', '.join(known)}"
