"""``normal_coupling``: the normal force moves with the tangential load (tilt, machine compliance).

    Fn,eff = Fn + kappa K0 (x_stage - X)

The tangential force in the drive path tilts the loading frame and changes the normal load the
interface and the force sensor see (a linear moment-arm coupling; e.g. the tilt of paper Fig. 2's
angle adjusters). The friction thresholds use Fn,eff, so the residual of a model without it correlates
with Ft and Fn moves during a slip. Off: kappa = 0.

Fn,eff is linear in the slider's position X: the effect declares it as a linear term
(:class:`~rigctl.model.effects.base.LinearTerms`), which the exact path integrates in closed form.
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import Effect, LinearTerms
from rigctl.model.params import ParamSpec


class NormalCoupling(Effect):
    name = "normal_coupling"
    summary = "Fn varies with the tangential force"
    signature = "residual correlates with Ft; Fn moves during slip"
    reveal_protocol = "TLRE recording Fn at full rate (its jumps at slips)"
    reveal_run = ("tlre", (("repetitions", "1"),))
    params = (
        ParamSpec("kappa", 0.1, -0.5, 0.5, "-", "dFn / dFt coupling", off=0.0),
    )

    def linear_terms(self, values: Mapping[str, float]) -> LinearTerms:
        return LinearTerms(normal_per_drive_force=values["kappa"])
