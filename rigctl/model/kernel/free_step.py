"""Specimens apart: below FN_CONTACT_MIN_N the interface carries nothing and the drive alone acts."""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import element_stiffness
from rigctl.model.kernel.global_slip import end_global_slip
from rigctl.model.kernel.inputs import Segment
from rigctl.model.layout import (
    I_GSLIP,
    I_STAGE,
    P_C0,
    P_K0,
    P_KPAR,
    P_M,
    P_TAU_S,
    P_XPAR,
    S_K_USED,
    S_T,
    S_THETA,
    S_V,
    S_X,
    S_YF,
)
from rigctl.model.modal import filtered_drive_force, modal_solution, position, velocity


@njit(cache=True)
def free_step(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    ev: np.ndarray,
    seg: Segment,
    h: float,
) -> bool:
    """Advance by h with the specimens apart: the drive alone moves the specimen, exactly (with
    the parallel springs of linear terms, which tie the slider to the frame, not to the interface).

    Every element is left stuck and unloaded, so contact resumes with a fresh interface.
    Returns whether a running global slip was closed.
    """
    xs0, vs, fn0, _ = seg
    ended = False
    if ist[I_GSLIP] == 1:
        end_global_slip(cp, weights, fs, ist, g, mode, ev, xs0, vs, fn0)
        ended = True
    k0 = cp[P_K0]
    c0 = cp[P_C0]
    kp = cp[P_KPAR]
    sol = modal_solution(cp[P_M], c0, k0 + kp, k0 * xs0 + c0 * vs + kp * cp[P_XPAR], k0 * vs,
                         fs[S_X], fs[S_V])
    if cp[P_TAU_S] > 0.0:
        fs[S_YF] = filtered_drive_force(fs[S_YF], 1.0 / cp[P_TAU_S], k0, c0, xs0, vs, sol, h)
    fs[S_X] = position(sol, h)
    fs[S_V] = velocity(sol, h)
    fs[S_T] = fs[S_T] + h
    # a new contact is a fresh interface: the initial stage starts again (paper Sec. 2.2: each
    # TLRE repetition, after unloading, shows the initial stage and its mu_s,max threshold again)
    # and the contact's age (rate-and-state theta) restarts at zero
    ist[I_STAGE] = 0
    fs[S_THETA] = 0.0
    k = element_stiffness(cp, 0, fn0, g.shape[0])
    for i in range(g.shape[0]):
        mode[i] = 0
        g[i] = -k * fs[S_X]
    fs[S_K_USED] = k
    return ended
