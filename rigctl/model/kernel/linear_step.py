"""The exact step: between events the motion is linear and solved in closed form (docs/model.md, 3).

Each element's state is fixed over the step and the inputs are affine in time, so X obeys
M X'' + C X' + K X = F0 + F1 tau with constant coefficients (:mod:`rigctl.model.modal`). The step
stops at the first event (:mod:`rigctl.model.kernel.event_search`) and applies it: elements start or
stop presliding, a global slip starts (none left stuck) or ends (V back to zero).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import element_stiffness, mu_kinetic, mu_static
from rigctl.model.kernel.event_search import ElementSet, event_possible, first_event
from rigctl.model.kernel.forces import drive_force
from rigctl.model.kernel.global_slip import (
    end_global_slip,
    note_slip_force,
    note_slip_speed,
    start_global_slip,
)
from rigctl.model.kernel.inputs import Segment
from rigctl.model.layout import (
    I_GSLIP,
    I_SIGN,
    I_STAGE,
    P_C0,
    P_CINT,
    P_K0,
    P_KAPPA,
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
from rigctl.model.modal import (
    ModalSolution,
    filtered_drive_force,
    modal_solution,
    position,
    velocity,
)

GOLDEN = 0.6180339887498949  # (sqrt(5) - 1) / 2, the golden-section ratio
THRESHOLD_TOL_M = 1e-12  # an element within this of its threshold position at an event slides


@njit(cache=True)
def extreme_drive_force(
    cp: np.ndarray, sign: int, sol: ModalSolution, seg: Segment, tau_e: float
) -> float:
    """Lowest (sign > 0) or highest drive force over [0, tau_e] of a global slip step.

    Within one slip step the drive force is one half-swing of the slip oscillation plus a slow drive
    term, hence unimodal: golden-section search on the exact solution locates the trough to 1e-12 of
    the step (the end points are included).
    """
    xs0 = seg.xs0
    vs = seg.vs

    def fd_at(tau: float) -> float:
        return sign * drive_force(cp, xs0 + vs * tau, vs, position(sol, tau), velocity(sol, tau))

    lo = 0.0
    hi = tau_e
    best = min(fd_at(lo), fd_at(hi))
    x1 = hi - GOLDEN * (hi - lo)
    x2 = lo + GOLDEN * (hi - lo)
    f1 = fd_at(x1)
    f2 = fd_at(x2)
    for _ in range(60):
        if hi - lo <= 1e-12 * tau_e:
            break
        if f1 < f2:
            hi = x2
            x2 = x1
            f2 = f1
            x1 = hi - GOLDEN * (hi - lo)
            f1 = fd_at(x1)
        else:
            lo = x1
            x1 = x2
            f1 = f2
            x2 = lo + GOLDEN * (hi - lo)
            f2 = fd_at(x2)
    return sign * min(best, f1, f2)


@njit(cache=True)
def peak_speed(sign: int, sol: ModalSolution, tau_e: float) -> float:
    """Highest |V| over [0, tau_e] of a global slip step (V of one sign, one half-swing of the
    slip oscillation: unimodal; golden-section search on the exact solution, ends included)."""
    lo = 0.0
    hi = tau_e
    best = max(sign * velocity(sol, lo), sign * velocity(sol, hi))
    x1 = hi - GOLDEN * (hi - lo)
    x2 = lo + GOLDEN * (hi - lo)
    f1 = sign * velocity(sol, x1)
    f2 = sign * velocity(sol, x2)
    for _ in range(60):
        if hi - lo <= 1e-12 * tau_e:
            break
        if f1 > f2:
            hi = x2
            x2 = x1
            f2 = f1
            x1 = hi - GOLDEN * (hi - lo)
            f1 = sign * velocity(sol, x1)
        else:
            lo = x1
            x1 = x2
            f1 = f2
            x2 = lo + GOLDEN * (hi - lo)
            f2 = sign * velocity(sol, x2)
    return max(best, f1, f2)


@njit(cache=True)
def linear_step(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    ev: np.ndarray,
    seg: Segment,
    h: float,
    allow_events: bool,
) -> tuple[float, bool]:
    """Advance exactly by at most h; stop at the first event and apply it.

    Returns (time advanced, whether a global slip ended).
    """
    n = g.shape[0]
    m = cp[P_M]
    k0 = cp[P_K0]
    c0 = cp[P_C0]
    kk0 = cp[P_KAPPA] * k0
    xs0, vs, fn0, fn1 = seg
    stage = ist[I_STAGE]
    gslip = ist[I_GSLIP] == 1
    x0 = fs[S_X]
    v0 = fs[S_V]
    th0 = fs[S_THETA]
    pw = weights[stage]

    k = 0.0
    n_stuck = 0
    gsum = 0.0
    n_pos = 0
    n_neg = 0
    csl0 = 0.0
    cslh = 0.0
    if gslip:
        sgn = ist[I_SIGN]
        csl0 = sgn * mu_kinetic(cp, fn0, 0.0, th0)
        cslh = sgn * mu_kinetic(cp, fn0 + fn1 * h, 0.0, th0 + h)
    else:
        k = element_stiffness(cp, stage, fn0, n)
        k_old = fs[S_K_USED]
        if k != k_old:
            for i in range(n):
                if mode[i] == 0:
                    g[i] = g[i] + (k_old - k) * x0
            fs[S_K_USED] = k
        spm = 0.0
        for i in range(n):
            if mode[i] == 0:
                n_stuck += 1
                gsum += g[i]
            else:
                spm += mode[i] * pw[i]
                if mode[i] > 0:
                    n_pos += 1
                else:
                    n_neg += 1
        if n_pos + n_neg > 0:
            csl0 = mu_static(cp, stage, fn0, th0) * spm
            cslh = mu_static(cp, stage, fn0 + fn1 * h, th0 + h) * spm

    kst = k * n_stuck
    kp = cp[P_KPAR]  # parallel springs (linear terms): -kp (X - X(0)), in K and F
    kk = k0 + kst - csl0 * kk0 + kp
    cc = c0 + cp[P_CINT]
    q0 = csl0 * (fn0 + kk0 * xs0)
    qh = cslh * (fn0 + fn1 * h + kk0 * (xs0 + vs * h))
    q1 = (qh - q0) / h if h > 0.0 else 0.0
    f0 = k0 * xs0 + c0 * vs - gsum - q0 + kp * cp[P_XPAR]
    f1 = k0 * vs - q1
    sol = modal_solution(m, cc, kk, f0, f1, x0, v0)

    tau_e = h
    event = False
    if allow_events:
        el = ElementSet(stage, gslip, ist[I_SIGN], k, n_stuck, n_pos, n_neg)
        if event_possible(cp, g, mode, pw, el, sol, seg, th0, h):
            t_ev = first_event(cp, g, mode, pw, el, sol, seg, th0, h)
            if t_ev > 0.0:
                tau_e = t_ev
                event = True

    # --- advance the state to tau_e ---
    x1 = position(sol, tau_e)
    v1 = velocity(sol, tau_e)
    tau_s = cp[P_TAU_S]
    if tau_s > 0.0:
        fs[S_YF] = filtered_drive_force(fs[S_YF], 1.0 / tau_s, k0, c0, xs0, vs, sol, tau_e)
    fs[S_X] = x1
    fs[S_V] = v1
    fs[S_T] = fs[S_T] + tau_e
    fs[S_THETA] = th0 + tau_e
    xs1 = xs0 + vs * tau_e
    fn_e = fn0 + fn1 * tau_e
    if gslip:
        note_slip_force(fs, ist[I_SIGN], extreme_drive_force(cp, ist[I_SIGN], sol, seg, tau_e))
        note_slip_speed(fs, peak_speed(ist[I_SIGN], sol, tau_e))
    if not event:
        return tau_e, False

    # --- apply the event ---
    if gslip:
        end_global_slip(cp, weights, fs, ist, g, mode, ev, xs1, vs, fn_e)
        return tau_e, True
    mus = mu_static(cp, stage, fn_e, th0 + tau_e)
    fe_in = fn_e + kk0 * xs1
    fe = fe_in - kk0 * x1
    n_left = 0
    dir_sum = 0
    for i in range(n):
        ci = mus * pw[i]
        if mode[i] == 0:
            xp = (ci * fe_in - g[i]) / (k + ci * kk0)
            xm = (-ci * fe_in - g[i]) / (k - ci * kk0)
            if x1 >= xp - THRESHOLD_TOL_M:
                mode[i] = 1
            elif x1 <= xm + THRESHOLD_TOL_M:
                mode[i] = -1
            else:
                n_left += 1
        elif (mode[i] > 0 and v1 < 0.0) or (mode[i] < 0 and v1 > 0.0):
            # a presliding element sticks again where the slip direction reverses
            g[i] = mode[i] * ci * fe - k * x1
            mode[i] = 0
            n_left += 1
        dir_sum += mode[i]
    if n_left == 0:
        sign = 1 if dir_sum >= 0 else -1
        start_global_slip(cp, fs, ist, mode, ev, xs1, vs, fn_e, sign)
    return tau_e, False
