"""``interface_damping``: viscous damping at the interface.

    M X'' = K0 (x_stage - X) + C0 (v_stage - X') - F_interface - c_i X'

A Kelvin-Voigt dashpot in parallel with the interface (e.g. the dry-friction damping of the elastic
PMMA that paper Sec. 4.1 invokes for the fading stick-slip at 200 N). Ringing after a slip decays
faster and the slip residual follows the velocity. Off: c_i = 0.

The dashpot is linear in the slider's velocity: the effect declares it as a linear term
(:class:`~rigctl.model.effects.base.LinearTerms`, the API a plug-in uses for a drag of its own), and
the exact path integrates it in closed form.
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import Effect, LinearTerms
from rigctl.model.params import ParamSpec


class InterfaceDamping(Effect):
    name = "interface_damping"
    summary = "viscous damping at the interface"
    signature = "ringing after slip decays faster; slip residual ~ velocity"
    reveal_protocol = "a normal-force sweep (faster slips at higher Fn: the damping force grows with them)"
    reveal_run = ("force_sweep", (("forces_N", "150,250,350"),))
    params = (
        ParamSpec("c_N_s_per_m", 30.0, 0.0, 300.0, "N s/m", "interface damping coefficient",
                  off=0.0, scales_with="damping"),
    )

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(damping_N_s_per_m=values["c_N_s_per_m"])
