"""A camera read through ``cv2.VideoCapture`` in its own thread (docs/protocols.md, "Camera").

``source`` is whatever VideoCapture opens: a device index (``0``), a video file, an image-sequence
pattern (``frames/img_%04d.png``) or a stream URL. The capture thread stamps each frame with
``time.monotonic_ns()`` right after ``read()`` returns (the same clock as the DAQ blocks; capture
latency inside the camera is not compensated), numbers it, converts it to 8-bit grey (H x W uint8)
and puts it in a bounded queue; when the reader falls behind the oldest frame goes and
``queue_dropped`` counts it, and the gap in ``seq`` shows as ``dropped_before`` on the next frame.
A frame interval above 1.5 / ``frame_rate_hz`` is a drop too (frames the camera never delivered).

``playback_rate_hz`` paces a file source like a live camera (for replays and tests); its frames are
stamped at their scheduled times (period 1 / ``playback_rate_hz`` from ``start()``), so a playback
thread that runs late on a loaded machine delivers them late but no drop is counted. Exposure and
gain map to ``CAP_PROP_EXPOSURE`` / ``CAP_PROP_GAIN``; OpenCV's exposure unit depends on the
backend, so exposure is supported only when ``exposure_units_per_s`` is configured (e.g. 10,000
for V4L2's 100 us steps), and a setting the backend refuses raises :class:`NotSupportedError`.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from drivers.errors import DeviceError, DeviceStateError, NotSupportedError, SettingError
from drivers.interfaces import Camera, RawFrame
from drivers.validate import check_integer, check_number


@dataclass(frozen=True)
class CameraConfig:
    """Source, nominal rate and buffering of an :class:`OpenCvCamera`."""

    name: str = "camera"
    source: int | str = 0
    frame_rate_hz: float = 60.0
    queue_size: int = 8
    playback_rate_hz: float | None = None
    exposure_units_per_s: float | None = None

    def __post_init__(self) -> None:
        owner = f"camera {self.name!r}"
        if isinstance(self.source, bool) or not isinstance(self.source, int | str):
            raise SettingError(owner, "source", self.source, "must be a device index or a path/URL")
        for key, unit in (("frame_rate_hz", "Hz"), ("playback_rate_hz", "Hz"),
                          ("exposure_units_per_s", "1/s")):
            value = getattr(self, key)
            if value is None and key != "frame_rate_hz":
                continue
            check_number(owner, key, value, unit=unit, gt=0.0)
        check_integer(owner, "queue_size", self.queue_size, 1, 10_000)


def to_gray_u8(image: NDArray[np.integer | np.floating]) -> NDArray[np.uint8]:
    """An OpenCV image as 8-bit grey H x W (BGR/BGRA converted; 16-bit scaled by 1/256)."""
    frame: NDArray[np.uint8]
    if image.dtype == np.uint16:
        frame = (image.astype(np.uint16) >> 8).astype(np.uint8)
    elif image.dtype == np.uint8:
        frame = image.astype(np.uint8, copy=False)
    else:
        raise ValueError(f"unsupported image dtype {image.dtype}")
    if frame.ndim == 3 and frame.shape[2] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if frame.shape[2] == 3 else cv2.COLOR_BGRA2GRAY
        frame = np.asarray(cv2.cvtColor(frame, code), dtype=np.uint8)
    elif frame.ndim == 3 and frame.shape[2] == 1:
        frame = frame[:, :, 0]
    if frame.ndim != 2:
        raise ValueError(f"unsupported image shape {image.shape}")
    return np.ascontiguousarray(frame)


class OpenCvCamera(Camera):
    """A :class:`Camera` over ``cv2.VideoCapture`` with a capture thread and a bounded queue."""

    def __init__(self, config: CameraConfig | None = None) -> None:
        cfg = config if config is not None else CameraConfig()
        super().__init__(cfg.name)
        self._config = cfg
        self._capture: cv2.VideoCapture | None = None
        self._capture_lock = threading.Lock()
        self._queue: deque[RawFrame] = deque(maxlen=cfg.queue_size)
        self._cond = threading.Condition()
        self._thread: threading.Thread | None = None
        self._running = False
        self._ended = False
        self._capture_error: str | None = None
        self._queue_dropped = 0
        self._seq = 0

    @property
    def config(self) -> CameraConfig:
        """The configuration this camera was built from."""
        return self._config

    @property
    def frame_rate_hz(self) -> float:
        """Nominal frame rate [Hz] from the configuration."""
        return self._config.frame_rate_hz

    @property
    def queue_dropped(self) -> int:
        """Frames pushed out of the full queue since start (they show as seq gaps)."""
        return self._queue_dropped

    @property
    def ended(self) -> bool:
        """True once the source gave no more frames (end of file, camera unplugged)."""
        return self._ended

    # hooks --------------------------------------------------------------------------------------
    def _do_start(self) -> None:
        if self._thread is not None:
            raise DeviceStateError(self.name, "already started")
        capture = cv2.VideoCapture(self._config.source)
        if not capture.isOpened():
            capture.release()
            raise DeviceError(self.name, f"cannot open video source {self._config.source!r}")
        self._capture = capture
        self._queue.clear()
        self._queue_dropped = 0
        self._seq = 0
        self._ended = False
        self._capture_error = None
        self._running = True
        self._thread = threading.Thread(target=self._capture_loop, name=f"{self.name}-capture")
        self._thread.daemon = True
        self._thread.start()

    def _do_stop(self) -> None:
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        with self._capture_lock:
            if self._capture is not None:
                self._capture.release()
                self._capture = None

    def _do_close(self) -> None:
        self._do_stop()

    def _do_read_frame(self, timeout_s: float) -> RawFrame | None:
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while not self._queue:
                if self._ended:
                    detail = f": {self._capture_error}" if self._capture_error else ""
                    raise DeviceStateError(self.name, f"capture ended, no more frames{detail}")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return None
                self._cond.wait(remaining)
            return self._queue.popleft()

    def _do_get_exposure_s(self) -> float:
        units = self._exposure_units()
        return self._get_property(cv2.CAP_PROP_EXPOSURE, "exposure") / units

    def _do_set_exposure_s(self, exposure_s: float) -> None:
        units = self._exposure_units()
        self._set_property(cv2.CAP_PROP_EXPOSURE, exposure_s * units, "exposure")

    def _do_get_gain(self) -> float:
        return self._get_property(cv2.CAP_PROP_GAIN, "gain")

    def _do_set_gain(self, gain: float) -> None:
        self._set_property(cv2.CAP_PROP_GAIN, gain, "gain")

    # internals ----------------------------------------------------------------------------------
    def _exposure_units(self) -> float:
        units = self._config.exposure_units_per_s
        if units is None:
            raise NotSupportedError(self.name, "exposure (set exposure_units_per_s for this backend)")
        return units

    def _get_property(self, prop: int, what: str) -> float:
        with self._capture_lock:
            if self._capture is None:
                raise DeviceStateError(self.name, f"{what}: camera not started")
            value = float(self._capture.get(prop))
        if value == 0.0 and what == "exposure":  # 0 s is no exposure: the backend has none
            raise NotSupportedError(self.name, what)
        return value

    def _set_property(self, prop: int, value: float, what: str) -> None:
        with self._capture_lock:
            if self._capture is None:
                raise DeviceStateError(self.name, f"{what}: camera not started")
            accepted = bool(self._capture.set(prop, value))
        if not accepted:
            raise NotSupportedError(self.name, what)

    def _capture_loop(self) -> None:
        period_ns = None
        if self._config.playback_rate_hz is not None:
            period_ns = round(1e9 / self._config.playback_rate_hz)
        next_due_ns = time.monotonic_ns()
        due_ns = next_due_ns
        while self._running:
            if period_ns is not None:
                delay_ns = next_due_ns - time.monotonic_ns()
                if delay_ns > 0:
                    time.sleep(delay_ns * 1e-9)
                due_ns = next_due_ns
                next_due_ns += period_ns
            with self._capture_lock:
                capture = self._capture
                if capture is None:
                    break
                ok, image = capture.read()
            # a paced file is a replay: its frames are stamped at their scheduled times, so a
            # playback thread starved by a loaded machine emits late but loses nothing
            t_ns = time.monotonic_ns() if period_ns is None else due_ns
            if not ok or image is None:
                self._finish(None)
                return
            try:
                gray = to_gray_u8(image)
            except ValueError as exc:
                self._finish(str(exc))
                return
            with self._cond:
                if len(self._queue) == self._queue.maxlen:
                    self._queue_dropped += 1
                self._queue.append(RawFrame(gray, t_ns, self._seq))
                self._seq += 1
                self._cond.notify_all()

    def _finish(self, error: str | None) -> None:
        with self._cond:
            self._ended = True
            self._capture_error = error
            self._cond.notify_all()
