"""Global slip with velocity- or state-dependent kinetic friction, by classical RK4 (docs/model.md, 3).

When the kinetic friction depends on V or theta (``stribeck``, ``rate_state``) the global slip alone
is integrated numerically, at 1/64 of the drive period (convergence tested); its end (V = 0) is
located on the cubic Hermite interpolant of the last step. The Stribeck part of the slip friction
rises no faster than elastic loading of the elements allows (docs/model.md, section 2, "Re-stick
with velocity-dependent friction").
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from rigctl.model.friction_laws import (
    element_stiffness,
    mu_kinetic_base,
    stribeck_amplitude,
    stribeck_shape,
)
from rigctl.model.kernel.event_search import BISECT_ITERS
from rigctl.model.kernel.forces import drive_force, parallel_spring_force
from rigctl.model.kernel.global_slip import end_global_slip, note_slip_force, note_slip_speed
from rigctl.model.kernel.inputs import Segment
from rigctl.model.layout import (
    FN_CONTACT_MIN_N,
    I_SIGN,
    P_CINT,
    P_K0,
    P_KAPPA,
    P_M,
    P_RS_A,
    P_RS_B,
    P_RS_DC,
    P_TAU_S,
    P_VS,
    S_STRIB,
    S_T,
    S_THETA,
    S_V,
    S_X,
    S_YF,
)

RK_STEPS_PER_PERIOD = 64  # RK4 steps per drive period 2 pi sqrt(M/K0); 512 changes events < 5e-5 s
CAP_GRID_UNIFORM = 16  # points of the uniform grid on which a rising Stribeck law is minimised
CAP_GRID_GEOMETRIC = 60  # further points towards V = 0 in the step that ends the slip
AGING_STEP_LIMIT = 2.0  # max |V| h / Dc of a step: the aging law's decay rate |V|/Dc times h stays
# inside RK4's stability interval (2.78) with theta kept positive (RK4's factor at -2 is 1/3);
# the paper preset's slips stay below 1.1, so the limit acts only for short D_c or fast slips


class SlipState(NamedTuple):
    """The integrated variables of a nonlinear global slip."""

    x: float
    """specimen position X [m]"""
    v: float
    """specimen velocity [m/s]"""
    th: float
    """rate-and-state variable theta [s]"""
    y: float
    """sensor filter output [N]"""
    e: float
    """Stribeck part of mu the sliding elements can carry [-]"""


@njit(cache=True)
def rk_step_s(cp: np.ndarray) -> float:
    """The RK4 step: 1/RK_STEPS_PER_PERIOD of the drive period 2 pi sqrt(M/K0)."""
    return 2.0 * math.pi * math.sqrt(cp[P_M] / cp[P_K0]) / RK_STEPS_PER_PERIOD


@njit(cache=True)
def stribeck_law(cp: np.ndarray, fn: float, v_abs: float) -> float:
    """Stribeck part of the steady-sliding kinetic coefficient at |V| (0 when stribeck is off)."""
    if cp[P_VS] <= 0.0:
        return 0.0
    return stribeck_amplitude(cp, fn) * stribeck_shape(cp, v_abs)


@njit(cache=True)
def kinetic_mu(cp: np.ndarray, fn: float, v_abs: float, th: float, e: float) -> float:
    """The kinetic coefficient of a global slip: mu_k,base(|V|, theta) + min(e, law(|V|)).

    The Stribeck part is the law's value capped by e, what the sliding elements can carry
    (:func:`slip_rhs`); it is absent when stribeck is off."""
    mu = mu_kinetic_base(cp, fn, v_abs, th)
    if cp[P_VS] > 0.0:
        mu += min(e, stribeck_law(cp, fn, v_abs))
    return mu


@njit(cache=True)
def slip_friction(cp: np.ndarray, fn: float, fe: float, v_abs: float, th: float,
                  e: float) -> tuple[float, float, float]:
    """(mu, theta', e') in a global slip: the kinetic coefficient (:func:`kinetic_mu`), the aging
    law d theta/dt = 1 - |V| theta / Dc (1 when rate_state is off, so theta keeps the contact's
    age) and the elastic loading rate of the Stribeck bound, de/dt = Kt |V| / Fn_eff
    (:func:`slip_rhs`)."""
    mu = kinetic_mu(cp, fn, v_abs, th, e)
    de = 0.0
    if cp[P_VS] > 0.0:
        de = element_stiffness(cp, 1, fn, 1) * v_abs / max(fe, FN_CONTACT_MIN_N)
    dth = 1.0
    if cp[P_RS_A] != 0.0 or cp[P_RS_B] != 0.0:
        dth = 1.0 - v_abs * th / cp[P_RS_DC]
    return mu, dth, de


@njit(cache=True)
def slip_rhs(
    cp: np.ndarray, sign: int, s: SlipState, xs: float, vs: float, fn: float
) -> tuple[float, float, float, float]:
    """(V', theta', y', e') during a global slip with velocity/state-dependent kinetic friction.

    e bounds the Stribeck part of mu the sliding elements can carry: it grows as their springs
    would load, de/dt = Kt |V| / Fn_eff, and is capped by the Stribeck law
    (mu_s - mu_k) exp(-(|V|/v_s)^d) at the end of every step (:func:`cap_stribeck`), so the
    friction mu_k,base(V, theta) + min(e, law(V)) follows the law where it falls and rises no
    faster than elastic loading allows (docs/model.md, "Re-stick with velocity-dependent
    friction").
    """
    x, v, th, y, e = s
    k0 = cp[P_K0]
    fe = fn + cp[P_KAPPA] * k0 * (xs - x)
    fd = drive_force(cp, xs, vs, x, v)
    mu, dth, de = slip_friction(cp, fn, fe, abs(v), th, e)
    acc = (fd - cp[P_CINT] * v - sign * mu * fe + parallel_spring_force(cp, x)) / cp[P_M]
    dy = 0.0
    if cp[P_TAU_S] > 0.0:
        dy = (fd - y) / cp[P_TAU_S]
    return acc, dth, dy, de


@njit(cache=True)
def _acceleration(cp: np.ndarray, sign: int, s: SlipState, seg: Segment, t: float) -> float:
    acc, _, _, _ = slip_rhs(cp, sign, s, seg.xs0 + seg.vs * t, seg.vs, seg.fn0 + seg.fn1 * t)
    return acc


@njit(cache=True)
def rk4(cp: np.ndarray, sign: int, s: SlipState, seg: Segment, t0: float, h: float) -> SlipState:
    """One classical Runge-Kutta step of (X, V, theta, y, e) from local time t0 by h.

    e is returned uncapped (the caller applies :func:`cap_stribeck`).
    """
    x, v, th, y, e = s
    xs0, vs, fn0, fn1 = seg
    a1, t1, y1, e1 = slip_rhs(cp, sign, s, xs0 + vs * t0, vs, fn0 + fn1 * t0)
    tm = t0 + 0.5 * h
    xs_m = xs0 + vs * tm
    fn_m = fn0 + fn1 * tm
    a2, t2, y2, e2 = slip_rhs(
        cp, sign,
        SlipState(x + 0.5 * h * v, v + 0.5 * h * a1, th + 0.5 * h * t1, y + 0.5 * h * y1,
                  e + 0.5 * h * e1),
        xs_m, vs, fn_m,
    )
    v2 = v + 0.5 * h * a1
    a3, t3, y3, e3 = slip_rhs(
        cp, sign,
        SlipState(x + 0.5 * h * v2, v + 0.5 * h * a2, th + 0.5 * h * t2, y + 0.5 * h * y2,
                  e + 0.5 * h * e2),
        xs_m, vs, fn_m,
    )
    v3 = v + 0.5 * h * a2
    te = t0 + h
    a4, t4, y4, e4 = slip_rhs(
        cp, sign,
        SlipState(x + h * v3, v + h * a3, th + h * t3, y + h * y3, e + h * e3),
        xs0 + vs * te, vs, fn0 + fn1 * te,
    )
    v4 = v + h * a3
    xn = x + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
    vn = v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    thn = th + h / 6.0 * (t1 + 2.0 * t2 + 2.0 * t3 + t4)
    yn = y + h / 6.0 * (y1 + 2.0 * y2 + 2.0 * y3 + y4)
    en = e + h / 6.0 * (e1 + 2.0 * e2 + 2.0 * e3 + e4)
    return SlipState(xn, vn, thn, yn, en)


@njit(cache=True)
def cap_stribeck(
    cp: np.ndarray,
    sign: int,
    s0: SlipState,
    s1: SlipState,
    seg: Segment,
    t0: float,
    h: float,
    arrest: bool,
) -> float:
    """Stribeck part the elements can carry at the end of an RK step from s0 at t0 to s1 at t0 + h
    (:func:`cap_on_step` with the accelerations of :func:`slip_rhs` at both ends)."""
    law0, law_e = step_laws(cp, seg, t0, h, s0.v, s1.v)
    if law_e <= law0:
        return min(s1.e, law_e)
    acc0 = _acceleration(cp, sign, s0, seg, t0)
    acc1 = _acceleration(cp, sign, s1, seg, t0 + h)
    return cap_on_step(cp, seg, t0, h, s0.x, s0.v, acc0, s1.x, s1.v, acc1, s1.e, law_e, arrest)


@njit(cache=True)
def step_laws(cp: np.ndarray, seg: Segment, t0: float, h: float, v0: float,
              v1: float) -> tuple[float, float]:
    """The Stribeck law at the start and at the end of a step from local time t0 by h (both 0
    when stribeck is off). Only where it rises over the step (the slip decelerating into the band
    |V| < v_s) can its minimum lie inside the step (:func:`cap_on_step`); elsewhere the cap is
    min(e, law at the end)."""
    return (stribeck_law(cp, seg.fn0 + seg.fn1 * t0, abs(v0)),
            stribeck_law(cp, seg.fn0 + seg.fn1 * (t0 + h), abs(v1)))


@njit(cache=True)
def cap_on_step(
    cp: np.ndarray,
    seg: Segment,
    t0: float,
    h: float,
    x: float,
    v: float,
    acc0: float,
    xn: float,
    vn: float,
    acc1: float,
    e_n: float,
    law_e: float,
    arrest: bool,
) -> float:
    """Stribeck part the elements can carry at the end of a step from (x, v) at t0 to (xn, vn) at
    t0 + h over which the law rises (:func:`step_laws`), with the accelerations acc0, acc1 at its
    ends; e_n is the step's uncapped e, law_e the law at its end.

    e(t) = min over s <= t of [law(V(s)) + (Kt / Fn_eff) |X(t) - X(s)|]: the law's value at some
    earlier instant plus the elastic loading since (e_n is the s = start term). As the law rises
    over the step (the slip decelerating into the Stribeck region) the minimum is sought on the
    cubic Hermite interpolants of X and V over the step, on a uniform grid and, in the step that
    ends the slip (``arrest``: V -> 0), on a geometric one towards its end, so the law's rise
    within a velocity band narrower than the step is seen, however small v_s. Both paths cap e
    with it (the exact path's nonlinear slips, :mod:`rigctl.model.kernel.general`).
    """
    xs0, vs, fn0, fn1 = seg
    te = t0 + h
    fn_e = fn0 + fn1 * te
    cap = min(e_n, law_e)
    fe = max(fn_e + cp[P_KAPPA] * cp[P_K0] * (xs0 + vs * te - xn), FN_CONTACT_MIN_N)
    kfe = element_stiffness(cp, 1, fn_e, 1) / fe
    n_uni = CAP_GRID_UNIFORM
    n_geo = CAP_GRID_GEOMETRIC if arrest else 0
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
        cand = stribeck_law(cp, fn0 + fn1 * tj, abs(vj)) + kfe * abs(xn - xj)
        if cand < cap:
            cap = cand
    return cap


@njit(cache=True)
def _arrest_fraction(
    cp: np.ndarray, sign: int, s0: SlipState, s1: SlipState, seg: Segment, t0: float, h: float
) -> float:
    """Fraction of the step t0 -> t0 + h at which V = 0, on the cubic Hermite interpolant of V."""
    acc0 = _acceleration(cp, sign, s0, seg, t0)
    acc1 = _acceleration(cp, sign, s1, seg, t0 + h)
    v = s0.v
    vn = s1.v
    lo = 0.0
    hi = 1.0
    for _ in range(BISECT_ITERS):
        s = 0.5 * (lo + hi)
        h00 = 2 * s**3 - 3 * s**2 + 1
        h10 = s**3 - 2 * s**2 + s
        h01 = -2 * s**3 + 3 * s**2
        h11 = s**3 - s**2
        vs_ = h00 * v + h10 * h * acc0 + h01 * vn + h11 * h * acc1
        if sign * vs_ <= 0.0:
            hi = s
        else:
            lo = s
    return hi


@njit(cache=True)
def _aging_step_ok(cp: np.ndarray, s0: SlipState, s1: SlipState, hs: float) -> bool:
    """A step of the aging law is stable: finite, theta >= 0, |V| hs <= AGING_STEP_LIMIT Dc."""
    if not (math.isfinite(s1.x) and math.isfinite(s1.v) and math.isfinite(s1.th)):
        return False
    return s1.th >= 0.0 and max(abs(s0.v), abs(s1.v)) * hs <= AGING_STEP_LIMIT * cp[P_RS_DC]


@njit(cache=True)
def aging_limited_step(cp: np.ndarray, v: float, hs: float) -> float:
    """hs, shortened so that |v| hs <= AGING_STEP_LIMIT Dc (a NaN v keeps hs)."""
    lim = AGING_STEP_LIMIT * cp[P_RS_DC]
    if abs(v) * hs > lim:
        return lim / abs(v)
    return hs


@njit(cache=True)
def _store(fs: np.ndarray, s: SlipState) -> None:
    fs[S_X] = s.x
    fs[S_V] = s.v
    fs[S_THETA] = s.th
    fs[S_YF] = s.y
    fs[S_STRIB] = s.e


@njit(cache=True)
def nonlinear_slip_step(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    ev: np.ndarray,
    seg: Segment,
    h: float,
    h_rk: float,
) -> tuple[float, bool]:
    """Integrate a global slip by at most h with RK4; end it where the velocity returns to zero."""
    sign = ist[I_SIGN]
    xs0, vs, fn0, fn1 = seg
    s = SlipState(fs[S_X], fs[S_V], fs[S_THETA], fs[S_YF], fs[S_STRIB])
    aging = cp[P_RS_A] != 0.0 or cp[P_RS_B] != 0.0
    tloc = 0.0
    while tloc < h:
        hs = min(h_rk, h - tloc)
        if aging:
            hs = aging_limited_step(cp, s.v, hs)
        sn = rk4(cp, sign, s, seg, tloc, hs)
        while aging and not _aging_step_ok(cp, s, sn, hs):
            # the slip sped up within the step (or the step blew up): redo it shorter
            hs = aging_limited_step(cp, abs(sn.v), 0.5 * hs)
            sn = rk4(cp, sign, s, seg, tloc, hs)
        if sign * sn.v <= 0.0 and tloc + hs > 0.0:
            # locate V = 0 on the cubic Hermite interpolant of V over the step, then redo the step
            hpart = _arrest_fraction(cp, sign, s, sn, seg, tloc, hs) * hs
            sn = rk4(cp, sign, s, seg, tloc, hpart)
            en = cap_stribeck(cp, sign, s, sn, seg, tloc, hpart, True)
            tloc += hpart
            _store(fs, SlipState(sn.x, 0.0, sn.th, sn.y, en))
            fs[S_T] += tloc
            xs1 = xs0 + vs * tloc
            note_slip_force(fs, sign, drive_force(cp, xs1, vs, sn.x, 0.0))
            end_global_slip(cp, weights, fs, ist, g, mode, ev, xs1, vs, fn0 + fn1 * tloc)
            return tloc, True
        en = cap_stribeck(cp, sign, s, sn, seg, tloc, hs, False)
        s = SlipState(sn.x, sn.v, sn.th, sn.y, en)
        tloc += hs
        note_slip_force(fs, sign, drive_force(cp, xs0 + vs * tloc, vs, s.x, s.v))
        note_slip_speed(fs, s.v)
    _store(fs, s)
    fs[S_T] += h
    return h, False
