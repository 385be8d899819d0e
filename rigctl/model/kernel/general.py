"""The general path: classical RK4 for the whole motion when a model has plug-in terms.

A plug-in's friction law, force or state variables (:mod:`rigctl.model.terms`) are arbitrary
functions of the state, so the closed form between events (:mod:`rigctl.model.modal`) no longer
holds. A model with such terms is integrated here, stick phases included (docs/model.md, section 3,
"Terms from plug-ins"): classical RK4 on (X, V, theta, e, z) at the step of the nonlinear slips,
1/64 of the drive period 2 pi sqrt(M/K0) (:func:`rigctl.model.kernel.nonlinear_slip.rk_step_s`);
the sensor filter follows the drive force, taken linear over each step, in closed form (so a short
tau_s does not limit the step). After each step the events of the exact path are tested at its end
(a stuck element reaching its threshold, a presliding element's velocity reversing, V = 0 ending a
global slip); where one happened, the step is redone from its start with the length found by
bisection (50 halvings), and the event is applied as in :mod:`rigctl.model.kernel.linear_step`.

The terms come as one tuple (:meth:`rigctl.model.terms.TermSet.bundle`): for each kind (friction,
force, state law) a tuple of compiled first-class functions, a tuple of their parameter vectors and
the bounds of each one's state in ``z``. The library's laws (:mod:`rigctl.model.friction_laws`)
give the coefficient each friction term receives; the Stribeck bound e is capped at every step end
as on the exact path (:func:`rigctl.model.kernel.nonlinear_slip.cap_on_step`, the law's minimum
within the step included).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from rigctl.model.friction_laws import element_stiffness, mu_static
from rigctl.model.kernel.forces import drive_force, parallel_spring_force
from rigctl.model.kernel.free_step import free_step
from rigctl.model.kernel.global_slip import (
    end_global_slip,
    note_slip_force,
    note_slip_speed,
    start_global_slip,
)
from rigctl.model.kernel.inputs import Segment, segment_at
from rigctl.model.kernel.nonlinear_slip import (
    AGING_STEP_LIMIT,
    aging_limited_step,
    cap_on_step,
    kinetic_mu,
    rk_step_s,
    slip_friction,
    step_laws,
)
from rigctl.model.kernel.walk import STEP, apart, current_knot, step_end, write_due_sample
from rigctl.model.layout import (
    I_CHATTER,
    I_GSLIP,
    I_SIGN,
    I_STAGE,
    I_TERM_ERR,
    MAX_STEPS_PER_SAMPLE,
    O_FI,
    P_CINT,
    P_K0,
    P_KAPPA,
    P_M,
    P_RS_A,
    P_RS_B,
    P_RS_DC,
    P_TAU_S,
    RET_SLIP_END,
    RET_TERM_ERROR,
    S_K_USED,
    S_STRIB,
    S_T,
    S_THETA,
    S_V,
    S_X,
    S_YF,
    W_STABLE,
    W_UNIFORM,
)

BISECT_STEPS = 50  # halvings of an RK4 step (~18 us) locating an event: below 1e-19 s


@njit(cache=True, inline="always")
def friction_chain(terms: Any, mu: float, x: float, v: float, t: float, fn: float,
                   stick: float, z: np.ndarray) -> float:
    """The friction coefficient after every plug-in friction term, in the model's order."""
    fns = terms[0]
    ps = terms[1]
    zb = terms[2]
    for j in range(len(fns)):
        mu = fns[j](ps[j], mu, x, v, t, fn, stick, z[zb[j, 0]:zb[j, 1]])
    return mu


@njit(cache=True, inline="always")
def plugin_force(terms: Any, x: float, v: float, t: float, fn: float, z: np.ndarray) -> float:
    """Sum of the plug-in forces on the slider [N]."""
    fns = terms[3]
    ps = terms[4]
    zb = terms[5]
    f = 0.0
    for j in range(len(fns)):
        f += fns[j](ps[j], x, v, t, fn, z[zb[j, 0]:zb[j, 1]])
    return f


@njit(cache=True, inline="always")
def state_rates(terms: Any, x: float, v: float, t: float, fn: float, z: np.ndarray,
                dz: np.ndarray) -> None:
    """dz/dt of the plug-ins' state variables into dz."""
    fns = terms[6]
    ps = terms[7]
    zb = terms[8]
    dz[:] = 0.0
    for j in range(len(fns)):
        a = zb[j, 0]
        b = zb[j, 1]
        fns[j](ps[j], x, v, t, fn, z[a:b], dz[a:b])


