"""Camera frames read chunk by chunk with ISA-L's inflate instead of HDF5's deflate filter.

The run writer stores each camera frame as one HDF5 chunk ``(1, H, W)`` of uint8, through the
filter pipeline ``deflate`` (gzip level 1) then ``fletcher32`` (:mod:`rigctl.storage.writer`,
``_create_camera``). Reading such frames with ``h5py`` spends most of its time in zlib's inflate
(docs/performance.md, Contact images). :class:`FrameDecoder` reads the same frames as
``dataset[a:b]`` does, byte for byte, but faster:

1. the stored bytes of a chunk and its filter mask, ``h5py``'s ``DatasetID.read_direct_chunk``
   (no filter applied);
2. with ``fletcher32`` in the pipeline, the chunk's last 4 bytes are the Fletcher-32 checksum of
   the bytes before them (little-endian, HDF5's ``H5Zfletcher32.c``): checked with
   :func:`fletcher32` (HDF5's ``H5_checksum_fletcher32``);
3. the rest is one zlib stream (HDF5's ``H5Zdeflate.c`` writes it with zlib's ``compress2``),
   inflated by ISA-L (``isal.isal_zlib.decompress``, zlib-compatible; it checks the stream's
   Adler-32) into the frame's ``H x W`` bytes.

Whatever this path cannot vouch for is read by ``h5py`` instead (the plain read, its errors
included), so the result never differs from it:

* for the whole dataset: not ``(n, H, W)`` uint8 stored one frame per chunk, or a filter pipeline
  other than ``deflate`` or ``deflate, fletcher32`` (shuffle, lzf, no compression, ...);
* for one frame: a chunk that cannot be read raw (not written yet), a filter mask that is not 0
  (HDF5 stores a chunk raw when deflate would make it larger: noise that does not compress), a
  checksum that does not match (corruption, or the byte-swapped checksum of HDF5 < 1.6.3 files
  that HDF5 still accepts), a stream ISA-L refuses or that does not inflate to ``H x W`` bytes.

:attr:`FrameDecoder.fast_frames` and :attr:`FrameDecoder.fallback_frames` count both paths.
"""

from __future__ import annotations

import logging

import h5py
import numpy as np
from h5py import h5z
from isal import isal_zlib
from numba import njit
from numpy.typing import NDArray

_log = logging.getLogger(__name__)

FAST_PIPELINES: tuple[tuple[int, ...], ...] = (
    (h5z.FILTER_DEFLATE,),
    (h5z.FILTER_DEFLATE, h5z.FILTER_FLETCHER32),
)
"""Filter pipelines (in the order HDF5 applies them when writing) that the fast path decodes."""

_INFLATE_ERROR: type[Exception] = getattr(isal_zlib, "error")  # noqa: B009 (stubs type it as an instance)
"""What ISA-L raises for a stream it cannot inflate (``isal_zlib.error``, zlib's ``error``)."""

CHECKSUM_BYTES = 4
MAX_CHECKED_BYTES = 16 * 2**20
"""Largest chunk :func:`fletcher32` sums (its 64-bit sums cannot overflow below 2**24 words)."""


@njit(cache=True, nogil=True)
def _fletcher_sums(data: NDArray[np.uint8]) -> tuple[np.uint64, np.uint64]:
    """(sum of the words, sum of the running sums) over ``data`` read as big-endian 16-bit words.

    An odd last byte counts as the high byte of one more word. Both sums without the modulo:
    ``sum_k w_k`` and ``sum_k (m - k) w_k`` for m words (the second is the sum of the running sums),
    in 64 bits (exact for fewer than 2**24 words).
    """
    n = data.shape[0]
    m = n // 2
    a = np.uint64(0)
    b = np.uint64(0)
    for k in range(m):
        w = (np.uint64(data[2 * k]) << np.uint64(8)) | np.uint64(data[2 * k + 1])
        a += w
        b += np.uint64(k) * w
    if n % 2:
        w = np.uint64(data[n - 1]) << np.uint64(8)
        a += w
        b += np.uint64(m) * w
        m += 1
    return a, np.uint64(m) * a - b


def _fold(s: int) -> int:
    """``s`` reduced as HDF5 does (end-around carry, ``(s & 0xffff) + (s >> 16)``): congruent to
    ``s`` modulo 65535, in 1..65535 when ``s`` > 0 and 0 only when ``s`` = 0."""
    r = s % 65535
    return 65535 if r == 0 and s > 0 else r


