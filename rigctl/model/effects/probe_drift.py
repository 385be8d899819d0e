"""``probe_drift``: slow linear drift of the displacement probes.

    d1_meas(t) = d1(t) + r t,   t = time since the start of the run (of the stepper, when stepping)

(thermal drift of fibre-optic probes is slow and close to linear over a run; MTI-2100 manual notes
drift with temperature). Only the measurement changes: delta = d1 - d2 grows with time at equal force.
Off: r = 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING

from rigctl.model.effects.base import Effect
from rigctl.model.params import ParamSpec

if TYPE_CHECKING:
    from rigctl.model.result import SimResult


class ProbeDrift(Effect):
    name = "probe_drift"
    summary = "slow drift of the displacement probes"
    signature = "delta residual grows with time at equal force"
    reveal_protocol = "a long hold at constant force recording delta"
    reveal_run = ("slide_hold_slide", (("holds_s", "300"),))
    params = (
        ParamSpec("rate_m_per_s", 5e-8, -1e-5, 1e-5, "m/s", "drift rate r of probe 1", off=0.0,
                  scales_with="drive_velocity"),
    )

    def transform_output(self, result: SimResult, values: Mapping[str, float]) -> None:
        # t_s counts from the start of the run, also in a Stepper's chunks: the drift continues
        result.d1_m += values["rate_m_per_s"] * result.t_s
