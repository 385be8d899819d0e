"""Finding the first event of a linear step: envelope test, grid scan, bisection (docs/model.md, 3).

Three kinds of event end a linear step: a stuck element reaching its threshold (X crossing a
threshold position), a presliding element's velocity reversing, the end of a global slip (V = 0).
A rigorous envelope bound on the exact solution rules out most intervals at once; where it cannot,
the interval is scanned on a grid of at most 1/16 of the ringing period and the first event is
located by bisection to round-off.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from rigctl.model.friction_laws import mu_static
from rigctl.model.kernel.forces import thresholds
from rigctl.model.kernel.inputs import Segment
from rigctl.model.layout import P_K0, P_KAPPA
from rigctl.model.modal import ModalSolution, position, velocity

BISECT_ITERS = 60  # halvings: 2^-60 of a step is below double round-off of any time in a run
GRID_PER_PERIOD = 16  # scan points per ringing period: a threshold graze shorter than this is missed
GRID_OVERDAMPED = 8  # scan points per step when there is no ringing (over-damped)


class ElementSet(NamedTuple):
    """What the event predicate needs to know about the elements during one linear step."""

    stage: int
    gslip: bool
    sign: int
    """direction of the running global slip (+1/-1)"""
    k: float
    """stiffness of one stuck element [N/m]"""
    n_stuck: int
    n_pos: int
    """elements presliding forward"""
    n_neg: int
    """elements presliding backward"""


@njit(cache=True)
def event_at(
    cp: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw: np.ndarray,
    el: ElementSet,
    sol: ModalSolution,
    seg: Segment,
    th0: float,
    tau: float,
) -> bool:
    """Has an event happened by tau? (monotone predicate used by the bisection)."""
    v = velocity(sol, tau)
    if el.gslip:
        return el.sign * v <= 0.0
    if el.n_pos > 0 and v < 0.0:
        return True
    if el.n_neg > 0 and v > 0.0:
        return True
    if el.n_stuck > 0:
        x = position(sol, tau)
        fn = seg.fn0 + seg.fn1 * tau
        mus = mu_static(cp, el.stage, fn, th0 + tau)
        lo, hi = thresholds(
            cp, g, mode, pw, el.k, mus, fn + cp[P_KAPPA] * cp[P_K0] * (seg.xs0 + seg.vs * tau)
        )
        if x >= lo or x <= hi:
            return True
    return False


@njit(cache=True)
def event_possible(
    cp: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw: np.ndarray,
    el: ElementSet,
    sol: ModalSolution,
    seg: Segment,
    th0: float,
    h: float,
) -> bool:
    """Envelope test: False only if no event can happen in [0, h].

    |X - (a + b tau)| <= |c1| + |c2| and |V - b| <= |c1 l1| + |c2 l2| for all tau; the thresholds
    are compared at both ends of the step (they move monotonically with Fn and theta).
    """
    x_osc = abs(sol.c1) + abs(sol.c2)
    v_osc = abs(sol.c1 * sol.l1) + abs(sol.c2 * sol.l2)
    xa = sol.a
    xb = sol.a + sol.b * h
    x_max = max(xa, xb) + x_osc
    x_min = min(xa, xb) - x_osc
    v_max = sol.b + v_osc
    v_min = sol.b - v_osc
    if el.gslip:
        return (v_min <= 0.0) if el.sign > 0 else (v_max >= 0.0)
    possible = False
    if el.n_stuck > 0:
        kk0 = cp[P_KAPPA] * cp[P_K0]
        fn0 = seg.fn0
        fn_h = seg.fn0 + seg.fn1 * h
        mus_a = mu_static(cp, el.stage, fn0, th0)
        mus_b = mu_static(cp, el.stage, fn_h, th0 + h)
        lo_a, hi_a = thresholds(cp, g, mode, pw, el.k, mus_a, fn0 + kk0 * seg.xs0)
        lo_b, hi_b = thresholds(
            cp, g, mode, pw, el.k, mus_b, fn_h + kk0 * (seg.xs0 + seg.vs * h)
        )
        if x_max >= min(lo_a, lo_b) or x_min <= max(hi_a, hi_b):
            possible = True
    if el.n_pos > 0 and v_min < 0.0:
        possible = True
    if el.n_neg > 0 and v_max > 0.0:
        possible = True
    return possible


@njit(cache=True)
def first_event(
    cp: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    pw: np.ndarray,
    el: ElementSet,
    sol: ModalSolution,
    seg: Segment,
    th0: float,
    h: float,
) -> float:
    """Time of the first event in (0, h], located to round-off; -1 if the grid scan finds none."""
    wd = abs(sol.l1.imag)
    step = h / GRID_OVERDAMPED
    if wd > 0.0:
        step = min(h, 2.0 * math.pi / wd / GRID_PER_PERIOD)
    n_grid = max(1, math.ceil(h / step))
    lo_t = 0.0
    hi_t = -1.0
    for j in range(1, n_grid + 1):
        tj = h * j / n_grid
        if event_at(cp, g, mode, pw, el, sol, seg, th0, tj):
            hi_t = tj
            break
        lo_t = tj
    if hi_t > 0.0:
        for _ in range(BISECT_ITERS):
            mid = 0.5 * (lo_t + hi_t)
            if mid <= lo_t or mid >= hi_t:
                break
            if event_at(cp, g, mode, pw, el, sol, seg, th0, mid):
                hi_t = mid
            else:
                lo_t = mid
    return hi_t
