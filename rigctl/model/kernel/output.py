"""One output sample: the state of the model as the instruments see it, written to the output table."""

from __future__ import annotations

import numpy as np
from numba import njit

from rigctl.model.friction_laws import mu_static
from rigctl.model.kernel.forces import drive_force
from rigctl.model.kernel.nonlinear_slip import kinetic_mu
from rigctl.model.layout import (
    F_SLIP,
    F_STAGE,
    I_GSLIP,
    I_SIGN,
    I_SLIPPED,
    I_STAGE,
    O_FI,
    O_FN,
    O_FT,
    O_V,
    O_X,
    O_XS,
    P_K0,
    P_KAPPA,
    P_TAU_S,
    S_K_USED,
    S_STRIB,
    S_THETA,
    S_V,
    S_X,
    S_YF,
)


@njit(cache=True)
def write_sample(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    io: int,
    xs: float,
    vs: float,
    fn: float,
    out: np.ndarray,
    flags: np.ndarray,
    elem: np.ndarray,
    record_elements: bool,
) -> None:
    """Write the current state as sample ``io`` (column of ``out`` and ``flags``, row of ``elem``).

    xs, vs, fn are the inputs at the current time. Clears the "slipped since the last sample" flag.
    """
    x = fs[S_X]
    v = fs[S_V]
    kk0 = cp[P_KAPPA] * cp[P_K0]
    fe = fn + kk0 * (xs - x)
    fd = drive_force(cp, xs, vs, x, v)
    stage = ist[I_STAGE]
    n = g.shape[0]
    if ist[I_GSLIP] == 1:
        fi = ist[I_SIGN] * kinetic_mu(cp, fn, abs(v), fs[S_THETA], fs[S_STRIB]) * fe
    else:
        k = fs[S_K_USED]
        pw = weights[stage]
        mus = mu_static(cp, stage, fn, fs[S_THETA])
        fi = 0.0
        for i in range(n):
            if mode[i] == 0:
                fi += g[i] + k * x
            else:
                fi += mode[i] * mus * pw[i] * fe
    out[O_FT, io] = fs[S_YF] if cp[P_TAU_S] > 0.0 else fd
    out[O_FI, io] = fi
    out[O_X, io] = x
    out[O_V, io] = v
    out[O_XS, io] = xs
    out[O_FN, io] = fe
    flags[F_STAGE, io] = stage
    flags[F_SLIP, io] = 1 if (ist[I_SLIPPED] == 1 or ist[I_GSLIP] == 1) else 0
    ist[I_SLIPPED] = 0
    if record_elements:
        for i in range(n):
            elem[io, i] = mode[i]


@njit(cache=True)
def state_sample(
    cp: np.ndarray,
    weights: np.ndarray,
    fs: np.ndarray,
    ist: np.ndarray,
    g: np.ndarray,
    mode: np.ndarray,
    xs: float,
    fn: float,
    out: np.ndarray,
    flags: np.ndarray,
    elem: np.ndarray,
) -> None:
    """The current state as one sample (column 0 of ``out`` and ``flags``, row 0 of ``elem``) with
    the stage at rest, leaving the state (including the slipped flag) untouched."""
    slipped = ist[I_SLIPPED]
    write_sample(cp, weights, fs, ist, g, mode, 0, xs, 0.0, fn, out, flags, elem, True)
    ist[I_SLIPPED] = slipped
