"""Typed, documented model parameters with units and bounds.

One :class:`ParamSpec` per parameter; the base models (``paper``, ``classic``) and every effect
declare theirs. The paper's identified values (Han et al. 2022, Sec. 5.3) are the defaults of the
``paper`` preset; values the paper does not give are project choices, marked as such in the doc.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from drivers.validate import bound_problem
from rigctl.errors import InputError, SimulationError


class ParameterError(InputError, SimulationError):
    """A parameter name or value that the model cannot take (unknown, NaN, out of bounds).

    An input error when the user gave it, a simulation error when a fit tried it.
    """


@dataclass(frozen=True)
class ParamSpec:
    """One model parameter: SI unit, default, bounds, whether identification fits it by default."""

    name: str
    default: float
    lower: float
    upper: float
    unit: str
    doc: str
    identify: bool = True
    integer: bool = False
    off: float | None = None
    """The value at which the owning effect has no influence (None for base parameters)."""
    scales_with: str = ""
    """Which quantity of a rig the default is typical for (SCALES), so that a model of another
    rig's data starts it at that rig's scale (docs/identification.md, "Any rig's data"); empty: the
    default holds for any rig (a ratio, an exponent, a count)."""

    def check(self, value: float, owner: str = "") -> float:
        """Return ``value`` as a float, or raise :class:`ParameterError` naming the parameter."""
        label = f"{owner}.{self.name}" if owner and owner != "base" else self.name
        try:
            v = float(value)
        except (TypeError, ValueError) as exc:
            raise ParameterError(f"parameter '{label}': not a number: {value!r}") from exc
        if not math.isfinite(v):
            raise ParameterError(f"parameter '{label}': must be finite, got {v}")
        if bound_problem(v, ge=self.lower, le=self.upper):
            raise ParameterError(
                f"parameter '{label}' = {v:g} {self.unit} is outside its bounds "
                f"[{self.lower:g}, {self.upper:g}] {self.unit}"
            )
        if bound_problem(v, integer=self.integer):
            raise ParameterError(f"parameter '{label}' must be an integer, got {v:g}")
        return v


@dataclass(frozen=True)
class ParamInfo:
    """A parameter of a built model, with its current value (see ``ModelSpec.parameter_table``)."""

    name: str
    value: float
    lower: float
    upper: float
    unit: str
    owner: str
    identify: bool
    doc: str
    scales_with: str = ""
    """As :attr:`ParamSpec.scales_with`."""


SCALES: dict[str, str] = {
    "fn": "the normal force (a reference load)",
    "drive_velocity": "the drive velocity",
    "slip_velocity": "the velocity of a slip, drop / sqrt(K0 M)",
    "slip_length": "the slip distance, drop / K_eff",
    "stick_time": "the stick duration",
    "sample_time": "the sample interval",
    "damping": "sqrt(K0 M)",
}
"""The quantities :attr:`ParamSpec.scales_with` may name."""


def check_values(
    specs: tuple[ParamSpec, ...], values: Mapping[str, float], owner: str
) -> dict[str, float]:
    """Defaults overridden by ``values``; unknown names and bad values raise ParameterError."""
    by_name = {s.name: s for s in specs}
    for key in values:
        if key not in by_name:
            known = ", ".join(sorted(by_name)) or "none"
            raise ParameterError(f"unknown parameter '{key}' for {owner} (known: {known})")
    return {s.name: s.check(values.get(s.name, s.default), owner) for s in specs}


# --- base parameters (classic and paper) ---------------------------------------------------------
BASE_PARAMS: tuple[ParamSpec, ...] = (
    # bounds span rigs from an AFM cantilever to a rock biax: the model of another rig's data takes
    # the data's own scale (docs/identification.md, "Any rig's data")
    ParamSpec("m_kg", 0.048, 1e-9, 1e5, "kg", "mass M of the driven specimen (paper Sec. 5.3)",
              identify=False),
    ParamSpec("c0_N_s_per_m", 4.0, 0.0, 1e8, "N s/m", "drive damping C0 (paper Sec. 5.3)",
              identify=False),
    ParamSpec("k0_N_per_m", 1.475e6, 1e-3, 1e13, "N/m", "drive stiffness K0 (paper Sec. 5.3)"),
    ParamSpec("kts_N_per_m", 0.9e6, 1e-3, 1e13, "N/m",
              "interface tangential stiffness Kts of the stable stage (paper Sec. 5.3)"),
    ParamSpec("mu_s", 0.15, 1e-3, 3.0, "-", "static friction coefficient of the stable stage"),
    ParamSpec("mu_k", 0.10, 0.0, 3.0, "-", "kinetic friction coefficient"),
    ParamSpec("n_elements", 10, 1, 2000, "-", "number N of Jenkins elements (paper Sec. 5.1)",
              identify=False, integer=True),
)
