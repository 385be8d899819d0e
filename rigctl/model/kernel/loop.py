"""The main loop: walk the input knots and output samples, choosing a step for each interval.

The step: the fast stick recurrence where it applies (constant inputs, no event possible before the
next sample), the free step with the specimens apart, RK4 for a global slip with
velocity/state-dependent friction, otherwise the exact linear step. Every step reads the terms
linear in the slider's state that effects declare (:class:`rigctl.model.effects.base.LinearTerms`:
the drag ``P_CINT``, the parallel spring ``P_KPAR`` relaxed at ``P_XPAR``, the normal coupling
``P_KAPPA``) from the coefficient vector, so a model with them keeps this loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import slip_is_nonlinear
from rigctl.model.kernel.fast_stick import fast_stick_run
from rigctl.model.kernel.free_step import free_step
from rigctl.model.kernel.inputs import segment_at
from rigctl.model.kernel.linear_step import linear_step
from rigctl.model.kernel.nonlinear_slip import nonlinear_slip_step, rk_step_s
from rigctl.model.kernel.walk import STEP, apart, current_knot, step_end, write_due_sample
from rigctl.model.layout import (
    I_CHATTER,
    I_GSLIP,
    K_T,
    MAX_STEPS_PER_SAMPLE,
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
    kt_t = knots[K_T]
    nonlinear = slip_is_nonlinear(cp)
    h_rk = rk_step_s(cp)
    steps = 0
    while True:
        j = current_knot(knots, fs, ist)
        io, _, _ = write_due_sample(cp, weights, fs, ist, g, mode, knots, j, t_out, out, flags,
                                    elem, record_elements)
        if io >= 0:
            steps = 0
            continue
        code, target = step_end(fs, ist, ev, knots, j, t_out, t_stop)
        if code != STEP:
            return code
        t = fs[S_T]
        h = target - t
        seg = segment_at(knots, j, t)
        steps += 1
        if apart(seg, h):
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
