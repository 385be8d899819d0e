"""Forces of the model's springs: the drive path and the stuck elements' thresholds."""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.layout import P_C0, P_K0, P_KAPPA, P_KPAR, P_XPAR


@njit(cache=True)
def drive_force(cp: np.ndarray, xs: float, vs: float, x: float, v: float) -> float:
    """Force in the drive spring and damper, what the force sensor in the drive path carries:
    K0 (x_stage - X) + C0 (v_stage - V) (docs/model.md, section 1)."""
    return cp[P_K0] * (xs - x) + cp[P_C0] * (vs - v)


@njit(cache=True)
def parallel_spring_force(cp: np.ndarray, x: float) -> float:
    """Force on the slider of the springs that effects declare as linear terms, -k_p (X - X(0)):
    springs from the slider to the frame, relaxed where the slider starts (docs/model.md,
    section 3, "Linear terms"); 0 when there are none."""
    kp = cp[P_KPAR]
    if kp == 0.0:
        return 0.0
    return -kp * (x - cp[P_XPAR])


@njit(cache=True)
def thresholds(
    cp: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw: np.ndarray,
    k: float,
    mus: float,
    fe_in: float,
) -> tuple[float, float]:
    """Lowest forward and highest backward slip position X over the stuck elements.

    Element i starts to slide forward when g_i + k X >= c_i (fe_in - kappa K0 X) and backward when
    g_i + k X <= -c_i (fe_in - kappa K0 X), with c_i = mu_s pw_i and fe_in = Fn + kappa K0 x_stage
    (the kappa terms are the normal coupling; they vanish when it is off).
    """
    kk0 = cp[P_KAPPA] * cp[P_K0]
    lo = np.inf
    hi = -np.inf
    for i in range(g.shape[0]):
        if mode[i] != 0:
            continue
        ci = mus * pw[i]
        xp = (ci * fe_in - g[i]) / (k + ci * kk0)
        xm = (-ci * fe_in - g[i]) / (k - ci * kk0)
        if xp < lo:
            lo = xp
        if xm > hi:
            hi = xm
    return lo, hi
