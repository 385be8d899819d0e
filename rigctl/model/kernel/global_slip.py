"""Start and end of a global slip (no element stuck), and the slip's event-table row.

A global slip starts when the last stuck element starts to slide (paper Sec. 3.1: the first one ends
the initial stage) and ends when the specimen velocity returns to zero, where every element sticks
again carrying the kinetic friction (docs/model.md, section 2).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import (
    element_stiffness,
    mu_kinetic_base,
    mu_static,
    stribeck_amplitude,
    stribeck_shape,
)
from rigctl.model.kernel.forces import drive_force
from rigctl.model.layout import (
    E_FN,
    E_PEAK,
    E_SLIP,
    E_STAGE,
    E_T_END,
    E_T_START,
    E_TROUGH,
    E_V_PEAK,
    E_X_START,
    I_GSLIP,
    I_NEVENT,
    I_NSLIP,
    I_SIGN,
    I_SLIPPED,
    I_STAGE,
    P_K0,
    P_KAPPA,
    P_VS,
    S_EV_MIN,
    S_EV_PEAK,
    S_EV_T0,
    S_EV_VMAX,
    S_EV_X0,
    S_K_USED,
    S_SLIP_CUM,
    S_STRIB,
    S_T,
    S_THETA,
    S_V,
    S_X,
    W_STABLE,
    W_UNIFORM,
)


@njit(cache=True)
def start_global_slip(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    mode: np.ndarray,
    ev: np.ndarray,
    xs: float,
    vs: float,
    fn: float,
    sign: int,
) -> None:
    """Every element slides in direction ``sign``; open the slip's row of the event table."""
    n_ev = ist[I_NEVENT]
    ev[n_ev, E_T_START] = fs[S_T]
    ev[n_ev, E_T_END] = np.nan
    fd = drive_force(cp, xs, vs, fs[S_X], fs[S_V])
    ev[n_ev, E_PEAK] = fd
    ev[n_ev, E_STAGE] = ist[I_STAGE]
    ev[n_ev, E_X_START] = fs[S_X]
    ev[n_ev, E_FN] = fn
    fs[S_EV_T0] = fs[S_T]
    fs[S_EV_X0] = fs[S_X]
    fs[S_EV_PEAK] = fd
    fs[S_EV_MIN] = fd
    fs[S_EV_VMAX] = abs(fs[S_V])
    fs[S_STRIB] = 0.0
    if cp[P_VS] > 0.0:
        fs[S_STRIB] = stribeck_amplitude(cp, fn) * stribeck_shape(cp, abs(fs[S_V]))
    ist[I_GSLIP] = 1
    ist[I_SIGN] = sign
    ist[I_SLIPPED] = 1
    ist[I_STAGE] = 1  # the first global slip ends the initial stage (paper Sec. 3.1)
    for i in range(mode.shape[0]):
        mode[i] = sign


@njit(cache=True)
def end_global_slip(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    ev: np.ndarray,
    xs: float,
    vs: float,
    fn: float,
) -> None:
    """Every element sticks again, keeping the force it carried while sliding.

    That force is the kinetic friction at the end of the slip: mu_k (load, wear, rate-and-state at
    V = 0) plus the Stribeck part the elements could actually take up (fs[S_STRIB], not the
    steady-sliding value mu_s at V = 0: docs/model.md, "Re-stick with velocity-dependent
    friction"), and never more than the element's own static threshold (an element of
    ``presliding`` whose threshold lies below the kinetic force re-sticks at its threshold).
    """
    pw1 = weights[W_STABLE]
    p_uni = weights[W_UNIFORM]
    sign = ist[I_SIGN]
    n = g.shape[0]
    k = element_stiffness(cp, 1, fn, n)
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - fs[S_X])
    muk = mu_kinetic_base(cp, fn, 0.0, fs[S_THETA])
    if cp[P_VS] > 0.0:
        muk += min(fs[S_STRIB], stribeck_amplitude(cp, fn))
    mus = mu_static(cp, 1, fn, fs[S_THETA])
    for i in range(n):
        f_i = sign * min(muk * p_uni[i], mus * pw1[i]) * fe
        g[i] = f_i - k * fs[S_X]
        mode[i] = 0
    fs[S_K_USED] = k
    n_ev = ist[I_NEVENT]
    fd = drive_force(cp, xs, vs, fs[S_X], fs[S_V])
    ev[n_ev, E_T_END] = fs[S_T]
    ev[n_ev, E_TROUGH] = min(fd, fs[S_EV_MIN]) if sign > 0 else max(fd, fs[S_EV_MIN])
    ev[n_ev, E_SLIP] = fs[S_X] - fs[S_EV_X0]
    ev[n_ev, E_V_PEAK] = fs[S_EV_VMAX]
    fs[S_SLIP_CUM] += abs(fs[S_X] - fs[S_EV_X0])
    ist[I_NEVENT] = n_ev + 1
    ist[I_NSLIP] += 1
    ist[I_GSLIP] = 0


@njit(cache=True)
def note_slip_speed(fs: np.ndarray, v: float) -> None:
    """Keep the running slip's highest |V| (the event's peak slip velocity) up to date."""
    fs[S_EV_VMAX] = max(fs[S_EV_VMAX], abs(v))


@njit(cache=True)
def note_slip_force(fs: np.ndarray, sign: int, fd: float) -> None:
    """Keep the running slip's extreme drive force (the event's trough) up to date."""
    if sign > 0:
        fs[S_EV_MIN] = min(fs[S_EV_MIN], fd)
    else:
        fs[S_EV_MIN] = max(fs[S_EV_MIN], fd)
