"""``stribeck``: velocity weakening of the kinetic friction.

    mu_k(V) = mu_k + (mu_s - mu_k) exp(-(|V| / v_s)^d)

Stribeck 1902; the exponential form as in Armstrong-Helouvry et al., Automatica 30 (1994). At the
onset of a slip (V -> 0) the friction equals mu_s and weakens as the slip accelerates, so the stress
drop and the trough depend on the slip velocity. As the slip decelerates, the friction rises towards
the law no faster than the elements' springs are loaded (d(mu Fn)/dt <= Kt |V|, elasto-plastic
friction: Dupont, Hayward, Armstrong & Altpeter, IEEE TAC 47 (2002)), so the elements re-stick
carrying mu_k plus what they took up, not mu_s; the effect then vanishes continuously as v_s -> 0
(docs/model.md, "Re-stick with velocity-dependent friction";
``rigctl.model.kernel.nonlinear_slip.cap_stribeck``).
Off: v_s = 0 (the exponential vanishes exactly).
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


class Stribeck(Effect):
    name = "stribeck"
    summary = "velocity weakening of kinetic friction"
    signature = "stress drop and trough depend on slip velocity / drive velocity"
    reveal_protocol = "velocity steps at two normal loads (the slip velocity scales with Fn)"
    reveal_run = ("velocity_steps", (("velocities_m_s", "1e-06,1e-05,3e-05,1e-05,1e-06"),))
    params = (
        ParamSpec("vs_m_per_s", 5e-3, 0.0, 10.0, "m/s", "Stribeck velocity v_s", off=0.0,
                  scales_with="slip_velocity"),
        ParamSpec("d", 1.0, 0.2, 4.0, "-", "Stribeck exponent d", off=1.0),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["stribeck_vs_m_per_s"] = values["vs_m_per_s"]
        core["stribeck_d"] = values["d"]
