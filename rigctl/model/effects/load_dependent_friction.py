"""``load_dependent_friction``: mu_s and mu_k as power laws of the normal force.

    mu_s(Fn) = mu_s (Fn / Fn_ref)^alpha_s,   mu_k(Fn) = mu_k (Fn / Fn_ref)^alpha_k

Paper Sec. 4.1 (Fig. 10b): the stable-stage mu_s and mu_k grow with Fn while mu_s,max barely
changes, so mu_s,max is left alone. Power-law load dependence of friction, e.g. Etsion, Friction 2010
(paper refs. 37-39). Off: alpha_s = alpha_k = 0.
"""

from __future__ import annotations

from collections.abc import Mapping

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


class LoadDependentFriction(Effect):
    name = "load_dependent_friction"
    summary = "mu_s, mu_k grow with Fn as power laws"
    signature = "drop sizes across a force sweep scale non-linearly with Fn"
    reveal_protocol = "a normal-force sweep (150-350 N)"
    reveal_run = ("force_sweep", (("forces_N", "150,200,250,300,350"),))
    params = (
        ParamSpec("alpha_s", 0.3, -2.0, 2.0, "-", "exponent on mu_s", off=0.0),
        ParamSpec("alpha_k", 0.3, -2.0, 2.0, "-", "exponent on mu_k", off=0.0),
        ParamSpec("fn_ref_N", 300.0, 1e-6, 1e9, "N", "reference normal force", scales_with="fn",
                  identify=False, off=300.0),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["alpha_s"] = values["alpha_s"]
        core["alpha_k"] = values["alpha_k"]
        core["fn_ref_mu_N"] = values["fn_ref_N"]
