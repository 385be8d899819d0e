"""Piecewise-linear inputs: the stage position and normal force between two knots.

The drive is given as knots (rows ``K_T``, ``K_XS``, ``K_FN`` of one array, :mod:`rigctl.model.layout`);
over one step both inputs are affine in the local time tau, which is what the exact solution of
:mod:`rigctl.model.modal` needs.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from rigctl.model.layout import K_FN, K_T, K_XS


class Segment(NamedTuple):
    """Inputs over one step from its start: x_stage = xs0 + vs tau, Fn = fn0 + fn1 tau."""

    xs0: float
    vs: float
    fn0: float
    fn1: float


@njit(cache=True)
def interp(knots: np.ndarray, row: int, j: int, t: float) -> float:
    """Value of input ``row`` at time t in knot interval j (linear interpolation)."""
    t0 = knots[K_T, j]
    dt = knots[K_T, j + 1] - t0
    if dt <= 0.0:
        return knots[row, j + 1]
    return knots[row, j] + (knots[row, j + 1] - knots[row, j]) * (t - t0) / dt


@njit(cache=True)
def slope(knots: np.ndarray, row: int, j: int) -> float:
    """Rate of change of input ``row`` over knot interval j (0 over an empty interval)."""
    dt = knots[K_T, j + 1] - knots[K_T, j]
    if dt <= 0.0:
        return 0.0
    return (knots[row, j + 1] - knots[row, j]) / dt


@njit(cache=True)
def segment_at(knots: np.ndarray, j: int, t: float) -> Segment:
    """Inputs from time t on within knot interval j; a negative Fn is held at 0 (no pulling)."""
    xs0 = interp(knots, K_XS, j, t)
    vs = slope(knots, K_XS, j)
    fn0 = interp(knots, K_FN, j, t)
    fn1 = slope(knots, K_FN, j)
    if fn0 < 0.0:
        fn0 = 0.0
        fn1 = max(fn1, 0.0)
    return Segment(xs0, vs, fn0, fn1)