@njit(cache=True, inline="always")
def _rhs(cp: np.ndarray, terms: Any, gslip: bool, sign: int, stage: int, gsum: float,
         kst: float, spm: float, t: float, xs: float, vs: float, fn: float, x: float, v: float,
         th: float, e: float, z: np.ndarray, dz: np.ndarray) -> tuple[float, float, float]:
    """(V', theta', e') and dz/dt: Newton's law
    M X'' = F_drive - F_interface - c_i V - k_p (X - X(0)) + F_plugins.

    Stuck elements carry g_i + k X (their sum gsum + kst X), presliding ones their static
    threshold mu_s,eff P_i m_i Fn_eff (spm sums mode_i P_i m_i), a global slip sign mu_k,eff
    Fn_eff; the coefficients are the library's laws passed through the plug-in friction terms
    (docs/model.md, sections 1-3)."""
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - x)
    fd = drive_force(cp, xs, vs, x, v)
    dth = 1.0
    de = 0.0
    if gslip:
        mu, dth, de = slip_friction(cp, fn, fe, abs(v), th, e)
        fi = sign * friction_chain(terms, mu, x, v, t, fe, 0.0, z) * fe
    else:
        fi = gsum + kst * x
        if spm != 0.0:
            mus = friction_chain(terms, mu_static(cp, stage, fn, th), x, v, t, fe, 0.0, z)
            fi += mus * spm * fe
    acc = (fd - cp[P_CINT] * v - fi + plugin_force(terms, x, v, t, fe, z)
           + parallel_spring_force(cp, x)) / cp[P_M]
    state_rates(terms, x, v, t, fe, z, dz)
    return acc, dth, de


@njit(cache=True)
def _rk4(cp: np.ndarray, terms: Any, gslip: bool, sign: int, stage: int, gsum: float,
         kst: float, spm: float, seg: Segment, t_abs0: float, t0: float, h: float, x: float,
         v: float, th: float, e: float, z: np.ndarray, zw: np.ndarray,
         zout: np.ndarray) -> tuple[float, float, float, float]:
    """One classical RK4 step of (X, V, theta, e, z) from local time t0 by h; z's end into zout."""
    xs0, vs, fn0, fn1 = seg
    k1 = zw[0]
    k2 = zw[1]
    k3 = zw[2]
    k4 = zw[3]
    zt = zw[4]
    nz = z.shape[0]
    a1, t1, e1 = _rhs(cp, terms, gslip, sign, stage, gsum, kst, spm, t_abs0 + t0,
                      xs0 + vs * t0, vs, fn0 + fn1 * t0, x, v, th, e, z, k1)
    tm = t0 + 0.5 * h
    for i in range(nz):
        zt[i] = z[i] + 0.5 * h * k1[i]
    a2, t2, e2 = _rhs(cp, terms, gslip, sign, stage, gsum, kst, spm, t_abs0 + tm,
                      xs0 + vs * tm, vs, fn0 + fn1 * tm, x + 0.5 * h * v, v + 0.5 * h * a1,
                      th + 0.5 * h * t1, e + 0.5 * h * e1, zt, k2)
    v2 = v + 0.5 * h * a1
    for i in range(nz):
        zt[i] = z[i] + 0.5 * h * k2[i]
    a3, t3, e3 = _rhs(cp, terms, gslip, sign, stage, gsum, kst, spm, t_abs0 + tm,
                      xs0 + vs * tm, vs, fn0 + fn1 * tm, x + 0.5 * h * v2, v + 0.5 * h * a2,
                      th + 0.5 * h * t2, e + 0.5 * h * e2, zt, k3)
    v3 = v + 0.5 * h * a2
    te = t0 + h
    for i in range(nz):
        zt[i] = z[i] + h * k3[i]
    a4, t4, e4 = _rhs(cp, terms, gslip, sign, stage, gsum, kst, spm, t_abs0 + te,
                      xs0 + vs * te, vs, fn0 + fn1 * te, x + h * v3, v + h * a3, th + h * t3,
                      e + h * e3, zt, k4)
    v4 = v + h * a3
    for i in range(nz):
        zout[i] = z[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    return (x + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4),
            v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4),
            th + h / 6.0 * (t1 + 2.0 * t2 + 2.0 * t3 + t4),
            e + h / 6.0 * (e1 + 2.0 * e2 + 2.0 * e3 + e4))


