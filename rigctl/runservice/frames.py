"""Camera frames for the live view: every frame's Isum, a few downsampled images a second.

The camera records at 60 Hz full size into the run file; a window needs far less to watch the
contact. :class:`FrameReducer` takes every frame (in the thread that forwards them, never the GUI's),
sums its intensities (Isum, Han et al. 2022 Eq. 1, on the full-resolution image, so the Isum(t)
curve has every frame) and, at most ``rate_hz`` times a second, emits a :class:`LiveFrame`: the newest
image block-averaged to at most ``max_width_px`` columns, with the Isum values gathered since the
previous one. The run service sends these as ``("frame", LiveFrame)`` messages; in-process, the run
panel's forwarding thread does the same.

Image columns run along the sliding direction x, column 0 at the back end of the contact (as the
simulated camera renders it, ``sim_devices/contact_image.py``).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from skimage.measure import block_reduce

LIVE_FRAME_RATE_HZ = 4.0
"""Images a second sent to a window (Isum values are sent for every frame)."""
LIVE_FRAME_MAX_WIDTH_PX = 320
"""Widest image sent to a window (block-averaged by an integer factor down to this or less)."""


@dataclass(frozen=True)
class LiveFrame:
    """One downsampled camera image and the Isum of every frame since the previous LiveFrame."""

    t_s: float
    """Device time of ``image`` (the DAQ's rig clock)."""
    image: NDArray[np.uint8]
    """The newest frame, block-averaged by ``factor`` in both directions (H x W, uint8)."""
    factor: int
    isum_t_s: NDArray[np.float64]
    """Device times of the frames summed in ``isum`` (oldest first)."""
    isum: NDArray[np.float64]
    """Isum of each of those frames, on the full-resolution image (grey levels)."""


def intensity_sum(image: NDArray[Any]) -> float:
    """Isum(t) = sum over x and y of I(x, y, t): the contact image's total intensity.

    Han et al. 2022, Sec. 2.2, Eq. (1) (a measure of the real contact area, after Rubinstein et al.).
    """
    return float(np.sum(image, dtype=np.float64))


def downsample(image: NDArray[Any], max_width_px: int = LIVE_FRAME_MAX_WIDTH_PX
               ) -> tuple[NDArray[np.uint8], int]:
    """Block-average ``image`` by the smallest integer factor that brings its width to at most
    ``max_width_px``; returns the image (uint8) and the factor. Edge rows/columns that do not fill a
    block are cut, so every output pixel is a mean of full blocks."""
    if max_width_px < 1:
        raise ValueError(f"max_width_px must be >= 1, got {max_width_px}")
    h, w = image.shape[:2]
    factor = max(1, -(-w // max_width_px))
    if factor == 1:
        return np.ascontiguousarray(image, dtype=np.uint8), 1
    cut = image[: h - h % factor, : w - w % factor]
    reduced = block_reduce(cut, (factor, factor), np.mean)
    return np.clip(np.rint(reduced), 0, 255).astype(np.uint8), factor


class FrameReducer:
    """Isum of every frame; a downsampled image at most ``rate_hz`` times a second (host time)."""

    def __init__(self, rate_hz: float = LIVE_FRAME_RATE_HZ,
                 max_width_px: int = LIVE_FRAME_MAX_WIDTH_PX,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not rate_hz > 0:
            raise ValueError(f"live frame rate must be > 0 Hz, got {rate_hz}")
        self.period_s = 1.0 / rate_hz
        self.max_width_px = max_width_px
        self._clock = clock
        self._next_s = -np.inf
        self._t: list[float] = []
        self._isum: list[float] = []
        self._newest: tuple[float, NDArray[Any]] | None = None

    def add(self, t_s: float, image: NDArray[Any]) -> LiveFrame | None:
        """One camera frame; returns a LiveFrame when one is due, else None."""
        self._t.append(float(t_s))
        self._isum.append(intensity_sum(image))
        self._newest = (float(t_s), image)
        now = self._clock()
        if now < self._next_s:
            return None
        self._next_s = now + self.period_s
        return self.flush()

    def flush(self) -> LiveFrame | None:
        """The newest frame and the Isum values not yet sent (None if no frame came)."""
        if self._newest is None:
            return None
        t, image = self._newest
        small, factor = downsample(image, self.max_width_px)
        out = LiveFrame(t, small, factor, np.asarray(self._t), np.asarray(self._isum))
        self._t, self._isum, self._newest = [], [], None
        return out


def forward_frames(sub: Any, send: Callable[[LiveFrame], None], running: Callable[[], bool],
                   reducer: FrameReducer | None = None) -> None:
    """Drain a ``"camera"`` subscription of ``(t_s, Frame)`` items, hand LiveFrames to ``send``.

    Runs in its own thread until the run ends (``running()`` false and nothing waiting); the last
    frames are flushed so the final Isum values are shown.
    """
    reducer = reducer or FrameReducer()
    while running() or not getattr(sub, "closed", True):
        item = sub.get(timeout_s=0.2)
        if item is None:
            if not running():
                break
            continue
        t_s, frame = item
        live = reducer.add(t_s, frame.image)
        if live is not None:
            send(live)
    last = reducer.flush()
    if last is not None:
        send(last)


def start_forwarding(sub: Any, send: Callable[[LiveFrame], None], running: Callable[[], bool],
                     name: str = "live-frames") -> threading.Thread:
    """:func:`forward_frames` in a daemon thread (started)."""
    thread = threading.Thread(target=forward_frames, args=(sub, send, running), name=name, daemon=True)
    thread.start()
    return thread
