"""Declaring configuration keys: a default, a unit, a meaning and bounds, in one place.

Every key of the rig configuration is a dataclass field made with :func:`setting`. The loader
(:mod:`rigctl.config.loader`) checks types and bounds from this declaration, and the reference table
in docs/configuration.md is generated from it (:mod:`rigctl.config.reference`), so the code, the
validation and the documentation cannot drift apart.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from drivers.validate import bound_problem


@dataclass(frozen=True)
class Setting:
    """What the loader and the documentation need to know about one key."""

    doc: str
    unit: str = ""
    ge: float | None = None
    """Inclusive lower bound."""
    gt: float | None = None
    """Exclusive lower bound."""
    le: float | None = None
    """Inclusive upper bound."""


def setting(
    default: Any,
    doc: str,
    *,
    unit: str = "",
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
) -> Any:
    """A dataclass field carrying a :class:`Setting` in its metadata."""
    info = Setting(doc=doc, unit=unit, ge=ge, gt=gt, le=le)
    return dataclasses.field(default=default, metadata={"setting": info})


def section(factory: Any, doc: str) -> Any:
    """A dataclass field holding a nested section (a TOML table)."""
    return dataclasses.field(default_factory=factory, metadata={"setting": Setting(doc=doc)})


_FOREIGN: dict[tuple[type, str], Setting] = {}
"""Settings of dataclasses defined elsewhere (e.g. the drivers' register map) used as sections."""


def describe(cls: type, **settings: Setting) -> None:
    """Attach :class:`Setting` declarations to the fields of a dataclass defined elsewhere."""
    names = {f.name for f in dataclasses.fields(cls)}
    for name, info in settings.items():
        if name not in names:
            raise TypeError(f"{cls.__name__} has no field {name!r}")
        _FOREIGN[(cls, name)] = info


def setting_of(cls: type, field: dataclasses.Field[Any]) -> Setting:
    """The :class:`Setting` of ``cls.field`` (an undeclared field gets an empty one)."""
    info = field.metadata.get("setting") or _FOREIGN.get((cls, field.name))
    return info if isinstance(info, Setting) else Setting(doc="")


def check_bounds(info: Setting, value: float) -> str | None:
    """The violated bound as text (e.g. ``"must be > 0"``), or None (``drivers.validate.bound_problem``)."""
    return bound_problem(value, gt=info.gt, ge=info.ge, le=info.le)
