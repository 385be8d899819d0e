"""A model as plain, picklable data: base, effect names, plug-in files and parameter values.

The search evaluates in worker processes, so the model travels as a
:class:`ModelChoice` and is rebuilt there with :func:`rigctl.model.build_model`. Plug-in effects
travel as the paths of their files and are loaded (once per process) through
:func:`rigctl.model.plugins.effect_registry`, so they take part exactly like built-in ones.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from rigctl.model import BASES, ModelSpec, ParamInfo, build_model
from rigctl.model.effects import Effect
from rigctl.model.plugins import effect_registry


@functools.lru_cache(maxsize=16)
def registry_for(effect_files: tuple[str, ...]) -> dict[str, type[Effect]]:
    """Library + entry points + plug-in files (cached per process)."""
    return effect_registry(effect_files)


@dataclass(frozen=True)
class ModelChoice:
    """Which model: base, added effects (in order), plug-in files, parameter values by flat name."""

    base: str = "paper"
    effects: tuple[str, ...] = ()
    values: Mapping[str, float] = field(default_factory=dict)
    effect_files: tuple[str, ...] = ()

    def build(self) -> ModelSpec:
        reg = registry_for(self.effect_files)
        spec = build_model(self.base, effects=list(self.effects), registry=reg)
        return spec.with_values(dict(self.values)) if self.values else spec

    def with_effect(self, name: str) -> ModelChoice:
        return ModelChoice(self.base, (*self.effects, name), dict(self.values), self.effect_files)

    def with_values(self, values: Mapping[str, float]) -> ModelChoice:
        merged = dict(self.values)
        merged.update(values)
        return ModelChoice(self.base, self.effects, merged, self.effect_files)

    def parameter_table(self) -> list[ParamInfo]:
        return self.build().parameter_table()

    def label(self) -> str:
        return self.base + "".join(f" + {e}" for e in self.effects)


def candidate_effects(choice: ModelChoice) -> list[str]:
    """Effects of the library and the plug-ins that the model does not have yet."""
    have = set(BASES.get(choice.base, ())) | set(choice.effects)
    return [name for name in registry_for(choice.effect_files) if name not in have]


def effect_class(name: str, effect_files: tuple[str, ...] = ()) -> type[Effect] | None:
    return registry_for(effect_files).get(name)


def effect_of(parameter: str) -> str:
    """The effect a parameter belongs to (``stribeck.v_s_m_s`` -> ``stribeck``); a base
    parameter (no dot) belongs to none: ``""``."""
    return parameter.split(".", 1)[0] if "." in parameter else ""


def with_effects(choice: ModelChoice, effects: Sequence[str]) -> ModelChoice:
    """``choice`` with ``effects`` added (their parameters at their defaults)."""
    for name in effects:
        choice = choice.with_effect(name)
    return choice


def without_effect(choice: ModelChoice, effect: str) -> ModelChoice:
    """``choice`` without ``effect`` (its parameters dropped, the others kept)."""
    prefix = f"{effect}."
    values = {k: v for k, v in choice.values.items() if not k.startswith(prefix)}
    return ModelChoice(choice.base, tuple(e for e in choice.effects if e != effect), values,
                       choice.effect_files)


def without_effects(choice: ModelChoice, effects: Sequence[str]) -> ModelChoice:
    """``choice`` without each of ``effects`` (:func:`without_effect`)."""
    for name in effects:
        choice = without_effect(choice, name)
    return choice
