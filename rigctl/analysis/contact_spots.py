"""Contact spots of one frame by a weighted multi-scale filter (the paper's WSM, its ref. [46]).

Han et al. 2022, Sec. 3.3: "the real contact spots in the three images are extracted by weighted
filter superposition (WSM)". The method is published in the authors' earlier work (ref. [46]); its
details are not in this paper, so rigctl builds its own, documented here (docs/analysis.md):

1. subtract the dark level ``I_dark`` (the grey level of no contact): ``I0 = I - I_dark``;
2. smooth ``I0`` with Gaussians of ``scales_px`` (0 = the image itself; ``skimage.filters.gaussian``)
   and superpose them with ``weights`` (sum 1):  ``S = sum_k w_k G_{s_k} * I0``.  The finest scale
   keeps the spots' edges, the coarser ones reject lone noise pixels and join a spot's faint rim;
3. **detection**: the white read noise of RMS ``sigma`` (robust: 1.4826 x the median absolute
   deviation of the dark pixels) becomes noise of RMS ``sigma ||sum_k w_k g_k||_2`` in S (the L2
   norm of the superposed kernel, computed by filtering a unit impulse); a pixel is a spot seed
   where S exceeds ``z`` times that;
4. **extent** (a hysteresis threshold between the two images): smoothing spreads a bright spot, so
   a spot's pixels are those of the unsmoothed ``I0`` above ``edge_z sigma`` that are connected
   (8-connectivity, ``skimage.measure.label``) to a seed; groups without a seed are noise. Near a
   bright spot S is high, so a noise pixel there is a seed too: a group is also required to stand
   out by itself, ``sum(I0) / (sigma sqrt(n)) > own_z`` over its n pixels (a matched sum);
5. spots smaller than ``min_spot_px`` are dropped (``skimage.morphology.remove_small_objects``)
   and the rest labelled.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from skimage.filters import gaussian
from skimage.measure import label
from skimage.morphology import remove_small_objects

from rigctl.data import FloatArray


@dataclass(frozen=True)
class WsmSettings:
    """Parameters of the weighted multi-scale filter (module docstring)."""

    scales_px: tuple[float, ...] = (0.0, 1.0, 2.0)
    weights: tuple[float, ...] = (0.5, 0.3, 0.2)
    z: float = 5.0
    edge_z: float = 2.5
    own_z: float = 4.0
    min_spot_px: int = 1

    def __post_init__(self) -> None:
        if len(self.scales_px) != len(self.weights) or not self.scales_px:
            raise ValueError("WSM needs one weight per scale (and at least one scale)")
        if any(s < 0 for s in self.scales_px) or any(w < 0 for w in self.weights):
            raise ValueError("WSM scales and weights must be >= 0")
        if not math.isclose(sum(self.weights), 1.0, rel_tol=1e-9):
            raise ValueError(f"WSM weights must sum to 1 (they sum to {sum(self.weights)})")
        if min(self.z, self.edge_z, self.own_z) <= 0 or self.min_spot_px < 1:
            raise ValueError("WSM thresholds z, edge_z, own_z must be > 0 and the smallest spot "
                             ">= 1 px")


def dark_noise(frame: NDArray[np.number], dark_level: float) -> float:
    """Read-noise RMS from the pixels at or below the dark level (at least half a grey level)."""
    f = np.asarray(frame, dtype=np.float64)
    low = dark_level - f[f <= dark_level]
    return max(1.4826 * float(np.median(low)) if low.size else 0.0, 0.5)


def superpose(image: FloatArray, settings: WsmSettings) -> FloatArray:
    """``sum_k w_k G_{s_k} * image`` (step 2)."""
    out = np.zeros_like(image, dtype=np.float64)
    for s, w in zip(settings.scales_px, settings.weights, strict=True):
        if w == 0:
            continue
        sm = image if s == 0 else gaussian(image, sigma=s, mode="nearest", preserve_range=True)
        out += w * sm
    return out


def noise_gain(settings: WsmSettings) -> float:
    """L2 norm of the superposed kernel: the RMS of S for unit white noise (step 3)."""
    r = math.ceil(4 * max(settings.scales_px)) + 1
    impulse = np.zeros((2 * r + 1, 2 * r + 1))
    impulse[r, r] = 1.0
    return float(np.sqrt(np.sum(superpose(impulse, settings) ** 2)))


@dataclass(frozen=True)
class Spots:
    """The contact spots of one frame."""

    mask: NDArray[np.bool_]
    labels: NDArray[np.int32]
    n_spots: int
    threshold: float
    """Grey-level threshold applied to S (detection)."""

    @property
    def area_px(self) -> int:
        return int(np.count_nonzero(self.mask))

    @property
    def area_fraction(self) -> float:
        return self.area_px / self.mask.size


def extract_spots(frame: NDArray[np.number], dark_level: float,
                  settings: WsmSettings | None = None, noise_rms: float | None = None) -> Spots:
    """Contact spots of ``frame`` (2-D grey levels) by the weighted multi-scale filter."""
    settings = settings or WsmSettings()
    img = np.asarray(frame, dtype=np.float64)
    if img.ndim != 2:
        raise ValueError(f"a frame must be 2-D, got shape {img.shape}")
    sigma = dark_noise(img, dark_level) if noise_rms is None else float(noise_rms)
    i0 = img - dark_level
    s = superpose(i0, settings)
    thr = settings.z * sigma * noise_gain(settings)
    bright = i0 > settings.edge_z * sigma
    groups = label(bright, connectivity=2)
    seeded = np.zeros(int(groups.max()) + 1, dtype=bool)
    seeded[groups[(s > thr) & bright]] = True
    n_px = np.bincount(groups.ravel())
    total = np.bincount(groups.ravel(), weights=i0.ravel())
    own = total / (sigma * np.sqrt(np.maximum(n_px, 1)))
    keep = seeded & (own > settings.own_z)
    keep[0] = False
    mask = keep[groups]
    mask = remove_small_objects(mask, max_size=settings.min_spot_px - 1, connectivity=2)
    labels, n = label(mask, connectivity=2, return_num=True)
    return Spots(mask, labels.astype(np.int32), int(n), thr)


def spot_areas_px(spots: Spots) -> Sequence[int]:
    """Area of every spot (pixels), largest first."""
    counts = np.bincount(spots.labels.ravel())[1:]
    return sorted((int(c) for c in counts if c), reverse=True)
