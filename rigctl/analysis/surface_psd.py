"""Power spectral density of a surface height map (Sec. 2.3, Fig. 4d).

Han et al. 2022, Sec. 2.3: "Figure 4(d) shows the power spectral density (PSD) of the surface profile
height before and after the experiment ... when the spatial frequency is about 0.02-0.18 um^-1, the
power spectrum curve is approximately equal". The paper's height maps come from a white-light
interferometer; here any (ny, nx) height map in metres on a square grid of ``pixel_m``.

The 2-D PSD (Jacobs, Junge & Pastewka, Surf. Topogr.: Metrol. Prop. 5 (2017) 013001, Sec. 2-3), of
the height with its mean (and by default its best-fit plane) removed, tapered by a 2-D Hann window
``w`` (``scipy.signal.windows.hann``) to stop the edges leaking power:

    C2(fx, fy) = dx^2 / (nx ny) |FFT2(w h)|^2 / mean(w^2)       [m^4],  f in cycles per metre

normalised so that (Parseval) ``sum C2 dfx dfy = mean(h^2) = Sq^2`` with ``df = 1/(n dx)``: the
window's loss of power is restored by ``mean(w^2)``. The isotropic PSD C(f) is the mean of C2 over
rings of |f| (``n_bins`` log-spaced rings from the lowest frequency to the Nyquist frequency).
Isotropy: the mean of C2 over each of four angular sectors (0, 45, 90, 135 degrees, +-22.5), each
divided by its ring's mean and averaged over the rings; ``anisotropy`` is the largest of the four over
the smallest (1 for an isotropic surface).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.signal.windows import hann

from rigctl.data import FloatArray

N_SECTORS = 4


@dataclass(frozen=True)
class SurfacePsd:
    """PSD of one height map."""

    f_per_m: FloatArray
    """Ring centres (geometric) of spatial frequency [1/m]."""
    c_m4: FloatArray
    """Isotropic PSD C(f) [m^4] (NaN for an empty ring)."""
    sq_m: float
    """Sq from the PSD: sqrt(sum C2 df^2) [m]."""
    sq_direct_m: float
    """Sq of the detrended heights, for comparison [m]."""
    sector_power: FloatArray
    """Ring-normalised mean power of the four angular sectors (0, 45, 90, 135 degrees)."""

    @property
    def anisotropy(self) -> float:
        """Largest over smallest sector power (1 = isotropic)."""
        return float(np.max(self.sector_power) / np.min(self.sector_power))

    def to_dict(self) -> dict[str, object]:
        return {"f_per_m": self.f_per_m.tolist(), "C_m4": self.c_m4.tolist(), "Sq_m": self.sq_m,
                "Sq_direct_m": self.sq_direct_m, "sector_power": self.sector_power.tolist(),
                "anisotropy": self.anisotropy}


def detrend_plane(h: NDArray[np.floating]) -> FloatArray:
    """Heights minus their least-squares plane."""
    ny, nx = h.shape
    yy, xx = np.mgrid[0:ny, 0:nx]
    a = np.column_stack([np.ones(h.size), xx.ravel(), yy.ravel()])
    coef, *_ = np.linalg.lstsq(a, h.ravel(), rcond=None)
    return np.asarray(h - (a @ coef).reshape(h.shape), dtype=np.float64)


def surface_psd(height_m: NDArray[np.floating], pixel_m: float, n_bins: int = 40,
                plane: bool = True) -> SurfacePsd:
    """The windowed, radially averaged PSD of ``height_m`` (module docstring)."""
    h = np.asarray(height_m, dtype=np.float64)
    if h.ndim != 2 or min(h.shape) < 8:
        raise ValueError(f"a height map must be 2-D and at least 8 x 8, got shape {h.shape}")
    if not np.all(np.isfinite(h)):
        raise ValueError("the height map has NaN or infinite heights (fill or crop them first)")
    if not (math.isfinite(pixel_m) and pixel_m > 0):
        raise ValueError(f"pixel size {pixel_m} m must be positive")
    if n_bins < 2:
        raise ValueError("need at least 2 frequency bins")
    ny, nx = h.shape
    h = detrend_plane(h) if plane else h - h.mean()
    w = np.outer(hann(ny, sym=False), hann(nx, sym=False))
    spec = np.abs(np.fft.fft2(h * w)) ** 2
    c2 = spec * pixel_m**2 / (nx * ny) / float(np.mean(w * w))
    fx = np.fft.fftfreq(nx, d=pixel_m)
    fy = np.fft.fftfreq(ny, d=pixel_m)
    dfx, dfy = 1.0 / (nx * pixel_m), 1.0 / (ny * pixel_m)
    sq = math.sqrt(float(c2.sum()) * dfx * dfy)
    f = np.hypot(fy[:, None], fx[None, :])
    f_nyq = 0.5 / pixel_m
    f_lo = max(dfx, dfy)
    edges = np.geomspace(f_lo, f_nyq, n_bins + 1)
    ring = np.digitize(f, edges) - 1  # -1 below, n_bins above
    inside = (ring >= 0) & (ring < n_bins)
    sums = np.bincount(ring[inside], weights=c2[inside], minlength=n_bins)
    counts = np.bincount(ring[inside], minlength=n_bins)
    with np.errstate(invalid="ignore", divide="ignore"):
        c_iso = np.where(counts > 0, sums / np.maximum(counts, 1), np.nan)
    centres = np.sqrt(edges[:-1] * edges[1:])
    # isotropy: ring-normalised sector power (angles folded to [0, 180) degrees: C2 is symmetric)
    ang = np.degrees(np.arctan2(fy[:, None] + 0 * fx[None, :], fx[None, :] + 0 * fy[:, None]))
    ang = np.mod(ang, 180.0)
    sector = np.mod(np.floor((ang + 22.5) / 45.0).astype(int), N_SECTORS)
    ring_mean = np.where(inside, c_iso[np.clip(ring, 0, n_bins - 1)], np.nan)
    ok = inside & (ring_mean > 0)
    rel = np.zeros_like(c2)
    rel[ok] = c2[ok] / ring_mean[ok]
    sp = np.array([float(np.mean(rel[ok & (sector == s)])) for s in range(N_SECTORS)])
    return SurfacePsd(centres, c_iso, sq, float(np.sqrt(np.mean(h * h))), sp)
