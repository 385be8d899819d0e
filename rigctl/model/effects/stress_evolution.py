"""``stress_evolution``: the paper's P_linear -> P_uniform variation of the normal-load shares.

Han et al. 2022, Secs. 3.2 and 5.2: in the initial stage the equivalent stress distribution is a ramp
along x (the back end carries less), the interface stiffness is Kt0 and the friction coefficient
mu_s,max; element i slides when its force reaches mu_s,max Fn P_linear(i), so the back end slips
first and the instantaneous stiffness dFt/d(delta) falls step by step until the whole interface
slides. From the first global slip on, P is uniform, the stiffness Kts and the coefficients mu_s/mu_k.

    P_linear(i) = (1 + s (2 xi_i - 1)) / N,  xi_i = (i + 1/2) / N,  sum_i P_linear(i) = 1

(the ramp form is the paper's; its slope s is a project choice, identified from data). Kt0 = 1.5e6 N/m
and s = 0.9 are project defaults: the paper gives neither. Off: s = 0, Kt0 = Kts, mu_s,max = mu_s.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


def p_linear(n_elements: int, slope: float) -> np.ndarray:
    """Equivalent stress distribution of the initial stage, element 0 at the back end."""
    xi = (np.arange(n_elements) + 0.5) / n_elements
    return (1.0 + slope * (2.0 * xi - 1.0)) / n_elements


class StressEvolution(Effect):
    name = "stress_evolution"
    summary = "initial stage with a linear stress distribution, Kt0 and mu_s,max (paper Sec. 5.2)"
    signature = "initial-stage Ft-delta curve bends while the model's stays straight"
    reveal_protocol = "TLRE: a tangential run from rest, analysing the initial stage"
    reveal_run = ("tlre", (("repetitions", "1"),))
    params = (
        ParamSpec("kt0_N_per_m", 1.5e6, 1e-3, 1e13, "N/m",
                  "interface stiffness of the initial stage Kt0 (project default; paper gives none)"),
        ParamSpec("mu_smax", 0.2, 1e-3, 3.0, "-",
                  "maximum static friction coefficient of the initial stage (paper Sec. 5.3)"),
        ParamSpec("p_slope", 0.9, 0.0, 0.999, "-",
                  "slope s of P_linear across the contact (project default)", off=0.0),
    )

    def off_values(self, base: Mapping[str, float]) -> dict[str, float]:
        return {
            "kt0_N_per_m": base["kts_N_per_m"],
            "mu_smax": base["mu_s"],
            "p_slope": 0.0,
        }

    def invalid_reason(
        self, values: Mapping[str, float], base: Mapping[str, float]
    ) -> str | None:
        if base["mu_k"] >= values["mu_smax"]:
            return (f"mu_k ({base['mu_k']:g}) reaches mu_smax ({values['mu_smax']:g}): no stick-slip "
                    "in the initial stage")
        return None

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["kt0_N_per_m"] = values["kt0_N_per_m"]
        core["mu_smax"] = values["mu_smax"]
        core["p_slope"] = values["p_slope"]
