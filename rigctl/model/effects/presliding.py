"""``presliding``: smooth pre-sliding before the peak, as a spread of element static thresholds.

The Iwan (1966) parallel-Jenkins form of pre-sliding: element i holds until mu_s Fn P_i m_i with

    m_i = 1 + w (2 zeta_i - 1),   zeta_i = a fixed permutation of (i + 1/2)/N,   mean(m_i) = 1,

and then slides quasi-statically at that force while the others stick, so the stick ramp rounds off
before the peak (Masing hysteresis; equivalent in the continuum limit to Dahl-type pre-sliding, see
Segalman, J. Appl. Mech. 72 (2005)). The peak stays mu_s Fn. The permutation keeps the spread
uncorrelated with the position along x (that correlation is ``stress_evolution``). Off: w = 0.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from rigctl.model.effects.base import CoreParams, Effect
from rigctl.model.params import ParamSpec


def spread_factors(n_elements: int, spread: float) -> np.ndarray:
    """Threshold multipliers m_i (mean exactly 1)."""
    order = (np.arange(n_elements) * 7 + 3) % n_elements
    if np.unique(order).size != n_elements:  # 7 shares a factor with n: fall back to a reversal
        order = np.arange(n_elements)[::-1]
    zeta = (order + 0.5) / n_elements
    return 1.0 + spread * (2.0 * zeta - 1.0)


class Presliding(Effect):
    name = "presliding"
    summary = "Iwan/Dahl-type pre-sliding: the stick ramp rounds off before the peak"
    signature = "the stick ramp rounds off before the peak"
    reveal_protocol = "a slow TLRE (1 um/s) resolving the last newtons before each peak"
    reveal_run = ("tlre", (("velocity_m_s", "1e-06"), ("repetitions", "1")))
    params = (
        ParamSpec("spread", 0.5, 0.0, 0.95, "-", "relative spread w of element thresholds",
                  off=0.0),
    )

    def apply(self, core: CoreParams, values: Mapping[str, float]) -> None:
        core["threshold_spread"] = values["spread"]

    def element_threshold_factors(
        self, values: Mapping[str, float], n_elements: int
    ) -> np.ndarray | None:
        return spread_factors(n_elements, values["spread"])
