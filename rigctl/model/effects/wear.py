"""``wear``: friction evolving with accumulated slip distance.

    mu_s(s) = mu_s + dmu_s (1 - exp(-s / s_w)),   mu_k(s) = mu_k + dmu_k (1 - exp(-s / s_w))

s is the cumulative global-slip distance, updated at the end of each slip (a slip is micrometres
against s_w of hundreds). Paper Sec. 2.2 (Fig. 4): roughness grows with repeated sliding. Archard-type
running-in with an exponential approach (Blau, Tribol. Int. 38 (2005)). Off: dmu_s = dmu_k = 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect, SlipContext
from rigctl.model.params import ParamSpec


class Wear(Effect):
    name = "wear"
    summary = "friction coefficients evolve with cumulative slip distance"
    signature = "event sizes drift with cumulative slip"
    reveal_protocol = "a long TLRE (many slips) or repeated TLREs on the same track"
    reveal_run = ("tlre", (("travel_m", "0.0008"), ("repetitions", "2")))
    params = (
        ParamSpec("dmu_s", 0.02, -0.5, 0.5, "-", "asymptotic change of mu_s", off=0.0),
        ParamSpec("dmu_k", 0.02, -0.5, 0.5, "-", "asymptotic change of mu_k", off=0.0),
        ParamSpec("s_wear_m", 3e-4, 1e-6, 1.0, "m", "wear length s_w",
                  off=3e-4, scales_with="slip_length"),
    )

    def invalid_reason(
        self, values: Mapping[str, float], base: Mapping[str, float]
    ) -> str | None:
        mu_s = base["mu_s"] + values["dmu_s"]
        mu_k = base["mu_k"] + values["dmu_k"]
        if mu_k >= mu_s:
            return (f"wear: mu_k + dmu_k ({mu_k:g}) reaches mu_s + dmu_s ({mu_s:g}): no stick-slip "
                    "once worn in")
        return None

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["dmu_s"] = 0.0
        core["dmu_k"] = 0.0

    def on_slip_end(
        self, core: CoreParams, values: Mapping[str, float], ctx: SlipContext
    ) -> None:
        f = 1.0 - math.exp(-ctx.cumulative_slip_m / values["s_wear_m"])
        core["dmu_s"] = values["dmu_s"] * f
        core["dmu_k"] = values["dmu_k"] * f
