"""``my_effect``: a worked example of a user effect - temperature-dependent kinetic friction.

    mu_k(T) = mu_k (1 + c_T (T - T_ref))

Polymer friction falls as the polymer softens when warmed (for PMMA on glass the kinetic coefficient
changes by about -0.5 % to -1 % per kelvin near room temperature; e.g. Ludema & Tabor, Wear 9 (1966)
on the temperature dependence of polymer friction). The rig's room temperature is a run condition, so
T is a parameter of the run and c_T the property to identify. Off: c_T = 0 (then T does nothing).

Use it without installing anything:

    rigctl simulate --effect-file my_effect.py --effect my_effect:c_per_K=-0.01,temperature_K=303.15

or register it from a package (pyproject.toml):

    [project.entry-points."rigctl.effects"]
    my_effect = "my_package.my_effect:ThermalKineticFriction"
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model import CoreParams, Effect, ParameterError, ParamSpec


class ThermalKineticFriction(Effect):
    name = "my_effect"
    summary = "kinetic friction falls linearly with the interface temperature"
    signature = "troughs (and drops) differ between runs at different room temperatures"
    reveal_protocol = "the same TLRE repeated at two room temperatures"
    params = (
        ParamSpec("c_per_K", -0.008, -0.05, 0.05, "1/K", "relative change of mu_k per kelvin",
                  off=0.0),
        ParamSpec("temperature_K", 303.15, 253.15, 373.15, "K", "interface temperature T",
                  identify=False, off=293.15),
        ParamSpec("t_ref_K", 293.15, 253.15, 373.15, "K",
                  "temperature at which the base mu_k holds", identify=False, off=293.15),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        factor = 1.0 + values["c_per_K"] * (values["temperature_K"] - values["t_ref_K"])
        if factor <= 0.0:
            raise ParameterError(f"my_effect: mu_k factor {factor:g} <= 0 (c_per_K or T too large)")
        core["mu_k"] = core["mu_k"] * factor
