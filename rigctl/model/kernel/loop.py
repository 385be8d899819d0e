"""The main loop: walk the input knots and output samples, choosing a step for each interval.

The step: the fast stick recurrence where it applies (constant inputs, no event possible before the
next sample), the free step with the specimens apart, RK4 for a global slip with
velocity/state-dependent friction, otherwise the exact linear step.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import slip_is_nonlinear
from rigctl.model.kernel.fast_stick import fast_stick_run
from rigctl.model.kernel.free_step import free_step
from rigctl.model.kernel.inputs import interp, segment_at, slope
from rigctl.model.kernel.linear_step import linear_step
from rigctl.model.kernel.nonlinear_slip import nonlinear_slip_step, rk_step_s
from rigctl.model.kernel.output import write_sample
from rigctl.model.layout import (
    FN_CONTACT_MIN_N,
    I_CHATTER,
    I_GSLIP,
    I_KNOT,
    I_NEVENT,
    I_OUT,
    K_FN,
    K_T,
    K_XS,
    MAX_STEPS_PER_SAMPLE,
    RET_DONE,
    RET_EVENT_TABLE_FULL,
    RET_SLIP_END,
    S_T,
)


@njit(cache=True)
def advance(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
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
    """Integrate from the state in (fs, ist, g, mode) up to t_stop, writing output samples.

    Model: parameter vector ``cp`` and element weight table ``weights`` (rows W_*). State: ``fs``
    and ``ist`` (slots S_*, I_*), stuck offsets ``g`` and element modes ``mode`` (0 stuck, +-1
    sliding). Inputs x_stage(t) and Fn(t) are piecewise linear through ``knots`` (rows K_*); output
    samples are written at the times t_out[ist[I_OUT]:] reached, to ``out`` (float rows O_*),
    ``flags`` (uint8 rows F_*) and ``elem`` (element modes, when ``record_elements``); completed
    global slips to ``ev`` (columns E_*).
    Re-entrant: all state lives in the arrays, so a caller may stop (RET_SLIP_END,
    RET_EVENT_TABLE_FULL), act, and call again. Returns a RET_* code.
    """
    n_out = t_out.shape[0]
    nk = knots.shape[1]
    kt_t = knots[K_T]
    nonlinear = slip_is_nonlinear(cp)
    h_rk = rk_step_s(cp)
    steps = 0
    while True:
        t = fs[S_T]
        j = ist[I_KNOT]
        while j < nk - 2 and kt_t[j + 1] <= t:
            j += 1
        ist[I_KNOT] = j
        io = ist[I_OUT]
        if io < n_out and t_out[io] <= t:
            xs = interp(knots, K_XS, j, t)
            fn = max(interp(knots, K_FN, j, t), 0.0)
            vs = slope(knots, K_XS, j)
            write_sample(
                cp, weights, fs, ist, g, mode, io, xs, vs, fn, out, flags, elem, record_elements
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
        seg = segment_at(knots, j, t)
        steps += 1
        if seg.fn0 < FN_CONTACT_MIN_N and seg.fn0 + seg.fn1 * h < FN_CONTACT_MIN_N:
            ended = free_step(cp, weights, fs, ist, g, mode, ev, seg, h)
            fs[S_T] = target
            if ended and stop_on_slip_end:
                return RET_SLIP_END
            continue
        if seg.fn1 == 0.0 and ist[I_GSLIP] == 0:
            t_lim = min(t_stop, kt_t[j + 1])
            if fast_stick_run(
                cp, weights, fs, ist, g, mode, t_out, t_lim, seg.xs0, seg.vs, seg.fn0,
                out, flags, elem, record_elements,
            ) > 0:
                steps = 0
                continue
        if ist[I_GSLIP] == 1 and nonlinear:
            tau, ended = nonlinear_slip_step(cp, weights, fs, ist, g, mode, ev, seg, h, h_rk)
        else:
            allow = steps <= MAX_STEPS_PER_SAMPLE
            if steps == MAX_STEPS_PER_SAMPLE + 1:
                ist[I_CHATTER] += 1
            tau, ended = linear_step(cp, weights, fs, ist, g, mode, ev, seg, h, allow)
        if tau >= h:
            fs[S_T] = target  # land exactly on the knot / sample time
        if ended and stop_on_slip_end:
            return RET_SLIP_END
