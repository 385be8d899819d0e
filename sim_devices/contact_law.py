"""Normal contact compliance: normal stage position z -> normal force Fn.

    Fn(z) = k_n * max(0, z - z_contact)^(3/2)

The 3/2 power is Hertz's law for a sphere on a flat (Johnson, *Contact Mechanics*, 1985, eq. 4.23:
P = (4/3) E* R^(1/2) delta^(3/2)); a nominally flat rough contact stiffens with load in the same way
(Greenwood and Williamson 1966 give an exponent between 1 and 3/2 for a Gaussian summit height
distribution), and the series compliance of the loading frame and force sensor is folded into the
single constant k_n. The constant is fixed by one reference point: by default 500 N at 80 um of
approach beyond first touch, i.e. "a few tens of micrometres for the full load" as the rig's
stage-and-frame stack gives. The law is strictly monotonic for z > z_contact and exactly 0 while the
specimens are apart (z <= z_contact): no adhesion, no tension.

Consequence for load control: dFn/dz = 1.5 Fn / (z - z_contact), about 7.9 N per micrometre at
300 N, so one count of the normal stage (0.6 um) is about 4.7 N there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

HERTZ_EXPONENT = 1.5  # Fn ~ approach^1.5 of a Hertzian contact (Johnson, Contact Mechanics, 1985)


@dataclass(frozen=True)
class NormalContactLaw:
    """Fn(z) = k_n * max(0, z - z_contact)^1.5 (see module docstring)."""

    z_contact_m: float = 0.020
    k_n_N_per_m1_5: float = 500.0 / (80e-6) ** HERTZ_EXPONENT

    def __post_init__(self) -> None:
        if not (math.isfinite(self.z_contact_m) and math.isfinite(self.k_n_N_per_m1_5)):
            raise ValueError("contact law constants must be finite")
        if self.k_n_N_per_m1_5 <= 0:
            raise ValueError("k_n must be positive")

    @classmethod
    def from_reference(
        cls, z_contact_m: float, fn_ref_N: float, approach_ref_m: float
    ) -> NormalContactLaw:
        """The law through one point: ``fn_ref_N`` at ``approach_ref_m`` beyond first touch."""
        if fn_ref_N <= 0 or approach_ref_m <= 0:
            raise ValueError("reference force and approach must be positive")
        return cls(z_contact_m, fn_ref_N / approach_ref_m**HERTZ_EXPONENT)

    def fn_N(self, z_m: float) -> float:
        """Normal force at stage position ``z_m`` (0 while apart)."""
        approach = z_m - self.z_contact_m
        if approach <= 0.0:
            return 0.0
        return self.k_n_N_per_m1_5 * approach**HERTZ_EXPONENT

    def z_for_fn_m(self, fn_N: float) -> float:
        """Stage position giving ``fn_N`` (the inverse law; ``fn_N`` must be > 0)."""
        if not (math.isfinite(fn_N) and fn_N > 0):
            raise ValueError(f"normal force must be positive and finite, got {fn_N!r}")
        return self.z_contact_m + (fn_N / self.k_n_N_per_m1_5) ** (1.0 / HERTZ_EXPONENT)
