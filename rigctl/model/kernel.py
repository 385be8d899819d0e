"""The compiled event-driven integrator of the stick-slip model (docs/model.md, section 3).

State: specimen position X and velocity V, the sensor filter output, the rate-and-state variable
theta, and for each Jenkins element either *stuck* (force f_i = g_i + kt X, offset g_i stored) or
*presliding* (force held at its static threshold +-c_i Fn_eff, paper Sec. 5.2: the back end slips
first in the initial stage). When no element is stuck the interface slides as a whole (*global slip*)
at the kinetic friction until the specimen velocity returns to zero, when every element sticks again.

Between events the problem is linear with constant coefficients and is solved exactly
(:mod:`rigctl.model.modal`); events are found on a grid of at most 1/16 of the ringing period with a
rigorous envelope test to skip intervals that cannot hold one, then located by bisection to round-off.
When the kinetic friction depends on the slip velocity or state (``stribeck``, ``rate_state``) the
global slip alone is integrated with classical RK4 at 1/64 of the drive period (convergence tested).
The Stribeck part of the slip friction rises no faster than elastic loading of the elements allows, and
the elements re-stick carrying that, never more than their static thresholds (docs/model.md, section 2,
"Re-stick with velocity-dependent friction").
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from rigctl.model.fastpath import fast_stick_run
from rigctl.model.friction_laws import (
    element_stiffness,
    mu_kinetic,
    mu_kinetic_base,
    mu_static,
    slip_is_nonlinear,
    stribeck_amplitude,
    stribeck_shape,
)
from rigctl.model.layout import (
    E_FN,
    E_PEAK,
    E_SLIP,
    E_STAGE,
    E_T_END,
    E_T_START,
    E_TROUGH,
    E_X_START,
    FN_CONTACT_MIN_N,
    I_CHATTER,
    I_GSLIP,
    I_KNOT,
    I_NEVENT,
    I_NSLIP,
    I_OUT,
    I_SIGN,
    I_SLIPPED,
    I_STAGE,
    MAX_STEPS_PER_SAMPLE,
    P_C0,
    P_CINT,
    P_K0,
    P_KAPPA,
    P_M,
    P_RS_A,
    P_RS_B,
    P_RS_DC,
    P_TAU_S,
    P_VS,
    RET_DONE,
    RET_EVENT_TABLE_FULL,
    RET_SLIP_END,
    S_EV_MIN,
    S_EV_PEAK,
    S_EV_T0,
    S_EV_X0,
    S_K_USED,
    S_SLIP_CUM,
    S_STRIB,
    S_T,
    S_THETA,
    S_V,
    S_X,
    S_YF,
)
from rigctl.model.modal import filtered_drive_force, modal_solution, position, velocity

_BISECT_ITERS = 60


@njit(cache=True)
def _interp(kt_t: np.ndarray, kt_v: np.ndarray, j: int, t: float) -> float:
    t0 = kt_t[j]
    dt = kt_t[j + 1] - t0
    if dt <= 0.0:
        return kt_v[j + 1]
    return kt_v[j] + (kt_v[j + 1] - kt_v[j]) * (t - t0) / dt


@njit(cache=True)
def _slope(kt_t: np.ndarray, kt_v: np.ndarray, j: int) -> float:
    dt = kt_t[j + 1] - kt_t[j]
    if dt <= 0.0:
        return 0.0
    return (kt_v[j + 1] - kt_v[j]) / dt


@njit(cache=True)
def _thresholds(
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


@njit(cache=True)
def _drive_force(cp: np.ndarray, xs: float, vs: float, x: float, v: float) -> float:
    """Force in the drive spring and damper, what the force sensor in the drive path carries."""
    return cp[P_K0] * (xs - x) + cp[P_C0] * (vs - v)


@njit(cache=True)
def _start_global_slip(
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
    n_ev = ist[I_NEVENT]
    ev[n_ev, E_T_START] = fs[S_T]
    ev[n_ev, E_T_END] = np.nan
    fd = _drive_force(cp, xs, vs, fs[S_X], fs[S_V])
    ev[n_ev, E_PEAK] = fd
    ev[n_ev, E_STAGE] = ist[I_STAGE]
    ev[n_ev, E_X_START] = fs[S_X]
    ev[n_ev, E_FN] = fn
    fs[S_EV_T0] = fs[S_T]
    fs[S_EV_X0] = fs[S_X]
    fs[S_EV_PEAK] = fd
    fs[S_EV_MIN] = fd
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
def _end_global_slip(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw1: np.ndarray,
    p_uni: np.ndarray,
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
    fd = _drive_force(cp, xs, vs, fs[S_X], fs[S_V])
    ev[n_ev, E_T_END] = fs[S_T]
    ev[n_ev, E_TROUGH] = min(fd, fs[S_EV_MIN]) if sign > 0 else max(fd, fs[S_EV_MIN])
    ev[n_ev, E_SLIP] = fs[S_X] - fs[S_EV_X0]
    fs[S_SLIP_CUM] += abs(fs[S_X] - fs[S_EV_X0])
    ist[I_NEVENT] = n_ev + 1
    ist[I_NSLIP] += 1
    ist[I_GSLIP] = 0


_GOLDEN = 0.6180339887498949


@njit(cache=True)
def _extreme_drive_force(
    cp: np.ndarray,
    sign: int,
    xs0: float,
    vs: float,
    a: float,
    b: float,
    c1: complex,
    c2: complex,
    l1: complex,
    l2: complex,
    tau_e: float,
) -> float:
    """Lowest (sign > 0) or highest drive force over [0, tau_e] of a global slip step.

    Within one slip step the drive force is one half-swing of the slip oscillation plus a slow drive
    term, hence unimodal: golden-section search on the exact solution locates the trough to 1e-12 of
    the step (the end points are included).
    """

    def fd_at(tau: float) -> float:
        return sign * _drive_force(
            cp, xs0 + vs * tau, vs, position(a, b, c1, c2, l1, l2, tau),
            velocity(b, c1, c2, l1, l2, tau),
        )

    lo = 0.0
    hi = tau_e
    best = min(fd_at(lo), fd_at(hi))
    x1 = hi - _GOLDEN * (hi - lo)
    x2 = lo + _GOLDEN * (hi - lo)
    f1 = fd_at(x1)
    f2 = fd_at(x2)
    for _ in range(60):
        if hi - lo <= 1e-12 * tau_e:
            break
        if f1 < f2:
            hi = x2
            x2 = x1
            f2 = f1
            x1 = hi - _GOLDEN * (hi - lo)
            f1 = fd_at(x1)
        else:
            lo = x1
            x1 = x2
            f1 = f2
            x2 = lo + _GOLDEN * (hi - lo)
            f2 = fd_at(x2)
    return sign * min(best, f1, f2)


@njit(cache=True)
def _linear_step(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw0: np.ndarray,
    pw1: np.ndarray,
    p_uni: np.ndarray,
    ev: np.ndarray,
    xs0: float,
    vs: float,
    fn0: float,
    fn1: float,
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
    stage = ist[I_STAGE]
    gslip = ist[I_GSLIP] == 1
    x0 = fs[S_X]
    v0 = fs[S_V]
    th0 = fs[S_THETA]
    pw = pw0 if stage == 0 else pw1

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
    kk = k0 + kst - csl0 * kk0
    cc = c0 + cp[P_CINT]
    q0 = csl0 * (fn0 + kk0 * xs0)
    qh = cslh * (fn0 + fn1 * h + kk0 * (xs0 + vs * h))
    q1 = (qh - q0) / h if h > 0.0 else 0.0
    f0 = k0 * xs0 + c0 * vs - gsum - q0
    f1 = k0 * vs - q1
    a, b, c1, c2, l1, l2 = modal_solution(m, cc, kk, f0, f1, x0, v0)

    tau_e = h
    event = False
    if allow_events:
        # --- envelope test: can an event happen in [0, h] at all? ---
        x_osc = abs(c1) + abs(c2)
        v_osc = abs(c1 * l1) + abs(c2 * l2)
        xa = a
        xb = a + b * h
        x_max = max(xa, xb) + x_osc
        x_min = min(xa, xb) - x_osc
        v_max = b + v_osc
        v_min = b - v_osc
        possible = False
        if gslip:
            possible = (v_min <= 0.0) if ist[I_SIGN] > 0 else (v_max >= 0.0)
        else:
            if n_stuck > 0:
                mus_a = mu_static(cp, stage, fn0, th0)
                mus_b = mu_static(cp, stage, fn0 + fn1 * h, th0 + h)
                lo_a, hi_a = _thresholds(cp, g, mode, pw, k, mus_a, fn0 + kk0 * xs0)
                lo_b, hi_b = _thresholds(
                    cp, g, mode, pw, k, mus_b, fn0 + fn1 * h + kk0 * (xs0 + vs * h)
                )
                if x_max >= min(lo_a, lo_b) or x_min <= max(hi_a, hi_b):
                    possible = True
            if n_pos > 0 and v_min < 0.0:
                possible = True
            if n_neg > 0 and v_max > 0.0:
                possible = True

        if possible:
            # --- grid scan at <= 1/16 of the ringing period, then bisection ---
            wd = abs(l1.imag)
            step = h / 8.0
            if wd > 0.0:
                step = min(h, 2.0 * math.pi / wd / 16.0)
            n_grid = max(1, math.ceil(h / step))
            lo_t = 0.0
            hi_t = -1.0
            for j in range(1, n_grid + 1):
                tj = h * j / n_grid
                if _event_at(
                    cp, g, mode, pw, k, stage, gslip, ist[I_SIGN], n_stuck, n_pos, n_neg,
                    a, b, c1, c2, l1, l2, tj, xs0, vs, fn0, fn1, th0,
                ):
                    hi_t = tj
                    break
                lo_t = tj
            if hi_t > 0.0:
                for _ in range(_BISECT_ITERS):
                    mid = 0.5 * (lo_t + hi_t)
                    if mid <= lo_t or mid >= hi_t:
                        break
                    if _event_at(
                        cp, g, mode, pw, k, stage, gslip, ist[I_SIGN], n_stuck, n_pos, n_neg,
                        a, b, c1, c2, l1, l2, mid, xs0, vs, fn0, fn1, th0,
                    ):
                        hi_t = mid
                    else:
                        lo_t = mid
                tau_e = hi_t
                event = True

    # --- advance the state to tau_e ---
    x1 = position(a, b, c1, c2, l1, l2, tau_e)
    v1 = velocity(b, c1, c2, l1, l2, tau_e)
    tau_s = cp[P_TAU_S]
    if tau_s > 0.0:
        fs[S_YF] = filtered_drive_force(
            fs[S_YF], 1.0 / tau_s, k0, c0, xs0, vs, a, b, c1, c2, l1, l2, tau_e
        )
    fs[S_X] = x1
    fs[S_V] = v1
    fs[S_T] = fs[S_T] + tau_e
    fs[S_THETA] = th0 + tau_e
    xs1 = xs0 + vs * tau_e
    fn_e = fn0 + fn1 * tau_e
    if gslip:
        fd = _extreme_drive_force(
            cp, ist[I_SIGN], xs0, vs, a, b, c1, c2, l1, l2, tau_e
        )
        if ist[I_SIGN] > 0:
            fs[S_EV_MIN] = min(fs[S_EV_MIN], fd)
        else:
            fs[S_EV_MIN] = max(fs[S_EV_MIN], fd)
    if not event:
        return tau_e, False

    # --- apply the event ---
    if gslip:
        _end_global_slip(cp, fs, ist, g, mode, pw1, p_uni, ev, xs1, vs, fn_e)
        return tau_e, True
    mus = mu_static(cp, stage, fn_e, th0 + tau_e)
    fe_in = fn_e + kk0 * xs1
    fe = fe_in - kk0 * x1
    tol = 1e-12
    n_left = 0
    dir_sum = 0
    for i in range(n):
        ci = mus * pw[i]
        if mode[i] == 0:
            xp = (ci * fe_in - g[i]) / (k + ci * kk0)
            xm = (-ci * fe_in - g[i]) / (k - ci * kk0)
            if x1 >= xp - tol:
                mode[i] = 1
            elif x1 <= xm + tol:
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
        _start_global_slip(cp, fs, ist, mode, ev, xs1, vs, fn_e, sign)
    return tau_e, False


@njit(cache=True)
def _free_step(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw1: np.ndarray,
    p_uni: np.ndarray,
    ev: np.ndarray,
    xs0: float,
    vs: float,
    fn0: float,
    h: float,
) -> bool:
    """Specimens apart (Fn below FN_CONTACT_MIN_N): the drive alone moves the specimen, exactly.

    Every element is left stuck and unloaded, so contact resumes with a fresh interface.
    Returns whether a running global slip was closed.
    """
    ended = False
    if ist[I_GSLIP] == 1:
        _end_global_slip(cp, fs, ist, g, mode, pw1, p_uni, ev, xs0, vs, fn0)
        ended = True
    k0 = cp[P_K0]
    c0 = cp[P_C0]
    a, b, c1, c2, l1, l2 = modal_solution(
        cp[P_M], c0, k0, k0 * xs0 + c0 * vs, k0 * vs, fs[S_X], fs[S_V]
    )
    if cp[P_TAU_S] > 0.0:
        fs[S_YF] = filtered_drive_force(
            fs[S_YF], 1.0 / cp[P_TAU_S], k0, c0, xs0, vs, a, b, c1, c2, l1, l2, h
        )
    fs[S_X] = position(a, b, c1, c2, l1, l2, h)
    fs[S_V] = velocity(b, c1, c2, l1, l2, h)
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


@njit(cache=True)
def _event_at(
    cp: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw: np.ndarray,
    k: float,
    stage: int,
    gslip: bool,
    sign: int,
    n_stuck: int,
    n_pos: int,
    n_neg: int,
    a: float,
    b: float,
    c1: complex,
    c2: complex,
    l1: complex,
    l2: complex,
    tau: float,
    xs0: float,
    vs: float,
    fn0: float,
    fn1: float,
    th0: float,
) -> bool:
    """Has an event happened by tau? (monotone predicate used by the bisection)."""
    v = velocity(b, c1, c2, l1, l2, tau)
    if gslip:
        return sign * v <= 0.0
    if n_pos > 0 and v < 0.0:
        return True
    if n_neg > 0 and v > 0.0:
        return True
    if n_stuck > 0:
        x = position(a, b, c1, c2, l1, l2, tau)
        fn = fn0 + fn1 * tau
        mus = mu_static(cp, stage, fn, th0 + tau)
        lo, hi = _thresholds(cp, g, mode, pw, k, mus, fn + cp[P_KAPPA] * cp[P_K0] * (xs0 + vs * tau))
        if x >= lo or x <= hi:
            return True
    return False


@njit(cache=True)
def _stribeck_law(cp: np.ndarray, fn: float, v_abs: float) -> float:
    """Stribeck part of the steady-sliding kinetic coefficient at |V| (0 when stribeck is off)."""
    if cp[P_VS] <= 0.0:
        return 0.0
    return stribeck_amplitude(cp, fn) * stribeck_shape(cp, v_abs)


@njit(cache=True)
def _slip_rhs(
    cp: np.ndarray,
    sign: int,
    x: float,
    v: float,
    th: float,
    y: float,
    e: float,
    xs: float,
    vs: float,
    fn: float,
) -> tuple[float, float, float, float]:
    """(V', theta', y', e') during a global slip with velocity/state-dependent kinetic friction.

    e bounds the Stribeck part of mu the sliding elements can carry: it grows as their springs
    would load, de/dt = Kt |V| / Fn_eff, and is capped by the Stribeck law
    (mu_s - mu_k) exp(-(|V|/v_s)^d) at the end of every step (:func:`_cap_stribeck`), so the
    friction mu_k,base(V, theta) + min(e, law(V)) follows the law where it falls and rises no
    faster than elastic loading allows (docs/model.md, "Re-stick with velocity-dependent
    friction").
    """
    k0 = cp[P_K0]
    fe = fn + cp[P_KAPPA] * k0 * (xs - x)
    fd = _drive_force(cp, xs, vs, x, v)
    va = abs(v)
    mu = mu_kinetic_base(cp, fn, va, th)
    de = 0.0
    if cp[P_VS] > 0.0:
        mu += min(e, _stribeck_law(cp, fn, va))
    acc = (fd - cp[P_CINT] * v - sign * mu * fe) / cp[P_M]
    if cp[P_VS] > 0.0:
        de = element_stiffness(cp, 1, fn, 1) * va / max(fe, FN_CONTACT_MIN_N)
    dth = 1.0
    if cp[P_RS_A] != 0.0 or cp[P_RS_B] != 0.0:
        dth = 1.0 - va * th / cp[P_RS_DC]
    dy = 0.0
    if cp[P_TAU_S] > 0.0:
        dy = (fd - y) / cp[P_TAU_S]
    return acc, dth, dy, de


@njit(cache=True)
def _rk4(
    cp: np.ndarray,
    sign: int,
    x: float,
    v: float,
    th: float,
    y: float,
    e: float,
    xs0: float,
    vs: float,
    fn0: float,
    fn1: float,
    t0: float,
    h: float,
) -> tuple[float, float, float, float, float]:
    """One classical Runge-Kutta step of (X, V, theta, y, e) from local time t0 by h.

    e is returned uncapped (the caller applies :func:`_cap_stribeck`).
    """
    a1, t1, y1, e1 = _slip_rhs(cp, sign, x, v, th, y, e, xs0 + vs * t0, vs, fn0 + fn1 * t0)
    tm = t0 + 0.5 * h
    xs_m = xs0 + vs * tm
    fn_m = fn0 + fn1 * tm
    a2, t2, y2, e2 = _slip_rhs(
        cp, sign, x + 0.5 * h * v, v + 0.5 * h * a1, th + 0.5 * h * t1, y + 0.5 * h * y1,
        e + 0.5 * h * e1, xs_m, vs, fn_m,
    )
    v2 = v + 0.5 * h * a1
    a3, t3, y3, e3 = _slip_rhs(
        cp, sign, x + 0.5 * h * v2, v + 0.5 * h * a2, th + 0.5 * h * t2, y + 0.5 * h * y2,
        e + 0.5 * h * e2, xs_m, vs, fn_m,
    )
    v3 = v + 0.5 * h * a2
    te = t0 + h
    a4, t4, y4, e4 = _slip_rhs(
        cp, sign, x + h * v3, v + h * a3, th + h * t3, y + h * y3, e + h * e3,
        xs0 + vs * te, vs, fn0 + fn1 * te,
    )
    v4 = v + h * a3
    xn = x + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
    vn = v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    thn = th + h / 6.0 * (t1 + 2.0 * t2 + 2.0 * t3 + t4)
    yn = y + h / 6.0 * (y1 + 2.0 * y2 + 2.0 * y3 + y4)
    en = e + h / 6.0 * (e1 + 2.0 * e2 + 2.0 * e3 + e4)
    return xn, vn, thn, yn, en


@njit(cache=True)
def _cap_stribeck(
    cp: np.ndarray,
    sign: int,
    x: float,
    v: float,
    th: float,
    y: float,
    e: float,
    xn: float,
    vn: float,
    thn: float,
    yn: float,
    en: float,
    xs0: float,
    vs: float,
    fn0: float,
    fn1: float,
    t0: float,
    h: float,
    arrest: bool,
) -> float:
    """Stribeck part the elements can carry at the end of an RK step from t0 to t0 + h.

    e(t) = min over s <= t of [law(V(s)) + (Kt / Fn_eff) |X(t) - X(s)|]: the law's value at some
    earlier instant plus the elastic loading since (en is the s = start term, uncapped). Where the
    law rises over the step (the slip decelerating into the Stribeck region) the minimum is sought
    on the cubic Hermite interpolants of X and V over the step, on a uniform grid and, in the step
    that ends the slip (``arrest``: V -> 0), on a geometric one towards its end, so the law's rise
    within a velocity band narrower than the step is seen, however small v_s.
    """
    te = t0 + h
    fn_e = fn0 + fn1 * te
    law_e = _stribeck_law(cp, fn_e, abs(vn))
    cap = min(en, law_e)
    if cp[P_VS] <= 0.0 or law_e <= _stribeck_law(cp, fn0 + fn1 * t0, abs(v)):
        return cap
    acc0, _, _, _ = _slip_rhs(cp, sign, x, v, th, y, e, xs0 + vs * t0, vs, fn0 + fn1 * t0)
    acc1, _, _, _ = _slip_rhs(cp, sign, xn, vn, thn, yn, en, xs0 + vs * te, vs, fn_e)
    fe = max(fn_e + cp[P_KAPPA] * cp[P_K0] * (xs0 + vs * te - xn), FN_CONTACT_MIN_N)
    kfe = element_stiffness(cp, 1, fn_e, 1) / fe
    n_uni = 16
    n_geo = 60 if arrest else 0
    for j in range(1, n_uni + n_geo):
        if j < n_uni:
            s = j / n_uni
        else:
            s = 1.0 - 0.5 ** (j - n_uni + 5)  # 1 - 1/32, 1 - 1/64, ... (beyond the uniform grid)
            if s >= 1.0:
                break
        s2 = s * s
        s3 = s2 * s
        h00 = 2.0 * s3 - 3.0 * s2 + 1.0
        h10 = s3 - 2.0 * s2 + s
        h01 = -2.0 * s3 + 3.0 * s2
        h11 = s3 - s2
        xj = h00 * x + h10 * h * v + h01 * xn + h11 * h * vn
        vj = h00 * v + h10 * h * acc0 + h01 * vn + h11 * h * acc1
        tj = t0 + s * h
        cand = _stribeck_law(cp, fn0 + fn1 * tj, abs(vj)) + kfe * abs(xn - xj)
        if cand < cap:
            cap = cand
    return cap


@njit(cache=True)
def _nonlinear_slip_step(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw1: np.ndarray,
    p_uni: np.ndarray,
    ev: np.ndarray,
    xs0: float,
    vs: float,
    fn0: float,
    fn1: float,
    h: float,
    h_rk: float,
) -> tuple[float, bool]:
    """Integrate a global slip by at most h with RK4; end it where the velocity returns to zero."""
    sign = ist[I_SIGN]
    x = fs[S_X]
    v = fs[S_V]
    th = fs[S_THETA]
    y = fs[S_YF]
    e = fs[S_STRIB]
    tloc = 0.0
    while tloc < h:
        hs = min(h_rk, h - tloc)
        xn, vn, thn, yn, en = _rk4(cp, sign, x, v, th, y, e, xs0, vs, fn0, fn1, tloc, hs)
        if sign * vn <= 0.0 and tloc + hs > 0.0:
            # locate V = 0 on the cubic Hermite interpolant of V over the step, then redo the step
            acc0, _, _, _ = _slip_rhs(
                cp, sign, x, v, th, y, e, xs0 + vs * tloc, vs, fn0 + fn1 * tloc
            )
            te = tloc + hs
            acc1, _, _, _ = _slip_rhs(
                cp, sign, xn, vn, thn, yn, en, xs0 + vs * te, vs, fn0 + fn1 * te
            )
            lo = 0.0
            hi = 1.0
            for _ in range(_BISECT_ITERS):
                s = 0.5 * (lo + hi)
                h00 = 2 * s**3 - 3 * s**2 + 1
                h10 = s**3 - 2 * s**2 + s
                h01 = -2 * s**3 + 3 * s**2
                h11 = s**3 - s**2
                vs_ = h00 * v + h10 * hs * acc0 + h01 * vn + h11 * hs * acc1
                if sign * vs_ <= 0.0:
                    hi = s
                else:
                    lo = s
            hpart = hi * hs
            xn, vn, thn, yn, en = _rk4(
                cp, sign, x, v, th, y, e, xs0, vs, fn0, fn1, tloc, hpart
            )
            en = _cap_stribeck(
                cp, sign, x, v, th, y, e, xn, vn, thn, yn, en, xs0, vs, fn0, fn1, tloc, hpart,
                True,
            )
            tloc += hpart
            fs[S_X] = xn
            fs[S_V] = 0.0
            fs[S_THETA] = thn
            fs[S_YF] = yn
            fs[S_STRIB] = en
            fs[S_T] += tloc
            xs1 = xs0 + vs * tloc
            fd = _drive_force(cp, xs1, vs, xn, 0.0)
            fs[S_EV_MIN] = min(fs[S_EV_MIN], fd) if sign > 0 else max(fs[S_EV_MIN], fd)
            _end_global_slip(
                cp, fs, ist, g, mode, pw1, p_uni, ev, xs1, vs, fn0 + fn1 * tloc
            )
            return tloc, True
        en = _cap_stribeck(
            cp, sign, x, v, th, y, e, xn, vn, thn, yn, en, xs0, vs, fn0, fn1, tloc, hs, False
        )
        x, v, th, y, e = xn, vn, thn, yn, en
        tloc += hs
        fd = _drive_force(cp, xs0 + vs * tloc, vs, x, v)
        fs[S_EV_MIN] = min(fs[S_EV_MIN], fd) if sign > 0 else max(fs[S_EV_MIN], fd)
    fs[S_X] = x
    fs[S_V] = v
    fs[S_THETA] = th
    fs[S_YF] = y
    fs[S_STRIB] = e
    fs[S_T] += h
    return h, False


@njit(cache=True)
def _write_sample(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw0: np.ndarray,
    pw1: np.ndarray,
    io: int,
    xs: float,
    vs: float,
    fn: float,
    o_ft: np.ndarray,
    o_fi: np.ndarray,
    o_x: np.ndarray,
    o_v: np.ndarray,
    o_xs: np.ndarray,
    o_fn: np.ndarray,
    o_stage: np.ndarray,
    o_slip: np.ndarray,
    o_elem: np.ndarray,
    record_elements: bool,
) -> None:
    x = fs[S_X]
    v = fs[S_V]
    kk0 = cp[P_KAPPA] * cp[P_K0]
    fe = fn + kk0 * (xs - x)
    fd = _drive_force(cp, xs, vs, x, v)
    stage = ist[I_STAGE]
    n = g.shape[0]
    if ist[I_GSLIP] == 1:
        mu = mu_kinetic_base(cp, fn, abs(v), fs[S_THETA])
        if cp[P_VS] > 0.0:
            mu += min(fs[S_STRIB], _stribeck_law(cp, fn, abs(v)))
        fi = ist[I_SIGN] * mu * fe
    else:
        k = fs[S_K_USED]
        pw = pw0 if stage == 0 else pw1
        mus = mu_static(cp, stage, fn, fs[S_THETA])
        fi = 0.0
        for i in range(n):
            if mode[i] == 0:
                fi += g[i] + k * x
            else:
                fi += mode[i] * mus * pw[i] * fe
    o_ft[io] = fs[S_YF] if cp[P_TAU_S] > 0.0 else fd
    o_fi[io] = fi
    o_x[io] = x
    o_v[io] = v
    o_xs[io] = xs
    o_fn[io] = fe
    o_stage[io] = stage
    o_slip[io] = 1 if (ist[I_SLIPPED] == 1 or ist[I_GSLIP] == 1) else 0
    ist[I_SLIPPED] = 0
    if record_elements:
        for i in range(n):
            o_elem[io, i] = mode[i]


@njit(cache=True)
def advance(
    cp: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw0: np.ndarray,
    pw1: np.ndarray,
    p_uni: np.ndarray,
    kt_t: np.ndarray,
    kt_xs: np.ndarray,
    kt_fn: np.ndarray,
    t_out: np.ndarray,
    o_ft: np.ndarray,
    o_fi: np.ndarray,
    o_x: np.ndarray,
    o_v: np.ndarray,
    o_xs: np.ndarray,
    o_fn: np.ndarray,
    o_stage: np.ndarray,
    o_slip: np.ndarray,
    o_elem: np.ndarray,
    ev: np.ndarray,
    t_stop: float,
    stop_on_slip_end: bool,
    record_elements: bool,
) -> int:
    """Integrate from the state in (fs, ist, g, mode) up to t_stop, writing output samples.

    Inputs x_stage(t) and Fn(t) are piecewise linear through the knots (kt_t, kt_xs, kt_fn); output
    samples are written at the times t_out[ist[I_OUT]:] reached. Re-entrant: all state lives in the
    arrays, so a caller may stop (RET_SLIP_END, RET_EVENT_TABLE_FULL), act, and call again.
    """
    n_out = t_out.shape[0]
    nk = kt_t.shape[0]
    nonlinear = slip_is_nonlinear(cp)
    h_rk = 2.0 * math.pi * math.sqrt(cp[P_M] / cp[P_K0]) / 64.0
    steps = 0
    while True:
        t = fs[S_T]
        j = ist[I_KNOT]
        while j < nk - 2 and kt_t[j + 1] <= t:
            j += 1
        ist[I_KNOT] = j
        io = ist[I_OUT]
        if io < n_out and t_out[io] <= t:
            xs = _interp(kt_t, kt_xs, j, t)
            fn = max(_interp(kt_t, kt_fn, j, t), 0.0)
            vs = _slope(kt_t, kt_xs, j)
            _write_sample(
                cp, fs, ist, g, mode, pw0, pw1, io, xs, vs, fn,
                o_ft, o_fi, o_x, o_v, o_xs, o_fn, o_stage, o_slip, o_elem, record_elements,
            )
            ist[I_OUT] = io + 1
            steps = 0
            continue
        if t >= t_stop:
            return RET_DONE
        if ist[I_NEVENT] >= ev.shape[0] - 1:
            return RET_EVENT_TABLE_FULL
        target = min(t_stop, kt_t[j + 1]) if kt_t[j + 1] > t else t_stop
        if io < n_out:
            target = min(target, t_out[io])
        h = target - t
        if h <= 0.0:
            return RET_DONE
        xs0 = _interp(kt_t, kt_xs, j, t)
        vs = _slope(kt_t, kt_xs, j)
        fn0 = _interp(kt_t, kt_fn, j, t)
        fn1 = _slope(kt_t, kt_fn, j)
        if fn0 < 0.0:
            fn0 = 0.0
            fn1 = max(fn1, 0.0)
        steps += 1
        if fn0 < FN_CONTACT_MIN_N and fn0 + fn1 * h < FN_CONTACT_MIN_N:
            ended = _free_step(cp, fs, ist, g, mode, pw1, p_uni, ev, xs0, vs, fn0, h)
            fs[S_T] = target
            if ended and stop_on_slip_end:
                return RET_SLIP_END
            continue
        if fn1 == 0.0 and ist[I_GSLIP] == 0:
            t_lim = min(t_stop, kt_t[j + 1])
            if fast_stick_run(
                cp, fs, ist, g, mode, pw0, pw1, t_out, t_lim, xs0, vs, fn0,
                o_ft, o_fi, o_x, o_v, o_xs, o_fn, o_stage, o_slip, o_elem, record_elements,
            ) > 0:
                steps = 0
                continue
        if ist[I_GSLIP] == 1 and nonlinear:
            tau, ended = _nonlinear_slip_step(
                cp, fs, ist, g, mode, pw1, p_uni, ev, xs0, vs, fn0, fn1, h, h_rk
            )
        else:
            allow = steps <= MAX_STEPS_PER_SAMPLE
            if steps == MAX_STEPS_PER_SAMPLE + 1:
                ist[I_CHATTER] += 1
            tau, ended = _linear_step(
                cp, fs, ist, g, mode, pw0, pw1, p_uni, ev, xs0, vs, fn0, fn1, h, allow,
            )
        if tau >= h:
            fs[S_T] = target  # land exactly on the knot / sample time
        if ended and stop_on_slip_end:
            return RET_SLIP_END
