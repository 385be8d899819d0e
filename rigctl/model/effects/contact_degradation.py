"""``contact_degradation``: real contact area, hence Kts, decays over cycles to a plateau.

    Kts(n) = Kts (1 + A exp(-(n - 1) / n_c)),   n = 1, 2, ... the stable cycle

Paper Sec. 3.2 (Fig. 7d with Fig. 6d): the average contact intensity Im(i), and with it K(i), falls
over the first cycles and then stays almost unchanged. Kts is the plateau. Off: A = 0.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect, SlipContext
from rigctl.model.params import ParamSpec


class ContactDegradation(Effect):
    name = "contact_degradation"
    summary = "stable-stage stiffness decays over cycles to a plateau"
    signature = "stick slopes decrease cycle by cycle, then settle"
    reveal_protocol = "a long TLRE with many stable cycles"
    reveal_run = ("tlre", (("travel_m", "0.0008"), ("repetitions", "1")))
    params = (
        ParamSpec("amplitude", 0.3, 0.0, 5.0, "-", "initial excess A of Kts", off=0.0),
        ParamSpec("n_cycles", 3.0, 0.1, 1000.0, "-", "decay constant n_c in cycles", off=3.0),
    )

    @staticmethod
    def multiplier(values: Mapping[str, float], cycle: int) -> float:
        return 1.0 + values["amplitude"] * math.exp(-(cycle - 1) / values["n_cycles"])

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["kt_multiplier"] = self.multiplier(values, 1)

    def on_slip_end(
        self, core: CoreParams, values: Mapping[str, float], ctx: SlipContext
    ) -> None:
        # stable cycle n is the stick that follows slip n (cycle 1 starts at the first slip's end)
        core["kt_multiplier"] = self.multiplier(values, ctx.n_slips)