def fletcher32(data: bytes | memoryview | NDArray[np.uint8]) -> int:
    """HDF5's Fletcher-32 checksum of ``data`` (``H5_checksum_fletcher32``, HDF5 ``H5checksum.c``).

    Fletcher's checksum (J. G. Fletcher, IEEE Trans. Commun. 30 (1982) 247) over 16-bit words
    ``w_k = 256 data[2k] + data[2k+1]`` (an odd last byte as ``256 data[-1]``):
    ``sum1 = sum_k w_k`` and ``sum2 = sum_k sum1_k`` (the running sums), each modulo 65535 as HDF5
    folds them (:func:`_fold`); the checksum is ``sum2 << 16 | sum1``.
    """
    arr = np.frombuffer(data, dtype=np.uint8)
    if arr.size > MAX_CHECKED_BYTES:
        raise ValueError(f"{arr.size} bytes is more than fletcher32 sums exactly "
                         f"({MAX_CHECKED_BYTES})")
    s1, s2 = _fletcher_sums(arr)
    return (_fold(int(s2)) << 16) | _fold(int(s1))


def pipeline_of(ds: h5py.Dataset) -> tuple[int, ...]:
    """The filter codes of ``ds``'s pipeline, in the order HDF5 applies them when writing."""
    plist = ds.id.get_create_plist()
    return tuple(int(plist.get_filter(i)[0]) for i in range(plist.get_nfilters()))


def why_not_fast(ds: h5py.Dataset) -> str | None:
    """Why :class:`FrameDecoder` cannot inflate ``ds`` itself (None: it can)."""
    if ds.ndim != 3 or ds.dtype != np.uint8:
        return f"frames of shape {ds.shape} and type {ds.dtype}, not (n, H, W) uint8"
    if ds.is_virtual or ds.chunks is None:
        return "frames not stored in chunks"
    if tuple(ds.chunks) != (1, *ds.shape[1:]):
        return f"chunks of {ds.chunks}, not one whole frame each"
    filters = pipeline_of(ds)
    if filters not in FAST_PIPELINES:
        return f"filter pipeline {filters}, not deflate (1) or deflate then fletcher32 (1, 3)"
    return None


class FrameDecoder:
    """Frames ``a:b`` of a camera dataset, as ``ds[a:b]`` gives them (see the module docstring)."""

    def __init__(self, ds: h5py.Dataset) -> None:
        self._ds = ds
        self.why_not = why_not_fast(ds)
        """Why every frame is read by h5py (None: the fast path is tried frame by frame)."""
        if self.why_not is not None:
            _log.debug("%s: read by h5py (%s)", ds.name, self.why_not)
        self._checked = self.why_not is None and pipeline_of(ds)[-1] == h5z.FILTER_FLETCHER32
        self._frame_shape: tuple[int, int] = (int(ds.shape[1]), int(ds.shape[2])) if ds.ndim == 3 \
            else (0, 0)
        self._frame_bytes = self._frame_shape[0] * self._frame_shape[1]
        self.fast_frames = 0
        """Frames inflated by ISA-L so far."""
        self.fallback_frames = 0
        """Frames read by h5py so far."""

    def read(self, start: int, stop: int) -> NDArray[np.uint8]:
        """Frames ``start:stop`` as a new ``(stop - start, H, W)`` uint8 array."""
        if not 0 <= start <= stop <= self._ds.shape[0]:
            raise IndexError(f"frames {start}:{stop} outside the dataset's 0:{self._ds.shape[0]}")
        if self.why_not is not None:
            self.fallback_frames += stop - start
            return np.asarray(self._ds[start:stop])
        out = np.empty((stop - start, *self._frame_shape), dtype=np.uint8)
        for j, i in enumerate(range(start, stop)):
            if self._inflate(i, out[j]):
                self.fast_frames += 1
            else:
                out[j] = self._ds[i]  # h5py's read as the plain read does it (into zeros)
                self.fallback_frames += 1
        return out

    def _inflate(self, i: int, out: NDArray[np.uint8]) -> bool:
        """Frame ``i`` into ``out`` by ISA-L; False (``out`` untouched or partly written) when
        it must be read by h5py."""
        try:
            mask, raw = self._ds.id.read_direct_chunk((i, 0, 0))
        except (OSError, ValueError, KeyError, RuntimeError):
            return False  # e.g. a chunk not allocated (not written yet)
        if mask != 0:
            return False  # a filter was skipped for this chunk (stored raw)
        view = memoryview(raw)
        if self._checked:
            if len(view) < CHECKSUM_BYTES or len(view) > MAX_CHECKED_BYTES:
                return False
            stored = int.from_bytes(view[-CHECKSUM_BYTES:], "little")
            view = view[:-CHECKSUM_BYTES]
            if fletcher32(view) != stored:
                return False
        try:
            pixels = isal_zlib.decompress(view, bufsize=self._frame_bytes)
        except _INFLATE_ERROR:
            return False
        if len(pixels) != self._frame_bytes:
            return False
        out[...] = np.frombuffer(pixels, dtype=np.uint8).reshape(self._frame_shape)
        return True
