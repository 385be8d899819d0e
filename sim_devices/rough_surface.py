"""A seeded, isotropic, self-affine random rough surface generated from its power spectral density.

The isotropic PSD with a roll-off (Persson et al., J. Phys.: Condens. Matter 17 (2005) R1, Sec. 2;
Jacobs, Junge and Pastewka, Surf. Topogr.: Metrol. Prop. 5 (2017) 013001, eq. 4):

    C(q) = C0                              for q <  q_r        (roll-off plateau)
    C(q) = C0 (q / q_r)^(-2 (1 + H))       for q_r <= q <= q_s (self-affine, Hurst exponent H)
    C(q) = 0                               for q >  q_s        (short-wavelength cut-off)

A height field with this spectrum is synthesised by the spectral (Fourier filtering) method (Jacobs et
al. 2017, Sec. 5; Wu, Tribol. Int. 33 (2000) 47): complex Gaussian white noise is shaped by
sqrt(C(q)), transformed back, and the real part is scaled so that its root-mean-square roughness equals
Sq exactly (3.024 um for the PMMA boss of Han et al. 2022, Section 2.1). The paper's measured PSD is
stable for spatial frequencies 0.02-0.18 um^-1 (Section 2.3); those wavelengths (5-50 um) are below
one pixel of a whole-boss image, so the image resolves the long-wavelength part of the spectrum and
the sub-pixel roughness acts through the contact fraction of each pixel (see contact_image.py).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

SQ_BOSS_M = 3.024e-6
"""Root-mean-square roughness Sq of the PMMA boss before the experiments (Han et al. 2022, Section 2.1)."""


def psd_isotropic(
    q_rad_m: NDArray[np.float64], q_r: float, q_s: float, hurst: float
) -> NDArray[np.float64]:
    """Unnormalised isotropic PSD C(q)/C0 with roll-off q_r and cut-off q_s (module docstring)."""
    q = np.asarray(q_rad_m, dtype=np.float64)
    c = np.where(q < q_r, 1.0, (np.maximum(q, q_r) / q_r) ** (-2.0 * (1.0 + hurst)))
    return np.where(q > q_s, 0.0, c)


def rough_surface(
    n_y: int,
    n_x: int,
    pixel_m: float,
    *,
    sq_m: float = SQ_BOSS_M,
    hurst: float = 0.8,
    rolloff_wavelength_m: float = 1.0e-3,
    cutoff_wavelength_m: float | None = None,
    seed: int = 0,
) -> NDArray[np.float64]:
    """Height field h(y, x) [m] with zero mean and RMS ``sq_m``, on an ``n_y`` x ``n_x`` grid.

    ``cutoff_wavelength_m`` defaults to two pixels (the grid's Nyquist wavelength).
    """
    if n_y < 2 or n_x < 2:
        raise ValueError("the surface grid needs at least 2 x 2 points")
    if not (pixel_m > 0 and sq_m > 0 and 0.0 < hurst <= 1.0 and rolloff_wavelength_m > 0):
        raise ValueError("pixel size, Sq, roll-off must be positive and 0 < H <= 1")
    cutoff = 2.0 * pixel_m if cutoff_wavelength_m is None else cutoff_wavelength_m
    q_r = 2.0 * math.pi / rolloff_wavelength_m
    q_s = 2.0 * math.pi / cutoff
    qy = 2.0 * math.pi * np.fft.fftfreq(n_y, d=pixel_m)
    qx = 2.0 * math.pi * np.fft.fftfreq(n_x, d=pixel_m)
    q = np.hypot(qy[:, None], qx[None, :])
    amplitude = np.sqrt(psd_isotropic(q, q_r, q_s, hurst))
    amplitude[0, 0] = 0.0  # zero mean height
    rng = np.random.default_rng(seed)
    noise = rng.standard_normal((n_y, n_x)) + 1j * rng.standard_normal((n_y, n_x))
    h = np.fft.ifft2(amplitude * noise).real
    h -= h.mean()
    rms = float(np.sqrt(np.mean(h * h)))
    if rms == 0.0:
        raise ValueError("the spectrum is empty on this grid: check the wavelengths")
    return h * (sq_m / rms)
