"""Total-reflection images of the real contact area, rendered from the model's contact state.

Optics (Han et al. 2022, Sections 2.1-2.2; Rubinstein et al., Nature 430 (2004) 1005): light
totally reflected at the glass surface is frustrated where an asperity of the rough PMMA boss touches
the glass, so the camera sees bright spots on a dark field, brighter where the local pressure is
higher (Han et al. 2022, Section 3.2: "the brighter the image of the local area is, the greater the
stress is").

Geometry: the 9 x 9 mm boss is a square centred in the frame, ``boss_fill`` of the shorter image side.
Image columns run along the sliding direction x: the boss's left edge is x = 0, the back end, where
element 0 of the model sits; element i covers x in [i/N, (i+1)/N).

Per frame, with Fn, the element load shares P_i (sum 1) and the sliding flags:

1. Nominal pressure along x, p(x) = Fn * N * P(x) / A0 with A0 = 81 mm^2 and P(x) interpolated
   linearly between element centres (Han et al. 2022, Section 3.2: the equivalent stress distribution).
2. Real contact fraction (Persson, J. Chem. Phys. 115 (2001) 3840, eq. 33; linear limit
   A/A0 = kappa p / (E* g) with kappa ~ 2, Hyun et al., Phys. Rev. E 70 (2004) 026117):

       a(x) = erf( (sqrt(pi) / 2) * kappa * p(x) / (E* g) ) * s(x)

   where g is the RMS surface slope and s(x) = ``separation_factor`` where elements slide during the
   initial stage (contact separation at the back end as Ft grows, Han et al. 2022, Section 3.2 and
   Fig. 9), else 1. a is linear in p at low load, so the summed intensity Isum is nearly linear in Fn
   (Han et al. 2022, Fig. 3a).
3. Which pixels touch: those whose height exceeds the level u(x) that the fraction a(x) of the
   surface's height distribution lies above, u(x) = F_h^-1(1 - a(x)) (the bearing-area / Abbott
   construction, Greenwood and Williamson, Proc. R. Soc. A 295 (1966) 300).
4. Brightness of a touching pixel grows with its interference h - u (a larger spot inside the pixel):
   I = dark + (full - dark) * min(1, (h - u) / (c * Sq)), then Gaussian read noise and 8-bit rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.special import erf

from sim_devices.rough_surface import SQ_BOSS_M, rough_surface

BOSS_SIDE_M = 9e-3
"""Side of the PMMA boss (Han et al. 2022, Section 2.1, Fig. 1b)."""

MAX_WIDTH_PX = 640  # VGA at most: every frame is rendered from the contact state, in real time
MAX_HEIGHT_PX = 480


@dataclass(frozen=True)
class CameraOptics:
    """Frame geometry and grey levels of the simulated camera."""

    width_px: int = 240
    height_px: int = 240
    boss_fill: float = 0.9
    dark_level: float = 6.0
    full_level: float = 230.0
    read_noise_rms: float = 1.2
    seed: int = 2022

    def __post_init__(self) -> None:
        if not (16 <= self.width_px <= MAX_WIDTH_PX and 16 <= self.height_px <= MAX_HEIGHT_PX):
            raise ValueError(
                f"camera size {self.width_px} x {self.height_px} px outside 16..{MAX_WIDTH_PX} x "
                f"16..{MAX_HEIGHT_PX}"
            )
        if not 0.1 <= self.boss_fill <= 1.0:
            raise ValueError("boss_fill must be within [0.1, 1]")
        if not 0 <= self.dark_level < self.full_level <= 255:
            raise ValueError("grey levels must satisfy 0 <= dark < full <= 255")
        if self.read_noise_rms < 0:
            raise ValueError("read noise must be >= 0")


@dataclass(frozen=True)
class ContactOptics:
    """Contact mechanics and surface of the rendering model (see the module docstring)."""

    e_star_Pa: float = 3.2e9
    """Effective modulus of PMMA (E ~ 3 GPa, nu 0.35) on glass (E 70 GPa, nu 0.22)."""
    slope_rms: float = 0.1
    """RMS slope g of the rough surface (assumed; not reported by Han et al. 2022)."""
    kappa: float = 2.0
    separation_factor: float = 0.35
    """Contact fraction kept by elements sliding in the initial stage (a rendering choice)."""
    brightness_overlap_sq: float = 0.5
    """c: interference (in units of Sq) at which a spot saturates its pixel."""
    sq_m: float = SQ_BOSS_M
    hurst: float = 0.8
    rolloff_wavelength_m: float = 0.3e-3
    boss_side_m: float = BOSS_SIDE_M


class ContactImageRenderer:
    """Renders 8-bit grey frames; the surface is generated once, per-frame work is vectorised."""

    def __init__(
        self, optics: CameraOptics | None = None, contact: ContactOptics | None = None
    ) -> None:
        self.optics = optics or CameraOptics()
        self.contact = contact or ContactOptics()
        o = self.optics
        self.boss_px = max(8, round(o.boss_fill * min(o.width_px, o.height_px)))
        self.pixel_m = self.contact.boss_side_m / self.boss_px
        self._y0 = (o.height_px - self.boss_px) // 2
        self._x0 = (o.width_px - self.boss_px) // 2
        h = rough_surface(
            self.boss_px,
            self.boss_px,
            self.pixel_m,
            sq_m=self.contact.sq_m,
            hurst=self.contact.hurst,
            rolloff_wavelength_m=self.contact.rolloff_wavelength_m,
            seed=o.seed,
        )
        self.height_m = h.astype(np.float32)
        self._sorted_h = np.sort(h.ravel())
        self._levels = (np.arange(self._sorted_h.size) + 0.5) / self._sorted_h.size
        self._x_norm = (np.arange(self.boss_px) + 0.5) / self.boss_px
        self._rng = np.random.default_rng(o.seed + 1)
        self._dark = np.full((o.height_px, o.width_px), o.dark_level, dtype=np.float32)

    @property
    def area_m2(self) -> float:
        return self.contact.boss_side_m**2

    def contact_fraction(
        self,
        fn_N: float,
        p_elements: NDArray[np.float64],
        sliding_elements: NDArray[np.bool_],
        stage: int,
    ) -> NDArray[np.float64]:
        """Real contact fraction a(x) per boss column (steps 1-2 of the module docstring)."""
        p = np.asarray(p_elements, dtype=np.float64)
        n = p.shape[0]
        if n < 1 or not np.all(np.isfinite(p)) or not math.isfinite(fn_N):
            raise ValueError("contact state must be finite with at least one element")
        centres = (np.arange(n) + 0.5) / n
        share = np.interp(self._x_norm, centres, p * n)  # P per unit normalised length
        pressure_Pa = max(fn_N, 0.0) * share / self.area_m2
        c = self.contact
        a = erf(0.5 * math.sqrt(math.pi) * c.kappa * pressure_Pa / (c.e_star_Pa * c.slope_rms))
        if stage == 0:
            sliding = np.asarray(sliding_elements, dtype=bool)
            keep = np.where(sliding, c.separation_factor, 1.0)
            a = a * np.interp(self._x_norm, centres, keep)
        return np.clip(a, 0.0, 1.0)

    def render(
        self,
        fn_N: float,
        p_elements: NDArray[np.float64],
        sliding_elements: NDArray[np.bool_],
        stage: int,
    ) -> NDArray[np.uint8]:
        """One frame (height x width, uint8) of the contact seen by total reflection."""
        o, c = self.optics, self.contact
        a = self.contact_fraction(fn_N, p_elements, sliding_elements, stage)
        u = np.interp(1.0 - a, self._levels, self._sorted_h).astype(np.float32)
        u = np.where(a > 0.0, u, np.float32(np.inf))
        overlap = (self.height_m - u[None, :]) * np.float32(1.0 / (c.brightness_overlap_sq * c.sq_m))
        np.clip(overlap, 0.0, 1.0, out=overlap)
        frame = self._dark.copy()
        y0, x0, b = self._y0, self._x0, self.boss_px
        frame[y0 : y0 + b, x0 : x0 + b] += np.float32(o.full_level - o.dark_level) * overlap
        if o.read_noise_rms > 0:
            frame += self._rng.standard_normal(frame.shape, dtype=np.float32) * np.float32(
                o.read_noise_rms
            )
        np.clip(frame, 0.0, 255.0, out=frame)
        return np.rint(frame).astype(np.uint8)

    def boss_columns(self) -> slice:
        """Image columns covered by the boss (back end first)."""
        return slice(self._x0, self._x0 + self.boss_px)

    def boss_rows(self) -> slice:
        return slice(self._y0, self._y0 + self.boss_px)
