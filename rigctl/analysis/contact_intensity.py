"""Contact-image intensities streamed over a run: Isum(t) (Eq. 1) and I(x,t) (Sec. 3.2).

Han et al. 2022, Sec. 2.2, Eq. 1: with ``I(x, y, t)`` the grey level of pixel (x, y) of the frame at
time t, an image of m rows and n columns,

    Isum(t) = sum_{x=1..n} sum_{y=1..m} I(x, y, t)                                  (Eq. 1)

Sec. 3.2 (the equation after "summing the intensity of the contact image in the y direction"):

    I(x, t) = sum_{y=1..m} I(x, y, t)

Readings (docs/analysis.md, "Contact images"):

* **Isum** is the raw sum of Eq. 1. The camera's dark field (no contact) is not zero, so every
  quantity that compares parts of the contact subtracts the **dark level** ``I_dark`` per pixel:
  the contact intensity ``Ic(t) = Isum(t) - m n I_dark`` and ``I(x, t) = sum_y (I(x, y, t) - I_dark)``.
* x runs over the **contact region**, the image columns between the back end (x = 0) and the front
  end (x = 1) of the contact (:class:`ContactRegion`, found by :func:`find_contact_region` or given).
* I(x, t) is kept in ``n_bins`` equal bins of the normalised length (default 100; each image column
  split between the bins it overlaps), so a run of any length keeps ``4 n_bins`` bytes per frame.

:func:`stream_intensity` reads the frames once, in chunks (:mod:`rigctl.analysis.contact_frames`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rigctl.analysis.contact_frames import DEFAULT_CHUNK_BYTES, iter_frame_chunks
from rigctl.analysis.progress import SILENT, Progress
from rigctl.data import DataError, FloatArray
from rigctl.storage.reader import RunReader

N_PROFILE_BINS = 100
PROBE_FRAMES = 48
REGION_NOISE_SIGMAS = 6.0
REGION_PEAK_FRACTION = 0.02


@dataclass(frozen=True)
class ContactRegion:
    """Where the contact is in the image, and the grey level of no contact."""

    col0: int
    """First image column of the contact region."""
    col1: int
    """One past its last column."""
    dark_level: float
    """Grey level of a pixel without contact (per pixel)."""
    back_end_left: bool = True
    """The back end (x = 0) is at ``col0`` (else at ``col1 - 1``)."""

    def __post_init__(self) -> None:
        if not 0 <= self.col0 < self.col1:
            raise ValueError(f"contact region columns {self.col0}:{self.col1} are empty")
        if not math.isfinite(self.dark_level):
            raise ValueError("dark level must be finite")

    @property
    def width_px(self) -> int:
        return self.col1 - self.col0


def bin_matrix(width_px: int, n_bins: int) -> NDArray[np.float32]:
    """(width_px, n_bins): the fraction of each column of the region that lies in each bin.

    Column j covers normalised x in [j/w, (j+1)/w], bin b covers [b/n, (b+1)/n]; every row sums to
    1, so binning keeps the total intensity.
    """
    if width_px < 1 or n_bins < 1:
        raise ValueError(f"need at least one column and one bin (got {width_px}, {n_bins})")
    c = np.arange(width_px + 1) / width_px
    b = np.arange(n_bins + 1) / n_bins
    lo = np.maximum(c[:-1, None], b[None, :-1])
    hi = np.minimum(c[1:, None], b[None, 1:])
    return (np.clip(hi - lo, 0.0, None) * width_px).astype(np.float32)


def find_contact_region(reader: RunReader, n_frames: int | None = None,
                        n_probe: int = PROBE_FRAMES) -> ContactRegion:
    """The contact region and dark level from up to ``n_probe`` frames spread over the run.

    Dark level: the median pixel of the probe frames (the real contact area is a small part of the
    field: bright spots on a dark field, Sec. 2.1). Noise: 1.4826 x the median absolute deviation of
    the pixels at or below the dark level, mirrored. Region: from the first to the last column whose
    largest dark-subtracted column sum over the probes exceeds both ``REGION_NOISE_SIGMAS`` noise
    RMS of a column sum and ``REGION_PEAK_FRACTION`` of the largest one. DataError if no column does
    (no contact in any probe frame).
    """
    n = reader.n_frames if n_frames is None else min(n_frames, reader.n_frames)
    if n < 1:
        raise DataError("the run has no camera frames", path=reader.path)
    idx = np.unique(np.linspace(0, n - 1, min(n_probe, n)).round().astype(int))
    probes = np.stack([reader.frames(int(i), int(i) + 1)[0][0] for i in idx])
    dark = float(np.median(probes))
    low = probes[probes <= dark].astype(np.float64)
    sigma = 1.4826 * float(np.median(dark - low)) if low.size else 0.0
    sigma = max(sigma, 0.5)  # 8-bit rounding: at least half a grey level
    h = probes.shape[1]
    cols = probes.sum(axis=1, dtype=np.int64).astype(np.float64) - h * dark
    top = cols.max(axis=0)
    peak = float(top.max())
    thr = max(REGION_NOISE_SIGMAS * sigma * math.sqrt(h), REGION_PEAK_FRACTION * peak)
    on = np.flatnonzero(top > thr)
    if on.size == 0:
        raise DataError("no contact is visible in the frames (every column at the dark level)",
                        path=reader.path)
    return ContactRegion(int(on[0]), int(on[-1]) + 1, dark)


@dataclass
class ContactIntensity:
    """Per frame: time, Isum (Eq. 1), contact intensity Ic, and I(x, t) in bins of x."""

    region: ContactRegion
    height_px: int
    width_px: int
    t_s: FloatArray
    isum: FloatArray
    """Eq. 1: the raw grey-level sum of the whole frame."""
    ic: FloatArray
    """Contact intensity: Isum - m n I_dark."""
    profile: NDArray[np.float32]
    """(frames, n_bins): I(x, t) summed over the columns of each bin of normalised x (back end first)."""

    @property
    def n_frames(self) -> int:
        return int(self.t_s.shape[0])

    @property
    def n_bins(self) -> int:
        return int(self.profile.shape[1])

    @property
    def x_centres(self) -> FloatArray:
        """Normalised x of the bin centres (0 back end, 1 front end)."""
        return (np.arange(self.n_bins) + 0.5) / self.n_bins


def stream_intensity(
    reader: RunReader,
    region: ContactRegion,
    n_frames: int | None = None,
    n_bins: int = N_PROFILE_BINS,
    max_bytes: int = DEFAULT_CHUNK_BYTES,
    progress: Progress = SILENT,
) -> ContactIntensity:
    """Isum(t), Ic(t) and I(x, t) of frames ``0:n_frames`` in one streamed pass."""
    n = reader.n_frames if n_frames is None else min(n_frames, reader.n_frames)
    if n < 1:
        raise DataError("the run has no camera frames", path=reader.path)
    t = np.empty(n)
    isum = np.empty(n)
    prof = np.empty((n, n_bins), dtype=np.float32)
    mat: NDArray[np.float32] | None = None
    h = w = 0
    with progress.bar(n, "contact images", "frame") as bar:
        for ch in iter_frame_chunks(reader, 0, n, max_bytes):
            if mat is None:
                h, w = int(ch.frames.shape[1]), int(ch.frames.shape[2])
                if region.col1 > w:
                    raise DataError(f"contact region columns {region.col0}:{region.col1} exceed "
                                    f"the frame width {w} px", path=reader.path)
                mat = bin_matrix(region.width_px, n_bins)
                if not region.back_end_left:
                    mat = mat[::-1].copy()
            cols = ch.frames.sum(axis=1, dtype=np.uint32)  # I(x, t) per image column, Sec. 3.2
            sl = slice(ch.start, ch.stop)
            t[sl] = ch.t_s
            isum[sl] = cols.sum(axis=1, dtype=np.uint64)  # Eq. 1
            sub = cols[:, region.col0:region.col1].astype(np.float32)
            sub -= np.float32(h * region.dark_level)
            prof[sl] = sub @ mat
            bar.update(ch.n)
    ic = isum - h * w * region.dark_level
    return ContactIntensity(region, h, w, t, isum, ic, prof)
