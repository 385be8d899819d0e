"""Exact sample-to-sample recurrence for long stick phases (the common case), docs/model.md sec. 3.4.

While every input is constant over a span (constant stage velocity, constant Fn), no rate-and-state
aging, no normal coupling and an ideal sensor, the element thresholds are fixed and the linear
problem of :mod:`rigctl.model.modal` has constant coefficients. Then the deviation u = X - X_p from
the particular solution X_p(t) = a + b t advances by the fixed transition matrix
Phi = exp(A dt) per sample (A = [[0, 1], [-K/M, -C/M]]): exact, not an approximation.

An event cannot happen before the next sample if the ringing amplitude R = sqrt(u^2 + ((u' + s u)/w)^2)
(s = C/2M, w the damped frequency; |u(t)| <= R and |u'(t)| <= R sqrt(K/M) for all later t) keeps X
below the lowest forward threshold and above the highest backward one, and V away from zero while
elements presliding at their threshold could stick again. When the bound cannot rule an event out the
general step of :mod:`rigctl.model.kernel.linear_step` (grid scan and bisection) takes over.
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
    P_M,
    P_RS_B,
    P_TAU_S,
    S_K_USED,
    S_T,
    S_THETA,
    S_V,
    S_X,
)


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
    if ist[I_GSLIP] == 1 or cp[P_TAU_S] > 0.0 or cp[P_RS_B] != 0.0 or cp[P_KAPPA] != 0.0:
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
    n_stuck = 0
    gsum = 0.0
    spm = 0.0
    n_pos = 0
    n_neg = 0
    lo = np.inf
    hi = -np.inf
    mus = mu_static(cp, stage, fn, fs[S_THETA])
    for i in range(n):
        if mode[i] == 0:
            n_stuck += 1
            gsum += g[i]
            ci = mus * pw[i]
            xp = (ci * fn - g[i]) / k
            xm = (-ci * fn - g[i]) / k
            lo = min(lo, xp)
            hi = max(hi, xm)
        else:
            spm += mode[i] * pw[i]
            if mode[i] > 0:
                n_pos += 1
            else:
                n_neg += 1
    csl = mus * spm
    kst = k * n_stuck
    kk = k0 + kst
    cc = c0 + cp[P_CINT]
    disc = cc * cc - 4.0 * m * kk
    if disc >= 0.0:
        return 0  # over-damped: leave it to the general step
    sig = cc / (2.0 * m)
    wd = math.sqrt(-disc) / (2.0 * m)
    wn = math.sqrt(kk / m)
    # particular solution X_p(tau) = a + b tau measured from t0
    f0 = k0 * xs_start + c0 * vs - gsum - csl * fn
    f1 = k0 * vs
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
    written = 0
    tau = 0.0
    while io < n_out:
        t_next = t_out[io]
        if t_next > t_end or abs((t_next - t0) - (tau + dt)) > 1e-9 * dt + 1e-15:
            break
        # bound over the coming interval
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
        fe = fn
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
    ist[I_OUT] = io
    return written
