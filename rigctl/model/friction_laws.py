"""Friction coefficients and stiffness of the interface, as compiled scalar functions.

These are the constitutive laws of the model (docs/model.md, sections 2 and 4). Each reduces to the
paper's constant values when the effect parameters that enter it are at their ``off`` values:

* static coefficient (paper Sec. 5.2): mu_s,max in the initial stage, mu_s in the stable stage;
  ``load_dependent_friction`` multiplies by (Fn/Fn_ref)^alpha_s; ``wear`` adds dmu_s; the aging part of
  ``rate_state`` adds b ln(1 + theta V_ref / Dc) (Dieterich 1979; Ruina 1983, aging law).
* kinetic coefficient: mu_k, times (Fn/Fn_ref)^alpha_k, plus dmu_k; ``stribeck`` adds
  (mu_s - mu_k) exp(-(|V|/v_s)^d) (Stribeck curve, docs/effects.md);
  ``rate_state`` adds a ln(1 + |V|/V_ref) + b ln(1 + theta V_ref / Dc) (regularised at V -> 0,
  Rice & Ben-Zion 1996).
* element stiffness: Kt/N with Kt = Kt0 (initial) or Kts (stable) (paper Sec. 5.2);
  ``load_dependent_stiffness`` multiplies by (Fn/Fn_ref)^beta (Raffa et al., paper refs. 47-48);
  ``contact_degradation`` multiplies Kts by a per-cycle factor.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigctl.model.layout import (
    P_ALPHA_K,
    P_ALPHA_S,
    P_BETA0,
    P_BETAS,
    P_DMU_K,
    P_DMU_S,
    P_FNREF_K,
    P_FNREF_MU,
    P_KT0,
    P_KT_MULT,
    P_KTS,
    P_MUK,
    P_MUS,
    P_MUSMAX,
    P_RS_A,
    P_RS_B,
    P_RS_DC,
    P_RS_VREF,
    P_SD,
    P_VS,
)

_FN_FLOOR_N = 1e-6  # power laws of Fn read Fn >= 1 uN: finite at Fn = 0 (negative exponents)


@njit(cache=True)
def load_factor(fn_N: float, fn_ref_N: float, exponent: float) -> float:
    """(Fn / Fn_ref)^exponent, exactly 1 when the exponent is 0; Fn floored at 1 uN."""
    if exponent == 0.0:
        return 1.0
    return (max(fn_N, _FN_FLOOR_N) / fn_ref_N) ** exponent


@njit(cache=True)
def aging_term(cp: np.ndarray, theta_s: float) -> float:
    """Rate-and-state state term b ln(1 + theta V_ref / Dc); 0 when b = 0."""
    b = cp[P_RS_B]
    if b == 0.0:
        return 0.0
    return b * math.log(1.0 + theta_s * cp[P_RS_VREF] / cp[P_RS_DC])


@njit(cache=True)
def mu_static(cp: np.ndarray, stage: int, fn_N: float, theta_s: float) -> float:
    """Static (stick) friction coefficient of the stage."""
    if stage == 0:
        mu = cp[P_MUSMAX]
    else:
        mu = cp[P_MUS] * load_factor(fn_N, cp[P_FNREF_MU], cp[P_ALPHA_S]) + cp[P_DMU_S]
    return mu + aging_term(cp, theta_s)


@njit(cache=True)
def mu_kinetic_base(cp: np.ndarray, fn_N: float, v_abs_m_s: float, theta_s: float) -> float:
    """Kinetic coefficient without the Stribeck term: mu_k (load, wear) plus rate-and-state."""
    muk = cp[P_MUK] * load_factor(fn_N, cp[P_FNREF_MU], cp[P_ALPHA_K]) + cp[P_DMU_K]
    a = cp[P_RS_A]
    if a != 0.0:
        muk += a * math.log(1.0 + v_abs_m_s / cp[P_RS_VREF])
    return muk + aging_term(cp, theta_s)


@njit(cache=True)
def stribeck_amplitude(cp: np.ndarray, fn_N: float) -> float:
    """Height of the Stribeck term, mu_s - mu_k of the stable stage at Fn; 0 when stribeck is off."""
    if cp[P_VS] <= 0.0:
        return 0.0
    mus = cp[P_MUS] * load_factor(fn_N, cp[P_FNREF_MU], cp[P_ALPHA_S]) + cp[P_DMU_S]
    muk = cp[P_MUK] * load_factor(fn_N, cp[P_FNREF_MU], cp[P_ALPHA_K]) + cp[P_DMU_K]
    return mus - muk


@njit(cache=True)
def stribeck_shape(cp: np.ndarray, v_abs_m_s: float) -> float:
    """exp(-(|V| / v_s)^d), 1 at V = 0 (call only with v_s > 0)."""
    return math.exp(-((v_abs_m_s / cp[P_VS]) ** cp[P_SD]))


@njit(cache=True)
def mu_kinetic(cp: np.ndarray, fn_N: float, v_abs_m_s: float, theta_s: float) -> float:
    """Steady-sliding kinetic (slip) friction coefficient at slip speed |V|.

    During a global slip the kernel caps the Stribeck part by what the elements can carry
    (docs/model.md, "Re-stick with velocity-dependent friction"); this is the uncapped law.
    """
    muk = mu_kinetic_base(cp, fn_N, v_abs_m_s, theta_s)
    if cp[P_VS] > 0.0:
        muk += stribeck_amplitude(cp, fn_N) * stribeck_shape(cp, v_abs_m_s)
    return muk


@njit(cache=True)
def slip_is_nonlinear(cp: np.ndarray) -> bool:
    """True when the kinetic friction depends on the slip state (needs numerical integration)."""
    return cp[P_VS] > 0.0 or cp[P_RS_A] != 0.0 or cp[P_RS_B] != 0.0


@njit(cache=True)
def element_stiffness(cp: np.ndarray, stage: int, fn_N: float, n_elements: int) -> float:
    """Tangential stiffness kt of one Jenkins element, Kt / N."""
    if stage == 0:
        kt = cp[P_KT0] * load_factor(fn_N, cp[P_FNREF_K], cp[P_BETA0])
    else:
        kt = cp[P_KTS] * cp[P_KT_MULT] * load_factor(fn_N, cp[P_FNREF_K], cp[P_BETAS])
    return kt / n_elements
