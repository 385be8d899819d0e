"""Exact sample-to-sample recurrence for long stick phases (the common case), docs/model.md sec. 3.

While every input is constant over a span (constant stage velocity, constant Fn) the linear
problem of :mod:`rigctl.model.modal` has constant coefficients. Then the deviation u = X - X_p from
the particular solution X_p(t) = a + b t advances by the fixed transition matrix
Phi = exp(A dt) per sample (A = [[0, 1], [-K/M, -C/M]]): exact, not an approximation. The sensor
filter of ``sensor_dynamics`` (y' = (F_drive - y) / tau_s) is linear too: its deviation
w = y - y_p from the filtered particular force joins (u, u') as a third state of the same
recurrence, its row of exp(A dt) taken from the closed form of
:func:`rigctl.model.modal.filtered_drive_force`.

An event cannot happen before the next sample if the ringing amplitude R = sqrt(u^2 + ((u' + s u)/w)^2)
(s = C/2M, w the damped frequency; |u(t)| <= R and |u'(t)| <= R sqrt(K/M) for all later t) keeps X
below the lowest forward threshold and above the highest backward one, and V away from zero while
elements presliding at their threshold could stick again. The thresholds are bounded over each
sample interval: with ``normal_coupling`` they move linearly with the stage (Fn,eff = Fn + kappa K0
(x_stage - X)), bounded by their values at the start plus the extreme rate; with the aging of
``rate_state`` (b > 0) they move monotonically with theta, so the extremes over the interval lie at
its ends; the force of presliding elements, which aging changes, is taken linear in time over each
interval as in the general step, with the particular solution rebuilt per interval.
When the bound cannot rule an event out the general step of :mod:`rigctl.model.kernel.linear_step`
(grid scan and bisection) takes over.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numba import njit

from rigctl.model.friction_laws import element_stiffness, mu_static
from rigctl.model.layout import (
    F_SLIP,
    F_STAGE,
    I_FAST,
    I_GSLIP,
    I_OUT,
    I_SLIPPED,
    I_STAGE,
    O_FI,
    O_FN,
    O_FT,
    O_V,
    O_X,
    O_XS,
    P_C0,
    P_CINT,
    P_K0,
    P_KAPPA,
    P_KPAR,
    P_M,
    P_RS_B,
    P_TAU_S,
    P_XPAR,
    S_K_USED,
    S_T,
    S_THETA,
    S_V,
    S_X,
    S_YF,
)
from rigctl.model.modal import filtered_drive_force, modal_solution


@njit(cache=True)
def _stuck_thresholds(
    g: np.ndarray, mode: np.ndarray, pw: np.ndarray, k: float, mus: float, fe_in: float,
    kk0: float, vs: float,
) -> tuple[float, float, float, float]:
    """(lo, hi, lo_rate, hi_rate): lowest forward and highest backward threshold position of the
    stuck elements at the current time, and bounds of their rates of change (normal coupling moves
    them with the stage: fe_in = Fn + kappa K0 x_stage). Where a threshold position does not exist
    (k -+ c_i kappa K0 <= 0) the bounds are -inf and +inf: no interval is ever cleared."""
    lo = np.inf
    hi = -np.inf
    lo_rate = 0.0
    hi_rate = 0.0
    for i in range(g.shape[0]):
        if mode[i] != 0:
            continue
        ci = mus * pw[i]
        dp = k + ci * kk0
        dm = k - ci * kk0
        if dp <= 0.0 or dm <= 0.0:
            return -np.inf, np.inf, 0.0, 0.0
        lo = min(lo, (ci * fe_in - g[i]) / dp)
        hi = max(hi, (-ci * fe_in - g[i]) / dm)
        if kk0 != 0.0:
            lo_rate = min(lo_rate, ci * kk0 * vs / dp)
            hi_rate = max(hi_rate, -ci * kk0 * vs / dm)
    return lo, hi, lo_rate, hi_rate


@njit(cache=True)
def fast_stick_run(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    t_out: np.ndarray,
    t_end: float,
    xs_start: float,
    vs: float,
    fn: float,
    out: np.ndarray,
    flags: np.ndarray,
    elem: np.ndarray,
    record_elements: bool,
) -> int:
    """Advance sample by sample while no event is possible; return the number of samples written.

    Preconditions (checked): stick phase, the state sits exactly on the previous output sample,
    inputs constant over [t, t_end] (xs_start is the stage position at the current time).
    """
    aging_b = cp[P_RS_B]
    if ist[I_GSLIP] == 1 or aging_b < 0.0:
        return 0
    io = ist[I_OUT]
    n_out = t_out.shape[0]
    if io == 0 or io >= n_out:
        return 0
    t0 = fs[S_T]
    if t_out[io - 1] != t0:
        return 0
    dt = t_out[io] - t0
    if dt <= 0.0 or t_out[io] > t_end:
        return 0
    n = g.shape[0]
    stage = ist[I_STAGE]
    k = element_stiffness(cp, stage, fn, n)
    if k != fs[S_K_USED]:
        return 0
    pw = weights[stage]
    m = cp[P_M]
    k0 = cp[P_K0]
    c0 = cp[P_C0]
    kk0 = cp[P_KAPPA] * k0
    aging = aging_b != 0.0
    n_stuck = 0
    gsum = 0.0
    spm = 0.0
    n_pos = 0
    n_neg = 0
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
    rebase = aging and n_pos + n_neg > 0
    if rebase and kk0 != 0.0:
        return 0  # aging presliding force under normal coupling changes the stiffness: general step
    mus = mu_static(cp, stage, fn, fs[S_THETA])
    lo, hi, lo_rate, hi_rate = _stuck_thresholds(g, mode, pw, k, mus, fn + kk0 * xs_start, kk0, vs)
    if n_stuck > 0 and not (math.isfinite(lo) and math.isfinite(hi)):
        return 0
    csl = mus * spm
    kst = k * n_stuck
    kp = cp[P_KPAR]  # parallel springs (linear terms): -kp (X - X(0)), in K and F
    kpx = kp * cp[P_XPAR]
    kk = k0 + kst - csl * kk0 + kp
    cc = c0 + cp[P_CINT]
    disc = cc * cc - 4.0 * m * kk
    if kk <= 0.0 or disc >= 0.0:
        return 0  # over-damped (or unstable): leave it to the general step
    sig = cc / (2.0 * m)
    wd = math.sqrt(-disc) / (2.0 * m)
    wn = math.sqrt(kk / m)
    # particular solution X_p(tau) = a + b tau measured from t0
    f0 = k0 * xs_start + c0 * vs - gsum - csl * (fn + kk0 * xs_start) + kpx
    f1 = k0 * vs - csl * kk0 * vs
    b = f1 / kk
    a = (f0 - cc * b) / kk
    # transition matrix of (u, u') over dt
    l1 = complex(-sig, wd)
    e = cmath.exp(l1 * dt)
    er = e.real
    ei = e.imag
    # u(t) = exp(-s t) (u0 cos + (u0' + s u0)/w sin)
    p11 = er + sig / wd * ei
    p12 = ei / wd
    p21 = -(wn * wn) / wd * ei
    p22 = er - sig / wd * ei
    u = fs[S_X] - a
    du = fs[S_V] - b
    # sensor filter: y = y_p + w, y_p(tau) = q0 + p1 (tau - tau_s) the lagged particular force,
    # w(dt) = ew w0 + wu u0 + wdu u0' (the filter's response to the ringing, exactly)
    tau_s = cp[P_TAU_S]
    filtered = tau_s > 0.0
    q0 = 0.0
    p1 = 0.0
    ew = 0.0
    wu = 0.0
    wdu = 0.0
    w = 0.0
    if filtered:
        q0 = k0 * (xs_start - a) + c0 * (vs - b)
        p1 = k0 * (vs - b)
        ew = math.exp(-dt / tau_s)
        wu = filtered_drive_force(0.0, 1.0 / tau_s, k0, c0, 0.0, 0.0,
                                  modal_solution(m, cc, kk, 0.0, 0.0, 1.0, 0.0), dt)
        wdu = filtered_drive_force(0.0, 1.0 / tau_s, k0, c0, 0.0, 0.0,
                                   modal_solution(m, cc, kk, 0.0, 0.0, 0.0, 1.0), dt)
        w = fs[S_YF] - (q0 - p1 * tau_s)
    written = 0
    tau = 0.0
    if not (filtered or aging or kk0 != 0.0):
        # the loop below without normal coupling, sensor filter and aging, written out because
        # the general loop costs 5-10 % more per sample (measured: bench engine, warm allocator)
        while io < n_out:
            t_next = t_out[io]
            if t_next > t_end or abs((t_next - t0) - (tau + dt)) > 1e-9 * dt + 1e-15:
                break
            amp = math.sqrt(u * u + ((du + sig * u) / wd) ** 2)
            xa = a + b * tau
            xb = a + b * (tau + dt)
            if max(xa, xb) + amp >= lo or min(xa, xb) - amp <= hi:
                break
            if n_pos > 0 and b - amp * wn <= 0.0:
                break
            if n_neg > 0 and b + amp * wn >= 0.0:
                break
            un = p11 * u + p12 * du
            dun = p21 * u + p22 * du
            u = un
            du = dun
            tau = t_next - t0
            x = a + b * tau + u
            v = b + du
            xs = xs_start + vs * tau
            out[O_FT, io] = k0 * (xs - x) + c0 * (vs - v)
            out[O_FI, io] = gsum + kst * x + csl * fn
            out[O_X, io] = x
            out[O_V, io] = v
            out[O_XS, io] = xs
            out[O_FN, io] = fn
            flags[F_STAGE, io] = stage
            flags[F_SLIP, io] = 1 if ist[I_SLIPPED] == 1 else 0
            ist[I_SLIPPED] = 0
            if record_elements:
                for i in range(n):
                    elem[io, i] = mode[i]
            fs[S_X] = x
            fs[S_V] = v
            fs[S_T] = t_next
            fs[S_THETA] += dt
            io += 1
            written += 1
        ist[I_OUT] = io
        ist[I_FAST] += written
        return written
    if rebase:
        # aging changes the force of presliding elements mus(theta) spm Fn: as in the general step,
        # over each interval it is taken linear in time between its values at the ends, so the
        # particular solution (a, b) is rebuilt per interval; the stiffness, hence Phi, is constant
        while io < n_out:
            t_next = t_out[io]
            if t_next > t_end or abs((t_next - t0) - (tau + dt)) > 1e-9 * dt + 1e-15:
                break
            mus_b = mu_static(cp, stage, fn, fs[S_THETA] + dt)
            xs_a = xs_start + vs * tau
            q_a = mus * spm * fn
            q1 = (mus_b * spm * fn - q_a) / dt
            b = (k0 * vs - q1) / kk
            a = (k0 * xs_a + c0 * vs - gsum - q_a + kpx - cc * b) / kk
            u = fs[S_X] - a
            du = fs[S_V] - b
            amp = math.sqrt(u * u + ((du + sig * u) / wd) ** 2)
            lo_a, hi_a, _, _ = _stuck_thresholds(g, mode, pw, k, mus, fn, 0.0, vs)
            lo_b, hi_b, _, _ = _stuck_thresholds(g, mode, pw, k, mus_b, fn, 0.0, vs)
            xb = a + b * dt
            if max(a, xb) + amp >= min(lo_a, lo_b) or min(a, xb) - amp <= max(hi_a, hi_b):
                break
            if n_pos > 0 and b - amp * wn <= 0.0:
                break
            if n_neg > 0 and b + amp * wn >= 0.0:
                break
            un = p11 * u + p12 * du
            dun = p21 * u + p22 * du
            x = xb + un
            v = b + dun
            xs = xs_a + vs * dt
            if filtered:
                q0 = k0 * (xs_a - a) + c0 * (vs - b)
                p1 = k0 * (vs - b)
                w = fs[S_YF] - (q0 - p1 * tau_s)
                w = ew * w + wu * u + wdu * du
                y = q0 + p1 * (dt - tau_s) + w
                fs[S_YF] = y
                out[O_FT, io] = y
            else:
                out[O_FT, io] = k0 * (xs - x) + c0 * (vs - v)
            out[O_FI, io] = gsum + kst * x + mus_b * spm * fn
            out[O_X, io] = x
            out[O_V, io] = v
            out[O_XS, io] = xs
            out[O_FN, io] = fn
            flags[F_STAGE, io] = stage
            flags[F_SLIP, io] = 1 if ist[I_SLIPPED] == 1 else 0
            ist[I_SLIPPED] = 0
            if record_elements:
                for i in range(n):
                    elem[io, i] = mode[i]
            fs[S_X] = x
            fs[S_V] = v
            fs[S_T] = t_next
            fs[S_THETA] += dt
            tau = t_next - t0
            mus = mus_b
            io += 1
            written += 1
        ist[I_OUT] = io
        ist[I_FAST] += written
        return written
    mus_b = mus
    while io < n_out:
        t_next = t_out[io]
        if t_next > t_end or abs((t_next - t0) - (tau + dt)) > 1e-9 * dt + 1e-15:
            break
        # bound over the coming interval
        amp = math.sqrt(u * u + ((du + sig * u) / wd) ** 2)
        xa = a + b * tau
        xb = a + b * (tau + dt)
        if aging:
            # thresholds at both ends of the interval in theta, moving with the stage in between
            # (each is affine in time and monotone in theta: the extremes lie at the corners)
            fe_a = fn + kk0 * (xs_start + vs * tau)
            mus_b = mu_static(cp, stage, fn, fs[S_THETA] + dt)
            lo_a, hi_a, lr_a, hr_a = _stuck_thresholds(g, mode, pw, k, mus, fe_a, kk0, vs)
            lo_b, hi_b, lr_b, hr_b = _stuck_thresholds(g, mode, pw, k, mus_b, fe_a, kk0, vs)
            lo_iv = min(lo_a + lr_a * dt, lo_b + lr_b * dt)
            hi_iv = max(hi_a + hr_a * dt, hi_b + hr_b * dt)
        else:
            lo_iv = lo + lo_rate * (tau + dt)  # lo_rate <= 0 <= hi_rate
            hi_iv = hi + hi_rate * (tau + dt)
        if max(xa, xb) + amp >= lo_iv or min(xa, xb) - amp <= hi_iv:
            break
        if n_pos > 0 and b - amp * wn <= 0.0:
            break
        if n_neg > 0 and b + amp * wn >= 0.0:
            break
        if filtered:
            w = ew * w + wu * u + wdu * du
        un = p11 * u + p12 * du
        dun = p21 * u + p22 * du
        u = un
        du = dun
        tau = t_next - t0
        x = a + b * tau + u
        v = b + du
        xs = xs_start + vs * tau
        fe = fn + kk0 * (xs - x)
        if filtered:
            y = q0 + p1 * (tau - tau_s) + w
            fs[S_YF] = y
            out[O_FT, io] = y
        else:
            out[O_FT, io] = k0 * (xs - x) + c0 * (vs - v)
        out[O_FI, io] = gsum + kst * x + csl * fe
        out[O_X, io] = x
        out[O_V, io] = v
        out[O_XS, io] = xs
        out[O_FN, io] = fe
        flags[F_STAGE, io] = stage
        flags[F_SLIP, io] = 1 if ist[I_SLIPPED] == 1 else 0
        ist[I_SLIPPED] = 0
        if record_elements:
            for i in range(n):
                elem[io, i] = mode[i]
        fs[S_X] = x
        fs[S_V] = v
        fs[S_T] = t_next
        fs[S_THETA] += dt
        io += 1
        written += 1
        if aging:
            mus = mus_b
    ist[I_OUT] = io
    ist[I_FAST] += written
    return written