@njit(cache=True, inline="always")
def _element_mu(terms: Any, mus0: float, t: float, x: float, v: float,
                fe: float, z: np.ndarray, tstick: np.ndarray, i: int, last_t0: float,
                last_mu: float) -> float:
    """mu_s,eff of element i (its stick time t - tstick[i]); reuses last_mu when the element
    stuck at the same instant as the previous one asked (elements stick together after a slip)."""
    if tstick[i] == last_t0:
        return last_mu
    return friction_chain(terms, mus0, x, v, t, fe, t - tstick[i], z)


@njit(cache=True, inline="always")
def _stuck_crossing(terms: Any, mus0: float, t: float, x: float, v: float, fe: float,
                    z: np.ndarray, tstick: np.ndarray, i: int, share: float, g_i: float, k: float,
                    last_t0: float, last_mu: float) -> tuple[int, float]:
    """(+1 or -1 when stuck element i has reached its static threshold mu_s,eff P_i m_i Fn_eff
    in that direction, else 0; its mu_s,eff). Its force is g_i + k X (``share`` = P_i m_i)."""
    mu_i = _element_mu(terms, mus0, t, x, v, fe, z, tstick, i, last_t0, last_mu)
    c = mu_i * share * fe
    f = g_i + k * x
    if f >= c:
        return 1, mu_i
    if f <= -c:
        return -1, mu_i
    return 0, mu_i


@njit(cache=True, inline="always")
def _reverses(mode_i: int, v: float) -> bool:
    """A presliding element's velocity has turned against its direction: it sticks again."""
    return (mode_i > 0 and v < 0.0) or (mode_i < 0 and v > 0.0)


@njit(cache=True)
def _event(cp: np.ndarray, weights: np.ndarray, terms: Any, g: np.ndarray, mode: np.ndarray,
           tstick: np.ndarray, gslip: bool, sign: int, stage: int, k: float, t: float,
           xs: float, fn: float, x: float, v: float, th: float, z: np.ndarray) -> bool:
    """Has an event happened at this state? (the end of a trial step)"""
    if gslip:
        return sign * v <= 0.0
    pw = weights[stage]
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - x)
    mus0 = mu_static(cp, stage, fn, th)
    last_t0 = np.nan
    last_mu = 0.0
    for i in range(g.shape[0]):
        if mode[i] == 0:
            d, last_mu = _stuck_crossing(terms, mus0, t, x, v, fe, z, tstick, i, pw[i], g[i], k,
                                         last_t0, last_mu)
            last_t0 = tstick[i]
            if d != 0:
                return True
        elif _reverses(mode[i], v):
            return True
    return False


@njit(cache=True)
def _apply_stick_events(cp: np.ndarray, weights: np.ndarray, terms: Any, fs: np.ndarray,
                        ist: np.ndarray, g: np.ndarray, mode: np.ndarray, tstick: np.ndarray,
                        ev: np.ndarray, k: float, xs: float, vs: float, fn: float,
                        z: np.ndarray) -> None:
    """Elements start or stop presliding at the current state; none left stuck: a global slip."""
    stage = ist[I_STAGE]
    pw = weights[stage]
    t = fs[S_T]
    x = fs[S_X]
    v = fs[S_V]
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - x)
    mus0 = mu_static(cp, stage, fn, fs[S_THETA])
    mus_sl = friction_chain(terms, mus0, x, v, t, fe, 0.0, z)
    n_left = 0
    dir_sum = 0
    last_t0 = np.nan
    last_mu = 0.0
    for i in range(g.shape[0]):
        if mode[i] == 0:
            d, last_mu = _stuck_crossing(terms, mus0, t, x, v, fe, z, tstick, i, pw[i], g[i], k,
                                         last_t0, last_mu)
            last_t0 = tstick[i]
            mode[i] = d
            if d == 0:
                n_left += 1
        elif _reverses(mode[i], v):
            g[i] = mode[i] * mus_sl * pw[i] * fe - k * x  # it sticks again keeping its force
            mode[i] = 0
            tstick[i] = t
            n_left += 1
        dir_sum += mode[i]
    if n_left == 0:
        start_global_slip(cp, fs, ist, mode, ev, xs, vs, fn, 1 if dir_sum >= 0 else -1)


