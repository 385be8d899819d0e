"""Exact solution of the one-degree-of-freedom linear problem between events.

Between two events (an element starting or stopping to slide, a global slip starting or ending, a
knot of the input histories) the specimen obeys a linear ODE with constant coefficients and a forcing
that is affine in time (docs/model.md, section 3):

    M X'' + C X' + K X = F0 + F1 tau,        tau = t - t_start.

Its solution is X(tau) = a + b tau + Re(c1 exp(l1 tau) + c2 exp(l2 tau)) with b = F1/K,
a = (F0 - C b)/K and l1,2 the roots of M l^2 + C l + K = 0 (standard result for linear ODEs with
constant coefficients; e.g. Meirovitch, *Fundamentals of Vibrations*, ch. 2-3). Complex arithmetic
covers the under- and over-damped cases alike. The first-order sensor filter y' = (Fs - y)/tau_s
driven by the drive force Fs = K0 (x_stage - X) + C0 (v_stage - X') is integrated in closed form too
(convolution of an affine term and exponentials with the filter kernel).
"""

from __future__ import annotations

import cmath
import math
from typing import NamedTuple

from numba import njit


class ModalSolution(NamedTuple):
    """X(tau) = a + b tau + Re(c1 exp(l1 tau) + c2 exp(l2 tau)) (compiled code passes it by value)."""

    a: float
    b: float
    c1: complex
    c2: complex
    l1: complex
    l2: complex



@njit(cache=True)
def modal_solution(
    m: float, c: float, k: float, f0: float, f1: float, x0: float, v0: float
) -> ModalSolution:
    """The exact solution from X(0) = x0, X'(0) = v0."""
    disc = complex(c * c - 4.0 * m * k)
    root = cmath.sqrt(disc)
    if abs(root) < 1e-9 * (abs(c) + math.sqrt(abs(m * k)) + 1e-300):
        # critically damped: split the double root by a relative 1e-6 (documented in docs/model.md)
        root = complex(1e-6 * (abs(c) + 2.0 * math.sqrt(abs(m * k))), 0.0)
    l1 = (-c + root) / (2.0 * m)
    l2 = (-c - root) / (2.0 * m)
    b = f1 / k
    a = (f0 - c * b) / k
    u0 = x0 - a
    du0 = v0 - b
    c2 = (du0 - l1 * u0) / (l2 - l1)
    c1 = u0 - c2
    return ModalSolution(a, b, c1, c2, l1, l2)


@njit(cache=True)
def position(s: ModalSolution, tau: float) -> float:
    """X(tau) of the modal solution."""
    return s.a + s.b * tau + (s.c1 * cmath.exp(s.l1 * tau) + s.c2 * cmath.exp(s.l2 * tau)).real


@njit(cache=True)
def velocity(s: ModalSolution, tau: float) -> float:
    """X'(tau) of the modal solution."""
    return s.b + (s.c1 * s.l1 * cmath.exp(s.l1 * tau) + s.c2 * s.l2 * cmath.exp(s.l2 * tau)).real


@njit(cache=True)
def filtered_drive_force(
    y0: float,
    rate: float,
    k0: float,
    c0: float,
    xs0: float,
    vs: float,
    s: ModalSolution,
    tau: float,
) -> float:
    """Exact output at tau of y' = rate (Fs - y), y(0) = y0, with Fs from the modal solution.

    Fs(s) = p0 + p1 s + sum_j q_j exp(l_j s) with p0 = K0 (xs0 - a) + C0 (vs - b),
    p1 = K0 (vs - b), q_j = -(K0 + C0 l_j) c_j. The affine part is followed with lag 1/rate; each
    exponential contributes q_j rate (exp(l_j tau) - exp(-rate tau)) / (l_j + rate).
    """
    a, b, c1, c2, l1, l2 = s
    p0 = k0 * (xs0 - a) + c0 * (vs - b)
    p1 = k0 * (vs - b)
    e = math.exp(-rate * tau)
    y = p0 + p1 * tau - p1 / rate + (y0 - p0 + p1 / rate) * e
    q1 = -(k0 + c0 * l1) * c1
    q2 = -(k0 + c0 * l2) * c2
    y += (q1 * rate * (cmath.exp(l1 * tau) - e) / (l1 + rate)).real
    y += (q2 * rate * (cmath.exp(l2 * tau) - e) / (l2 + rate)).real
    return y
