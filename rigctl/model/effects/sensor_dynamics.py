"""``sensor_dynamics``: finite force-sensor bandwidth (first-order low-pass).

    tau_s dF_meas/dt = F_drive - F_meas

integrated exactly with the mechanics (rigctl.model.modal.filtered_drive_force), so the sampled
output is what a sensor with corner frequency 1 / (2 pi tau_s) would give. Drops are smeared in time
and fall behind the slip the probes see (about ln 2 tau_s at half-way, the event feature
``drop_delay_s``: a heavier slider smears the drop too, but its force follows its slip within a
small part of the slip's duration); the residual of a model without it follows -tau_s dFt/dt.
Off: tau_s = 0 (ideal sensor).
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


class SensorDynamics(Effect):
    name = "sensor_dynamics"
    summary = "first-order low-pass of the force sensor"
    signature = "drops smeared in time and behind the probes' slip; residual ~ -tau dFt/dt"
    reveal_protocol = "any run with slips, looking at the drop shape at full rate"
    reveal_run = ("tlre", (("repetitions", "1"),))
    params = (
        ParamSpec("tau_s", 3e-3, 0.0, 0.5, "s", "sensor time constant", off=0.0,
                  scales_with="sample_time"),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["sensor_tau_s"] = values["tau_s"]