@njit(cache=True)
def _end_slip(cp: np.ndarray, weights: np.ndarray, terms: Any, fs: np.ndarray, ist: np.ndarray,
              g: np.ndarray, mode: np.ndarray, tstick: np.ndarray, ev: np.ndarray, xs: float,
              vs: float, fn: float, z: np.ndarray) -> None:
    """End the global slip (V = 0): every element sticks keeping the kinetic force it carried,
    capped by its static threshold, both through the plug-in friction terms (as
    :func:`rigctl.model.kernel.global_slip.end_global_slip` without terms)."""
    sign = ist[I_SIGN]
    x = fs[S_X]
    t = fs[S_T]
    th = fs[S_THETA]
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - x)
    muk = friction_chain(terms, kinetic_mu(cp, fn, 0.0, th, fs[S_STRIB]), x, 0.0, t, fe, 0.0, z)
    mus = friction_chain(terms, mu_static(cp, 1, fn, th), x, 0.0, t, fe, 0.0, z)
    end_global_slip(cp, weights, fs, ist, g, mode, ev, xs, vs, fn)
    k = fs[S_K_USED]
    pw1 = weights[W_STABLE]
    p_uni = weights[W_UNIFORM]
    for i in range(g.shape[0]):
        g[i] = sign * min(muk * p_uni[i], mus * pw1[i]) * fe - k * x
        tstick[i] = t


@njit(cache=True)
def _cap_e(cp: np.ndarray, terms: Any, sign: int, stage: int, seg: Segment, t_abs0: float,
           t0: float, h: float, x: float, v: float, th: float, e: float, z: np.ndarray,
           xn: float, vn: float, thn: float, en: float, zn: np.ndarray, zw: np.ndarray,
           arrest: bool) -> float:
    """The Stribeck bound e at the end of a global slip's step from local time t0 by h, as the
    exact path caps it (:func:`rigctl.model.kernel.nonlinear_slip.cap_on_step`): where the law
    rises over the step its minimum is sought inside the step, on the Hermite interpolants built
    with the accelerations of this path (plug-in terms included); in the step that ends the slip
    (``arrest``) also on the geometric grid towards V = 0. Capping by the law at the step's end
    only would miss that minimum and re-stick the elements carrying up to the law's whole rise
    within the last step (docs/model.md, "Re-stick with velocity-dependent friction")."""
    law0, law_e = step_laws(cp, seg, t0, h, v, vn)
    if law_e <= law0:
        return min(en, law_e)
    xs0, vs, fn0, fn1 = seg
    te = t0 + h
    acc0, _, _ = _rhs(cp, terms, True, sign, stage, 0.0, 0.0, 0.0, t_abs0 + t0, xs0 + vs * t0,
                      vs, fn0 + fn1 * t0, x, v, th, e, z, zw[0])
    acc1, _, _ = _rhs(cp, terms, True, sign, stage, 0.0, 0.0, 0.0, t_abs0 + te, xs0 + vs * te,
                      vs, fn0 + fn1 * te, xn, vn, thn, en, zn, zw[0])
    return cap_on_step(cp, seg, t0, h, x, v, acc0, xn, vn, acc1, en, law_e, arrest)


@njit(cache=True)
def _store(fs: np.ndarray, z: np.ndarray, x: float, v: float, th: float, e: float,
           zn: np.ndarray) -> None:
    fs[S_X] = x
    fs[S_V] = v
    fs[S_THETA] = th
    fs[S_STRIB] = e
    z[:] = zn


