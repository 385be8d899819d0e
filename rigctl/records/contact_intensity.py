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
* Frames without an image (**blank**: all black, every pixel 0; or with non-finite pixels) get
  NaN; **saturated** pixels (at the largest value of the pixel type) are counted per frame, as
  they under-count the contact (:meth:`ContactIntensity.quality_notes`).
* I(x, t) is kept in ``n_bins`` equal bins of the normalised length (default 100; each image column
  split between the bins it overlaps), so a run of any length keeps ``4 n_bins`` bytes per frame.

:func:`stream_intensity` reads the frames once, in chunks (:mod:`rigctl.records.contact_frames`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy import sparse

from rigctl.data import DataError, FloatArray
from rigctl.records.contact_frames import DEFAULT_CHUNK_BYTES, iter_frame_chunks
from rigctl.records.progress import SILENT, Progress
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


def dark_level_of(pixels: NDArray[np.generic]) -> tuple[float, float]:
    """Grey level and noise RMS of a pixel without contact: the mode of the histogram, refined.

    Bright contact spots on a dark field (Sec. 2.1): most pixels are dark field and the contact only
    adds a bright tail, so the dark level is the peak of the integer histogram of the grey levels,
    refined by the parabola through the logarithms of the counts at the peak and its two neighbours
    (the three-point Gaussian peak interpolation; exact for Gaussian read noise; for noise of two
    grey levels or more, the parabola fitted to the log counts within one RMS of the peak). With values
    rounded it lands on the noise's mean, with values truncated half a grey level lower, where the
    truncated values' mean is: a per-pixel offset that a median (an integer, on one side or the
    other of the mean) does not follow. The noise RMS comes from the same parabola's curvature
    (sigma^2 = -1 / (2 a) for log counts a x^2 + ...), at least 0.5 grey level (8-bit steps).
    Non-finite pixels are left out. DataError-free: ValueError if no pixel is finite.
    """
    v = np.asarray(pixels).ravel()
    if v.dtype.kind == "f":
        v = v[np.isfinite(v)]
    if v.size == 0:
        raise ValueError("no finite pixel to read a dark level from")
    lo = int(np.floor(np.min(v)))
    counts = np.bincount((np.floor(v) - lo).astype(np.int64) if v.dtype.kind == "f"
                         else (v.astype(np.int64) - lo))
    k = int(np.argmax(counts))
    c0 = float(counts[k])
    cm = float(counts[k - 1]) if k > 0 else 0.0
    cp = float(counts[k + 1]) if k + 1 < counts.size else 0.0
    if cm <= 0.0 or cp <= 0.0:  # noise below a grey level: the peak bin is the level
        return float(lo + k), 0.5
    lm, l0, lp = math.log(cm), math.log(c0), math.log(cp)
    curv = lm - 2.0 * l0 + lp
    if curv >= 0.0:
        return float(lo + k), 0.5
    shift = 0.5 * (lm - lp) / curv
    sigma = math.sqrt(-1.0 / curv)
    half = round(sigma)
    if half >= 2:  # broad noise: the same parabola, least squares over +-sigma (less sampling noise)
        x = np.arange(max(k - half, 0), min(k + half + 1, counts.size))
        y = counts[x].astype(np.float64)
        ok = y > 0
        a2, a1, _ = np.polyfit(x[ok] - k, np.log(y[ok]), 2, w=np.sqrt(y[ok]))
        if a2 < 0:
            shift, sigma = -a1 / (2.0 * a2), math.sqrt(-1.0 / (2.0 * a2))
    return float(lo + k + shift), max(sigma, 0.5)


def find_contact_region(reader: RunReader, n_frames: int | None = None,
                        n_probe: int = PROBE_FRAMES) -> ContactRegion:
    """The contact region and dark level from up to ``n_probe`` frames spread over the run.

    Dark level and noise: :func:`dark_level_of` the probe frames' pixels (frames all black or with
    non-finite pixels are not probes). Region: from the first to the
    last column whose largest dark-subtracted column sum over the probes exceeds both
    ``REGION_NOISE_SIGMAS`` noise RMS of a column sum and ``REGION_PEAK_FRACTION`` of the largest
    one. DataError if no probe frame is usable or no column is above that (no contact in any probe
    frame).
    """
    n = reader.n_frames if n_frames is None else min(n_frames, reader.n_frames)
    if n < 1:
        raise DataError("the run has no camera frames", path=reader.path)
    idx = np.unique(np.linspace(0, n - 1, min(n_probe, n)).round().astype(int))
    frames = [reader.frames(int(i), int(i) + 1)[0][0] for i in idx]
    usable = [f for f in frames if _usable(f)]
    if not usable:
        raise DataError(f"none of the {len(frames)} frames probed over the run has an image (each "
                        "is all black or has non-finite pixels)", path=reader.path)
    probes = np.stack(usable)
    dark, sigma = dark_level_of(probes)
    h = probes.shape[1]
    cols = probes.sum(axis=1, dtype=np.float64) - h * dark
    top = cols.max(axis=0)
    peak = float(top.max())
    thr = max(REGION_NOISE_SIGMAS * sigma * math.sqrt(h), REGION_PEAK_FRACTION * peak)
    on = np.flatnonzero(top > thr)
    if on.size == 0:
        raise DataError("no contact is visible in the frames (every column at the dark level)",
                        path=reader.path)
    return ContactRegion(int(on[0]), int(on[-1]) + 1, dark)


def _usable(frame: NDArray[np.generic]) -> bool:
    """A frame with an image: every pixel finite, not all black."""
    if frame.dtype.kind == "f" and not np.isfinite(frame).all():
        return False
    return bool(np.max(frame) > 0)


@dataclass
class ContactIntensity:
    """Per frame: time, Isum (Eq. 1), contact intensity Ic, and I(x, t) in bins of x."""

    region: ContactRegion
    height_px: int
    width_px: int
    t_s: FloatArray
    isum: FloatArray
    """Eq. 1: the raw grey-level sum of the whole frame (NaN for a frame without an image)."""
    ic: FloatArray
    """Contact intensity: Isum - m n I_dark."""
    profile: NDArray[np.float32]
    """(frames, n_bins): I(x, t) summed over the columns of each bin of normalised x (back end first)."""
    saturated_px: NDArray[np.int32] | None = None
    """Pixels at the pixel type's largest value, per frame (None: not counted, float pixels)."""
    blank: NDArray[np.bool_] | None = None
    """Frames with every pixel 0 (all black: no image)."""
    nonfinite: NDArray[np.bool_] | None = None
    """Frames with NaN or infinite pixels."""

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

    def quality_notes(self) -> list[str]:
        """What the frames lack: blank frames, non-finite pixels, saturated pixels (one line each)."""
        out: list[str] = []
        for mask, what in ((self.blank, "all black (every pixel 0)"),
                           (self.nonfinite, "with NaN or infinite pixels")):
            if mask is not None and mask.any():
                j = np.flatnonzero(mask)
                out.append(f"{j.size} of {self.n_frames} frames {what}, first at t = "
                           f"{self.t_s[j[0]]:.3f} s: no Isum, Ic or I(x, t) there (NaN)")
        if self.saturated_px is not None and self.saturated_px.any():
            j = np.flatnonzero(self.saturated_px)
            worst = int(np.argmax(self.saturated_px))
            frac = self.saturated_px[worst] / (self.height_px * self.width_px)
            out.append(f"{j.size} of {self.n_frames} frames have saturated pixels (most: "
                       f"{100 * frac:.2g} % of the frame at t = {self.t_s[worst]:.3f} s): Isum "
                       "under-counts the contact there")
        return out


def column_sums(frames: NDArray[np.generic]) -> NDArray[np.generic]:
    """I(x, t) per image column (Sec. 3.2): frames (n, H, W) summed along y, in their own type.

    8-bit frames are summed in blocks of 257 rows in uint16 (257 x 255 = 65535 cannot overflow),
    the blocks in uint32: half the memory traffic of summing in 32 bits. Other integer types sum in
    int64, floats in float64 (a NaN pixel makes its column NaN).
    """
    if frames.dtype == np.uint8:
        h = frames.shape[1]
        acc = np.add.reduce(frames[:, :257], axis=1, dtype=np.uint16).astype(np.uint32)
        for a in range(257, h, 257):
            acc += np.add.reduce(frames[:, a:a + 257], axis=1, dtype=np.uint16)
        return acc
    if frames.dtype.kind in "iub":
        return frames.sum(axis=1, dtype=np.int64)
    return frames.sum(axis=1, dtype=np.float64)


def stream_intensity(
    reader: RunReader,
    region: ContactRegion,
    n_frames: int | None = None,
    n_bins: int = N_PROFILE_BINS,
    max_bytes: int = DEFAULT_CHUNK_BYTES,
    progress: Progress = SILENT,
) -> ContactIntensity:
    """Isum(t), Ic(t) and I(x, t) of frames ``0:n_frames`` in one streamed pass.

    Per chunk: the column sums (:func:`column_sums`), Isum their sum, I(x, t) the region's columns
    binned by the sparse :func:`bin_matrix` (scipy.sparse: no BLAS call, whose waiting threads took
    the CPU from the HDF5 decompression on a 2-core machine), and the frame checks (one max per frame).
    """
    n = reader.n_frames if n_frames is None else min(n_frames, reader.n_frames)
    if n < 1:
        raise DataError("the run has no camera frames", path=reader.path)
    t = np.empty(n)
    isum = np.empty(n)
    prof = np.empty((n, n_bins), dtype=np.float32)
    sat = np.zeros(n, dtype=np.int32)
    blank = np.zeros(n, dtype=bool)
    bad = np.zeros(n, dtype=bool)
    mat: sparse.csr_array | None = None
    counted = True
    h = w = 0
    with progress.bar(n, "contact images", "frame") as bar:
        for ch in iter_frame_chunks(reader, 0, n, max_bytes):
            frames = ch.frames
            if mat is None:
                h, w = int(frames.shape[1]), int(frames.shape[2])
                if region.col1 > w:
                    raise DataError(f"contact region columns {region.col0}:{region.col1} exceed "
                                    f"the frame width {w} px", path=reader.path)
                dense = bin_matrix(region.width_px, n_bins)
                mat = sparse.csr_array(dense if region.back_end_left else dense[::-1])
            sl = slice(ch.start, ch.stop)
            flat = frames.reshape(ch.n, -1)
            cols = column_sums(frames)  # I(x, t) per image column, Sec. 3.2
            t[sl] = ch.t_s
            isum[sl] = cols.sum(axis=1, dtype=np.float64)  # Eq. 1
            sub = cols[:, region.col0:region.col1].astype(np.float32)
            sub -= np.float32(h * region.dark_level)
            prof[sl] = sub @ mat
            if frames.dtype.kind == "f":
                counted = False
                bad[sl] = ~np.isfinite(isum[sl])
                hi = np.fmax.reduce(flat, axis=1)
            else:
                hi = flat.max(axis=1)
                top = np.iinfo(frames.dtype).max
                for j in np.flatnonzero(hi == top):
                    sat[ch.start + j] = np.count_nonzero(flat[j] == top)
            blank[sl] = hi <= 0
            bar.update(ch.n)
            del ch, frames, flat
    nan = blank | bad
    isum[nan] = np.nan
    prof[nan] = np.nan
    ic = isum - h * w * region.dark_level
    return ContactIntensity(region, h, w, t, isum, ic, prof, sat if counted else None, blank, bad)
