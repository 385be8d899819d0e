"""User effects without editing rigctl: a Python file given by path, or an installed entry point.

A plug-in module defines one or more subclasses of :class:`rigctl.model.Effect` (docs/effects.md).
``load_effect_file(path)`` imports the file under a private module name and returns those classes;
``entry_point_effects()`` loads the classes registered in the ``rigctl.effects`` entry-point group.
Anything wrong with a plug-in raises :class:`EffectPluginError` naming the file (or entry point).
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import importlib.util
import math
import os
import sys
from collections.abc import Iterable
from pathlib import Path

from rigctl.errors import InputError
from rigctl.model.effects import LIBRARY, Effect
from rigctl.model.params import ParamSpec

ENTRY_POINT_GROUP = "rigctl.effects"  # where installed packages register effects (docs/effects.md)


class EffectPluginError(InputError):
    """A plug-in effect that cannot be loaded or is not a valid effect."""


def validate_effect_class(cls: type[Effect], origin: str) -> None:
    """Check what the engine relies on: a new name, parameter specs with off values."""
    if not cls.name or not cls.name.isidentifier():
        raise EffectPluginError(f"{origin}: effect {cls.__name__} needs a `name` identifier")
    if cls.name in LIBRARY and LIBRARY[cls.name] is not cls:
        raise EffectPluginError(
            f"{origin}: effect name '{cls.name}' is taken by the built-in library"
        )
    seen: set[str] = set()
    for p in cls.params:
        if not isinstance(p, ParamSpec):
            raise EffectPluginError(f"{origin}: {cls.__name__}.params must hold ParamSpec objects")
        if p.name in seen:
            raise EffectPluginError(
                f"{origin}: parameter '{p.name}' of effect '{cls.name}' is declared twice"
            )
        seen.add(p.name)
        if not p.unit:
            raise EffectPluginError(
                f"{origin}: parameter '{p.name}' of effect '{cls.name}' has no unit ('-' if none)"
            )
        if p.off is None and cls.off_values is Effect.off_values:
            raise EffectPluginError(
                f"{origin}: parameter '{p.name}' of effect '{cls.name}' has no `off` value"
            )
        if not all(math.isfinite(x) for x in (p.lower, p.default, p.upper)):
            raise EffectPluginError(f"{origin}: bounds or default of '{p.name}' are not finite")
        if not (p.lower <= p.default <= p.upper):
            raise EffectPluginError(
                f"{origin}: default of '{p.name}' ({p.default}) is outside its bounds"
            )
        if p.off is not None and not (p.lower <= p.off <= p.upper):
            raise EffectPluginError(
                f"{origin}: off value of '{p.name}' ({p.off}) is outside its bounds"
            )
    try:
        cls()
    except Exception as exc:  # a plug-in's constructor may fail any way at all
        raise EffectPluginError(f"{origin}: cannot instantiate {cls.__name__}: {exc}") from exc


def load_effect_file(path: str | Path) -> list[type[Effect]]:
    """Import a plug-in file and return the Effect subclasses it defines."""
    p = Path(path)
    origin = str(p)
    if not p.is_file():
        raise EffectPluginError(f"{origin}: no such effect file")
    digest = hashlib.sha1(str(p.resolve()).encode()).hexdigest()[:12]
    mod_name = f"rigctl_user_effect_{digest}"
    spec = importlib.util.spec_from_file_location(mod_name, p)
    if spec is None or spec.loader is None:
        raise EffectPluginError(f"{origin}: not a loadable Python file")
    module = importlib.util.module_from_spec(spec)
    sys.modules[mod_name] = module
    try:
        spec.loader.exec_module(module)
    except Exception as exc:
        sys.modules.pop(mod_name, None)
        raise EffectPluginError(
            f"{origin}: error while loading the effect file: {type(exc).__name__}: {exc}"
        ) from exc
    found = [
        obj
        for obj in vars(module).values()
        if isinstance(obj, type) and issubclass(obj, Effect) and obj is not Effect
        and obj.__module__ == mod_name
    ]
    if not found:
        raise EffectPluginError(f"{origin}: defines no subclass of rigctl.model.Effect")
    for cls in found:
        validate_effect_class(cls, origin)
    return found


def entry_point_effects() -> list[type[Effect]]:
    """Effect classes registered by installed packages under the ``rigctl.effects`` group."""
    out: list[type[Effect]] = []
    for ep in importlib.metadata.entry_points(group=ENTRY_POINT_GROUP):
        origin = f"entry point '{ep.name}' ({ep.value})"
        try:
            obj = ep.load()
        except Exception as exc:
            raise EffectPluginError(f"{origin}: cannot load: {exc}") from exc
        if not (isinstance(obj, type) and issubclass(obj, Effect)):
            raise EffectPluginError(f"{origin}: is not a subclass of rigctl.model.Effect")
        validate_effect_class(obj, origin)
        out.append(obj)
    return out


ENABLE_ENV = "RIGCTL_PLUGINS"
"""Set to 1 (``--plugins`` does it for the command and its worker processes) to load the effects
installed packages register: their code runs only when the user asked for it."""


def entry_points_enabled() -> bool:
    return os.environ.get(ENABLE_ENV, "").strip().lower() in ("1", "yes", "true", "on")


def enable_entry_points() -> list[str]:
    """Enable entry-point effects for this process and its children; the loaded ones as
    ``name (module:Class)`` for the command to list."""
    os.environ[ENABLE_ENV] = "1"
    return [f"{cls.name} ({cls.__module__}:{cls.__qualname__})" for cls in entry_point_effects()]


def effect_registry(effect_files: Iterable[str | Path] = ()) -> dict[str, type[Effect]]:
    """Library + the given files, by name; plus the entry-point plug-ins of installed packages
    when enabled (:data:`ENABLE_ENV`; files win over entry points)."""
    reg: dict[str, type[Effect]] = dict(LIBRARY)
    if entry_points_enabled():
        for cls in entry_point_effects():
            reg[cls.name] = cls
    for f in effect_files:
        for cls in load_effect_file(f):
            reg[cls.name] = cls
    return reg