@njit(cache=True)
def general_step(cp: np.ndarray, weights: np.ndarray, terms: Any, fs: np.ndarray,
                 ist: np.ndarray, g: np.ndarray, mode: np.ndarray, tstick: np.ndarray,
                 z: np.ndarray, zw: np.ndarray, ev: np.ndarray, seg: Segment, h: float,
                 h_rk: float) -> tuple[float, bool, bool]:
    """Advance by at most h with RK4, applying events; (time advanced, slip ended, term error).

    Stops right after a global slip ends (so that slip hooks can run) and, with the state of the
    step before it kept, where a step gives a non-finite state (``ist[I_TERM_ERR]`` = 1)."""
    xs0, vs, fn0, fn1 = seg
    n = g.shape[0]
    t_abs0 = fs[S_T]
    aging = cp[P_RS_A] != 0.0 or cp[P_RS_B] != 0.0
    tau_s = cp[P_TAU_S]
    zn = zw[5]
    tloc = 0.0
    n_events = 0
    while tloc < h:
        gslip = ist[I_GSLIP] == 1
        sign = ist[I_SIGN]
        stage = ist[I_STAGE]
        x = fs[S_X]
        v = fs[S_V]
        th = fs[S_THETA]
        e = fs[S_STRIB]
        fn_a = fn0 + fn1 * tloc
        hs = min(h_rk, h - tloc)
        if gslip and aging:
            hs = aging_limited_step(cp, v, hs)
        k = 0.0
        gsum = 0.0
        kst = 0.0
        spm = 0.0
        if not gslip:
            k = element_stiffness(cp, stage, fn_a, n)
            k_old = fs[S_K_USED]
            if k != k_old:
                for i in range(n):
                    if mode[i] == 0:
                        g[i] = g[i] + (k_old - k) * x
                fs[S_K_USED] = k
            pw = weights[stage]
            for i in range(n):
                if mode[i] == 0:
                    gsum += g[i]
                    kst += k
                else:
                    spm += mode[i] * pw[i]
        xn, vn, thn, en = _rk4(cp, terms, gslip, sign, stage, gsum, kst, spm, seg, t_abs0, tloc,
                               hs, x, v, th, e, z, zw, zn)
        while gslip and aging and (thn < 0.0 or max(abs(v), abs(vn)) * hs
                                   > AGING_STEP_LIMIT * cp[P_RS_DC]) and hs > 1e-15:
            hs = 0.5 * hs  # the slip sped up within the step: redo it shorter
            xn, vn, thn, en = _rk4(cp, terms, gslip, sign, stage, gsum, kst, spm, seg, t_abs0,
                                   tloc, hs, x, v, th, e, z, zw, zn)
        ok = math.isfinite(xn) and math.isfinite(vn) and math.isfinite(thn)
        for i in range(zn.shape[0]):
            ok = ok and math.isfinite(zn[i])
        if not ok:
            fs[S_T] = t_abs0 + tloc
            ist[I_TERM_ERR] = 1
            return tloc, False, True
        te = tloc + hs
        event = n_events <= MAX_STEPS_PER_SAMPLE and _event(
            cp, weights, terms, g, mode, tstick, gslip, sign, stage, k, t_abs0 + te,
            xs0 + vs * te, fn0 + fn1 * te, xn, vn, thn, zn)
        if event:
            lo = 0.0
            hi = hs
            for _ in range(BISECT_STEPS):
                mid = 0.5 * (lo + hi)
                if mid <= lo or mid >= hi:
                    break
                xm, vm, thm, _ = _rk4(cp, terms, gslip, sign, stage, gsum, kst, spm, seg,
                                      t_abs0, tloc, mid, x, v, th, e, z, zw, zn)
                if _event(cp, weights, terms, g, mode, tstick, gslip, sign, stage, k,
                          t_abs0 + tloc + mid, xs0 + vs * (tloc + mid), fn0 + fn1 * (tloc + mid),
                          xm, vm, thm, zn):
                    hi = mid
                else:
                    lo = mid
            hs = hi
            te = tloc + hs
            xn, vn, thn, en = _rk4(cp, terms, gslip, sign, stage, gsum, kst, spm, seg, t_abs0,
                                   tloc, hs, x, v, th, e, z, zw, zn)
            n_events += 1
            if n_events == MAX_STEPS_PER_SAMPLE + 1:
                ist[I_CHATTER] += 1
        xs_e = xs0 + vs * te
        fn_e = fn0 + fn1 * te
        if tau_s > 0.0:
            fd0 = drive_force(cp, xs0 + vs * tloc, vs, x, v)
            fd1 = drive_force(cp, xs_e, vs, xn, vn)
            slope_f = (fd1 - fd0) / hs
            decay = math.exp(-hs / tau_s)
            fs[S_YF] = fd1 - slope_f * tau_s + (fs[S_YF] - fd0 + slope_f * tau_s) * decay
        if gslip:
            en = _cap_e(cp, terms, sign, stage, seg, t_abs0, tloc, hs, x, v, th, e, z, xn, vn,
                        thn, en, zn, zw, event)
            if event:
                vn = 0.0
            note_slip_force(fs, sign, drive_force(cp, xs_e, vs, xn, vn))
            note_slip_speed(fs, vn)
        _store(fs, z, xn, vn, thn if gslip else th + hs, en, zn)
        tloc = te
        if event:
            fs[S_T] = t_abs0 + tloc
            if gslip:
                _end_slip(cp, weights, terms, fs, ist, g, mode, tstick, ev, xs_e, vs, fn_e, z)
                return tloc, True, False
            _apply_stick_events(cp, weights, terms, fs, ist, g, mode, tstick, ev, k, xs_e, vs,
                                fn_e, z)
    fs[S_T] = t_abs0 + h
    return h, False, False


