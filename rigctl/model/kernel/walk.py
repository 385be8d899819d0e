"""The walk over input knots and output samples that both main loops share.

:func:`rigctl.model.kernel.loop.advance` (the exact path) and
:func:`rigctl.model.kernel.general.advance_terms` (the general path) repeat one cycle: find the
knot interval of the current time, write the output sample that is due, else choose the end of the
next step (the next knot, the next sample or the end of the span, whichever comes first) and step.
The pieces of that cycle that do not depend on the path are here.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.kernel.inputs import Segment, interp, slope
from rigctl.model.kernel.output import write_sample
from rigctl.model.layout import (
    FN_CONTACT_MIN_N,
    I_KNOT,
    I_NEVENT,
    I_OUT,
    K_FN,
    K_T,
    K_XS,
    RET_DONE,
    RET_EVENT_TABLE_FULL,
    S_T,
)

STEP = -1
"""What :func:`step_end` gives instead of a RET_* code when the loop is to take a step."""


@njit(cache=True)
def current_knot(knots: np.ndarray, fs: np.ndarray, ist: np.ndarray) -> int:
    """Index j of the knot interval holding the current time (kept in ``ist[I_KNOT]``)."""
    t = fs[S_T]
    kt_t = knots[K_T]
    nk = knots.shape[1]
    j = ist[I_KNOT]
    while j < nk - 2 and kt_t[j + 1] <= t:
        j += 1
    ist[I_KNOT] = j
    return j


@njit(cache=True)
def write_due_sample(
    cp: np.ndarray, weights: np.ndarray, fs: np.ndarray, ist: np.ndarray, g: np.ndarray,
    mode: np.ndarray, knots: np.ndarray, j: int, t_out: np.ndarray, out: np.ndarray,
    flags: np.ndarray, elem: np.ndarray, record_elements: bool,
) -> tuple[int, float, float]:
    """Write the next output sample if its time has come: (its index, x_stage, Fn), or (-1, 0, 0).

    The inputs are those of knot interval j at the current time; a negative Fn is read as 0."""
    io = ist[I_OUT]
    t = fs[S_T]
    if io >= t_out.shape[0] or t_out[io] > t:
        return -1, 0.0, 0.0
    xs = interp(knots, K_XS, j, t)
    fn = max(interp(knots, K_FN, j, t), 0.0)
    vs = slope(knots, K_XS, j)
    write_sample(cp, weights, fs, ist, g, mode, io, xs, vs, fn, out, flags, elem, record_elements)
    ist[I_OUT] = io + 1
    return io, xs, fn


@njit(cache=True)
def step_end(fs: np.ndarray, ist: np.ndarray, ev: np.ndarray, knots: np.ndarray, j: int,
             t_out: np.ndarray, t_stop: float) -> tuple[int, float]:
    """(STEP, the time the next step ends) or (a RET_* code the loop returns, the current time).

    A step ends at the next knot, the next output sample or t_stop, whichever comes first; the
    loop returns RET_DONE at t_stop and RET_EVENT_TABLE_FULL when one more slip might not fit."""
    t = fs[S_T]
    if t >= t_stop:
        return RET_DONE, t
    if ist[I_NEVENT] >= ev.shape[0] - 1:
        return RET_EVENT_TABLE_FULL, t
    kt_t = knots[K_T]
    target = min(t_stop, kt_t[j + 1]) if kt_t[j + 1] > t else t_stop
    io = ist[I_OUT]
    if io < t_out.shape[0]:
        target = min(target, t_out[io])
    if target - t <= 0.0:
        return RET_DONE, t
    return STEP, target


@njit(cache=True)
def apart(seg: Segment, h: float) -> bool:
    """The specimens are apart over the whole step (Fn below FN_CONTACT_MIN_N at both ends)."""
    return seg.fn0 < FN_CONTACT_MIN_N and seg.fn0 + seg.fn1 * h < FN_CONTACT_MIN_N
