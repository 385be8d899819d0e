"""Protocol parameters: typed, with units, defaults from the paper and `--param k=v` parsing."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from drivers.validate import bound_problem
from experiments.errors import PlanError

POSITIVE_UNITS = ("m/s", "m", "N")
"""Units whose parameters must be above zero (a zero velocity never ends a slide; a zero travel or
force is no experiment); times may be 0 (no hold)."""

MAX_PLAN_STEPS = 10_000
"""Most steps a protocol's plan may have (docs/experiments.md, "Dry run"): 2,500 NLRE loadings, far
beyond an experiment; more is a typo (``repetitions=1000000000`` built its steps for minutes,
growing by 90 MB a second). A count parameter (a whole number: each counts at least one step) and a
list (each item at least one step) above it are refused here, before any step is built; the dry run
stops at the step past it (:func:`check_step_count`)."""


@dataclass(frozen=True)
class ParamDef:
    name: str
    default: float | int | tuple[float, ...]
    unit: str
    doc: str

    @property
    def is_list(self) -> bool:
        return isinstance(self.default, tuple)

    def parse(self, text: str) -> float | int | tuple[float, ...]:
        """A value from the command line; lists are comma-separated."""
        items = [t.strip() for t in text.split(",")]
        if len(items) > 1 and not all(items):
            raise PlanError(f"parameter '{self.name}': empty item in the list {text!r}")
        items = [t for t in items if t]
        try:
            values = [float(t) for t in items]
        except ValueError:
            raise PlanError(f"parameter '{self.name}': not a number in {text!r}") from None
        if not values:
            raise PlanError(f"parameter '{self.name}': no value given")
        for v in values:
            if bound_problem(v):
                raise PlanError(f"parameter '{self.name}': must be finite, got {text!r}")
            if v < 0.0:
                raise PlanError(f"parameter '{self.name}': {v:g} {self.unit} is negative (a "
                                "magnitude: the protocol sets the direction)")
            if v == 0.0 and self.unit in POSITIVE_UNITS:
                raise PlanError(f"parameter '{self.name}': must be above 0 {self.unit}")
        if self.is_list:
            if len(values) > MAX_PLAN_STEPS:
                raise PlanError(f"parameter '{self.name}': {len(values):,} values, more than a plan "
                                f"may hold (at most {MAX_PLAN_STEPS:,} steps)")
            return tuple(values)
        if len(values) != 1:
            raise PlanError(f"parameter '{self.name}' takes one value, got {text!r}")
        if isinstance(self.default, int):
            if bound_problem(values[0], integer=True, ge=1):
                raise PlanError(f"parameter '{self.name}' must be a whole number >= 1")
            if values[0] > MAX_PLAN_STEPS:
                raise PlanError(f"parameter '{self.name}': {values[0]:,.0f} is more than a plan may "
                                f"hold (at most {MAX_PLAN_STEPS:,} steps)")
            return int(values[0])
        return values[0]


def resolve(
    defs: tuple[ParamDef, ...], given: Mapping[str, Any], protocol: str
) -> dict[str, Any]:
    """Defaults overridden by ``given`` (values or command-line strings); unknown names refused."""
    by_name = {d.name: d for d in defs}
    out: dict[str, Any] = {d.name: d.default for d in defs}
    for key, value in given.items():
        if key not in by_name:
            raise PlanError(
                f"protocol '{protocol}' has no parameter '{key}' (known: {', '.join(by_name)})"
            )
        d = by_name[key]
        out[key] = d.parse(value) if isinstance(value, str) else (
            tuple(float(v) for v in value) if d.is_list else value
        )
    return out


def parse_assignments(items: list[str]) -> dict[str, str]:
    """['fn_N=300', 'holds_s=1,10,100'] -> {'fn_N': '300', 'holds_s': '1,10,100'}; a name given
    twice is refused (which of the two was meant is the user's to say, never the last one's)."""
    out: dict[str, str] = {}
    for item in items:
        if "=" not in item:
            raise PlanError(f"--param '{item}': expected NAME=VALUE")
        k, v = item.split("=", 1)
        k, v = k.strip(), v.strip()
        if k in out:
            raise PlanError(f"--param {k} is given twice ({out[k]} and {v})")
        out[k] = v
    return out


def check_step_count(n_steps: int, protocol: str) -> None:
    """Refuse a plan of more than :data:`MAX_PLAN_STEPS` steps (PlanError naming the count)."""
    if n_steps > MAX_PLAN_STEPS:
        raise PlanError(f"protocol {protocol}: {n_steps:,} steps, more than a plan may hold (at "
                        f"most {MAX_PLAN_STEPS:,}): is a repetition count or a list too long?")