@njit(cache=True)
def interface_force_terms(cp: np.ndarray, weights: np.ndarray, terms: Any, fs: np.ndarray,
                          ist: np.ndarray, g: np.ndarray, mode: np.ndarray, tstick: np.ndarray,
                          xs: float, fn: float, z: np.ndarray) -> float:
    """F_interface at the current state, with the plug-in friction terms (an output sample)."""
    x = fs[S_X]
    v = fs[S_V]
    t = fs[S_T]
    th = fs[S_THETA]
    fe = fn + cp[P_KAPPA] * cp[P_K0] * (xs - x)
    if ist[I_GSLIP] == 1:
        mu = kinetic_mu(cp, fn, abs(v), th, fs[S_STRIB])
        return ist[I_SIGN] * friction_chain(terms, mu, x, v, t, fe, 0.0, z) * fe
    stage = ist[I_STAGE]
    pw = weights[stage]
    k = fs[S_K_USED]
    fi = 0.0
    spm = 0.0
    for i in range(g.shape[0]):
        if mode[i] == 0:
            fi += g[i] + k * x
        else:
            spm += mode[i] * pw[i]
    if spm != 0.0:
        fi += friction_chain(terms, mu_static(cp, stage, fn, th), x, v, t, fe, 0.0, z) * spm * fe
    return fi


@njit(cache=True)
def advance_terms(
    cp: np.ndarray,
    weights: np.ndarray,
    terms: Any,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    tstick: np.ndarray,
    z: np.ndarray,
    knots: np.ndarray,
    t_out: np.ndarray,
    out: np.ndarray,
    flags: np.ndarray,
    elem: np.ndarray,
    ev: np.ndarray,
    t_stop: float,
    stop_on_slip_end: bool,
    record_elements: bool,
) -> int:
    """:func:`rigctl.model.kernel.loop.advance` for a model with plug-in terms (the general path).

    The same arrays and return codes, plus the terms (:meth:`rigctl.model.terms.TermSet.bundle`),
    each element's stick start time ``tstick`` and the plug-ins' state ``z``; RET_TERM_ERROR when
    a term made the state non-finite (the state is left at the last finite step)."""
    h_rk = rk_step_s(cp)
    zw = np.zeros((6, z.shape[0]))
    while True:
        j = current_knot(knots, fs, ist)
        io, xs, fn = write_due_sample(cp, weights, fs, ist, g, mode, knots, j, t_out, out, flags,
                                      elem, record_elements)
        if io >= 0:
            out[O_FI, io] = interface_force_terms(cp, weights, terms, fs, ist, g, mode, tstick,
                                                  xs, fn, z)
            continue
        code, target = step_end(fs, ist, ev, knots, j, t_out, t_stop)
        if code != STEP:
            return code
        t = fs[S_T]
        h = target - t
        seg = segment_at(knots, j, t)
        if apart(seg, h):
            ended = free_step(cp, weights, fs, ist, g, mode, ev, seg, h)
            fs[S_T] = target
            tstick[:] = target
            if ended and stop_on_slip_end:
                return RET_SLIP_END
            continue
        tau, ended, err = general_step(cp, weights, terms, fs, ist, g, mode, tstick, z, zw, ev,
                                       seg, h, h_rk)
        if err:
            return RET_TERM_ERROR
        if tau >= h:
            fs[S_T] = target
        if ended and stop_on_slip_end:
            return RET_SLIP_END
