"""Camera frames streamed from a run file in chunks, with bounded memory.

An hour of 60 Hz 640 x 480 video is 66 GB of pixels: no analysis may hold it. Every image analysis
(:mod:`~rigctl.records.contact_intensity`, the spot extraction of chosen frames) reads frames
through :func:`iter_frame_chunks`, which yields :class:`FrameChunk` objects of at most
``max_bytes`` of pixels (whole frames; at least one frame). Only one chunk is alive at a time when
the caller drops it before asking for the next, so the peak memory of a pass over a run is about one
chunk plus what the analysis keeps per frame.

Frames are read from the run file's camera datasets as :meth:`rigctl.storage.reader.RunReader.frames`
reads them (SWMR: a run still being written is read up to its last flushed frame), the pixels by
:class:`rigctl.records.frame_inflate.FrameDecoder` (ISA-L's inflate for deflate-compressed frames,
about twice h5py's speed, docs/performance.md; h5py for anything else), byte for byte what h5py
gives. Only frames with a time stamp are yielded (``n_frames`` of
:class:`rigctl.analysis.source.FrameInfo`, or what the reader reports).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np
from numpy.typing import NDArray

from rigctl.data import DataError, FloatArray
from rigctl.records.frame_inflate import FrameDecoder
from rigctl.storage import layout
from rigctl.storage.reader import RunReader

DEFAULT_CHUNK_BYTES = 32 * 1024 * 1024
"""Pixels per chunk by default: 109 frames of 640 x 480 (about 1.8 s of 60 Hz video)."""


@dataclass(frozen=True)
class FrameChunk:
    """Consecutive frames ``start:start + n`` of a run."""

    start: int
    frames: NDArray[np.uint8]
    """(n, H, W) grey levels."""
    t_s: FloatArray
    """Frame times on the DAQ clock (s)."""

    @property
    def n(self) -> int:
        return int(self.frames.shape[0])

    @property
    def stop(self) -> int:
        return self.start + self.n


def chunk_frames(height_px: int, width_px: int, max_bytes: int = DEFAULT_CHUNK_BYTES) -> int:
    """Frames per chunk so that one chunk holds at most ``max_bytes`` of pixels (at least 1)."""
    if height_px <= 0 or width_px <= 0:
        raise ValueError(f"frame size {height_px} x {width_px} px must be positive")
    if max_bytes <= 0:
        raise ValueError(f"chunk size {max_bytes} bytes must be positive")
    return max(1, max_bytes // (height_px * width_px))


def iter_frame_chunks(
    reader: RunReader,
    start: int = 0,
    stop: int | None = None,
    max_bytes: int = DEFAULT_CHUNK_BYTES,
) -> Iterator[FrameChunk]:
    """Frames ``start:stop`` of an open run file, chunk by chunk (bounded memory).

    ``stop`` defaults to the frames the reader has (all three camera datasets written). Raises
    DataError if the run has no camera stream or the range is outside it.
    """
    n = reader.n_frames
    if n == 0:
        raise DataError("the run has no camera frames", path=reader.path)
    stop = n if stop is None else stop
    if not 0 <= start <= stop <= n:
        raise DataError(f"frame range {start}:{stop} is outside the run's 0:{n} frames",
                        path=reader.path)
    first, _, _ = reader.frames(start, min(start + 1, stop)) if stop > start else (None, None, None)
    if first is None or first.ndim != 3:
        return
    step = chunk_frames(int(first.shape[1]), int(first.shape[2]), max_bytes)
    del first
    camera = _camera_group(reader)
    decoder = FrameDecoder(camera["frames"]) if camera is not None else None
    for a in range(start, stop, step):
        b = min(a + step, stop)
        if camera is None or decoder is None:
            frames, t_s, _ = reader.frames(a, b)
        else:
            frames = decoder.read(a, b)
            t_s = np.asarray(camera["time"][a:b], dtype=np.float64)
        yield FrameChunk(a, frames, t_s)
        del frames, t_s  # the chunk is the caller's alone: gone when the caller drops it


def _camera_group(reader: RunReader) -> h5py.Group | None:
    """The camera group of the reader's open file (None for a reader without one: the frames are
    then read through ``reader.frames``)."""
    f = getattr(reader, "_file", None)  # as rigctl.analysis.source reads the frame datasets
    if not isinstance(f, h5py.File) or layout.CAMERA not in f:
        return None
    group = f[layout.CAMERA]
    return group if isinstance(group, h5py.Group) else None


def read_frame(path: str | Path, index: int) -> tuple[NDArray[np.uint8], float]:
    """One frame of a run file and its time (for the spot analyses of chosen frames)."""
    with RunReader(path) as reader:
        n = reader.n_frames
        if not 0 <= index < n:
            raise DataError(f"frame {index} is outside the run's 0:{n} frames", path=path)
        frames, t_s, _ = reader.frames(index, index + 1)
    return frames[0], float(t_s[0])
