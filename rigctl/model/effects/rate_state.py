"""``rate_state``: Dieterich-Ruina rate-and-state friction with the aging law.

    static:   mu_s,eff = mu_s + b ln(1 + theta V_ref / D_c)
    kinetic:  mu_k,eff = mu_k + a ln(1 + |V| / V_ref) + b ln(1 + theta V_ref / D_c)
    state:    d theta / dt = 1 - |V| theta / D_c          (aging law; theta grows as t while stuck)

Dieterich, JGR 84 (1979); Ruina, JGR 88 (1983); the ln(1 + .) regularisation at V -> 0 follows Rice &
Ben-Zion, PNAS 93 (1996). Peaks grow with the log of the hold (stick) time and velocity steps leave
transients. theta starts at theta0 (the age of the contact when the run starts). Off: a = b = 0.
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


class RateState(Effect):
    name = "rate_state"
    summary = "Dieterich-Ruina rate-and-state friction (aging law)"
    signature = "peaks grow with log of hold / stick time; transients after velocity steps"
    reveal_protocol = "slide-hold-slide with holds of 1-100 s"
    reveal_run = ("slide_hold_slide", (("holds_s", "1,10,100"),))
    params = (
        ParamSpec("a", 0.002, 0.0, 0.1, "-", "direct effect a", off=0.0),
        ParamSpec("b", 0.004, 0.0, 0.1, "-", "evolution (aging) effect b", off=0.0),
        ParamSpec("dc_m", 1e-6, 1e-9, 1e-3, "m", "characteristic slip distance D_c",
                  off=1e-6, scales_with="slip_length"),
        ParamSpec("v_ref_m_per_s", 1e-5, 1e-9, 1.0, "m/s", "reference velocity V_ref",
                  identify=False, off=1e-5, scales_with="drive_velocity"),
        ParamSpec("theta0_s", 10.0, 0.0, 1e6, "s", "state (contact age) at the start of the run",
                  identify=False, off=10.0, scales_with="stick_time"),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["rs_a"] = values["a"]
        core["rs_b"] = values["b"]
        core["rs_dc_m"] = values["dc_m"]
        core["rs_v_ref_m_per_s"] = values["v_ref_m_per_s"]

    def initial_theta_s(self, values: Mapping[str, float]) -> float:
        return float(values["theta0_s"])
