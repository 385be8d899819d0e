"""``load_dependent_stiffness``: interface stiffness growing with Fn at a falling rate.

    Kt0(Fn) = Kt0 (Fn / Fn_ref)^beta0,   Kts(Fn) = Kts (Fn / Fn_ref)^beta_s,   0 < beta < 1

Paper Sec. 4.1 (Fig. 10c-d): K(1) grows with Fn with a falling growth rate (Raffa et al., paper refs.
47-48: tangential contact stiffness ~ Fn^(1/3) for Hertzian contacts); Fn mainly affects the initial
stage. Off: beta0 = beta_s = 0.
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


class LoadDependentStiffness(Effect):
    name = "load_dependent_stiffness"
    summary = "Kt grows with Fn as a power law with falling growth rate"
    signature = "stick slope and K(1) across a force sweep"
    reveal_protocol = "a normal-force sweep (150-350 N)"
    reveal_run = ("force_sweep", (("forces_N", "150,200,250,300,350"),))
    params = (
        ParamSpec("beta0", 0.5, -1.0, 2.0, "-", "exponent on Kt0 (initial stage)", off=0.0),
        ParamSpec("beta_s", 0.3, -1.0, 2.0, "-", "exponent on Kts (stable stage)", off=0.0),
        ParamSpec("fn_ref_N", 300.0, 1e-6, 1e9, "N", "reference normal force", scales_with="fn",
                  identify=False, off=300.0),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["beta0"] = values["beta0"]
        core["beta_s"] = values["beta_s"]
        core["fn_ref_k_N"] = values["fn_ref_N"]
