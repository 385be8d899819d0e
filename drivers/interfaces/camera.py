"""Cameras: frames, drop detection and the abstract camera."""

from __future__ import annotations

import math
from abc import abstractmethod
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from drivers.errors import DeviceStateError, DeviceTimeout, NotSupportedError
from drivers.interfaces.common import Device
from drivers.validate import check_argument, check_timeout


class RawFrame(NamedTuple):
    """What a camera hook returns: image (uint8, H x W), capture time [monotonic ns], sequence."""

    image: NDArray[np.uint8]
    t_monotonic_ns: int
    seq: int
    t_device_s: float = math.nan
    """Capture time on the DAQ's sample clock when the camera is synchronised to it (the simulated
    camera: both run on the rig's clock); NaN when only the host time is known."""


@dataclass(frozen=True, eq=False)
class Frame:
    """A camera frame: uint8 H x W image, host capture time, sequence number, frames lost before."""

    image: NDArray[np.uint8]
    t_monotonic_ns: int
    seq: int
    dropped_before: int
    t_device_s: float = math.nan
    """Capture time on the DAQ's sample clock (NaN: unknown; see :class:`RawFrame`)."""


@dataclass
class FrameDropDetector:
    """Counts frames lost before each frame: a ``seq`` gap or an interval above 1.5 periods.

    Lost frames = max(seq gap, round(interval * frame_rate_hz) - 1 when interval > 1.5 / rate): a
    gap and a long interval usually describe the same loss, so they are not added. The interval is
    taken on the DAQ's clock when frames carry a device time (a synchronised camera: on an
    accelerated simulated rig the host intervals are rig intervals divided by an uneven speed).
    """

    frame_rate_hz: float
    total_dropped: int = 0
    _last_seq: int | None = field(default=None, repr=False)
    _last_t_ns: int | None = field(default=None, repr=False)
    _last_t_device_s: float = field(default=math.nan, repr=False)

    def update(self, seq: int, t_monotonic_ns: int, t_device_s: float = math.nan) -> int:
        """Frames lost between the previous frame and this one.

        Sequence numbers start at 0 at ``start()``, so a first frame numbered n means n were lost.
        """
        dropped = max(seq, 0)
        if self._last_seq is not None and self._last_t_ns is not None:
            gap = max(seq - self._last_seq - 1, 0)
            if math.isfinite(t_device_s) and math.isfinite(self._last_t_device_s):
                interval_s = t_device_s - self._last_t_device_s
            else:
                interval_s = (t_monotonic_ns - self._last_t_ns) * 1e-9
            late = 0
            if interval_s > 1.5 / self.frame_rate_hz:
                late = max(round(interval_s * self.frame_rate_hz) - 1, 1)
            dropped = max(gap, late)
        self._last_seq = seq
        self._last_t_ns = t_monotonic_ns
        self._last_t_device_s = t_device_s
        self.total_dropped += dropped
        return dropped

    def reset(self) -> None:
        """Forget the previous frame (after a stop/start)."""
        self._last_seq = None
        self._last_t_ns = None
        self._last_t_device_s = math.nan


class Camera(Device):
    """A camera delivering timestamped, numbered frames; drops are detected and counted.

    Implementations number frames from 0 at each ``start()`` (``RawFrame.seq``) and stamp them
    with ``time.monotonic_ns()``; the base class fills ``Frame.dropped_before``. Usage::

        camera.start()
        frame = camera.read_frame(timeout_s=1.0)       # frame.image, frame.seq, frame.dropped_before
        camera.stop()
    """

    def __init__(self, name: str) -> None:
        super().__init__(name)
        self._drops: FrameDropDetector | None = None
        self._running = False

    @property
    @abstractmethod
    def frame_rate_hz(self) -> float:
        """Nominal frame rate [Hz] (used for drop detection)."""

    @property
    def running(self) -> bool:
        """True between :meth:`start` and :meth:`stop`."""
        return self._running

    @property
    def frames_dropped(self) -> int:
        """Frames lost since :meth:`start`."""
        return 0 if self._drops is None else self._drops.total_dropped

    def start(self) -> None:
        """Start capturing."""
        self._check_open()
        self._drops = None
        self._do_start()
        self._drops = FrameDropDetector(self.frame_rate_hz)
        self._running = True

    def stop(self) -> None:
        """Stop capturing (frames already captured stay readable)."""
        self._do_stop()
        self._running = False

    def read_frame(self, timeout_s: float) -> Frame:
        """The next frame; DeviceTimeout if none arrives within ``timeout_s``."""
        self._check_open()
        if self._drops is None:
            raise DeviceStateError(self.name, "read_frame before start()")
        wait_s = check_timeout(self.name, timeout_s)
        raw = self._do_read_frame(wait_s)
        if raw is None:
            raise DeviceTimeout(self.name, wait_s, detail="no frame")
        dropped = self._drops.update(raw.seq, raw.t_monotonic_ns, raw.t_device_s)
        return Frame(raw.image, raw.t_monotonic_ns, raw.seq, dropped, raw.t_device_s)

    @property
    def exposure_s(self) -> float:
        """Exposure time [s] (NotSupportedError where the device cannot report it)."""
        return self._do_get_exposure_s()

    @exposure_s.setter
    def exposure_s(self, value: float) -> None:
        exposure = check_argument(self.name, "exposure_s", value, gt=0.0)
        self._do_set_exposure_s(exposure)

    @property
    def gain(self) -> float:
        """Analog gain (device units; NotSupportedError where unsupported)."""
        return self._do_get_gain()

    @gain.setter
    def gain(self, value: float) -> None:
        gain = check_argument(self.name, "gain", value, ge=0.0)
        self._do_set_gain(gain)

    @abstractmethod
    def _do_start(self) -> None: ...

    @abstractmethod
    def _do_stop(self) -> None: ...

    @abstractmethod
    def _do_read_frame(self, timeout_s: float) -> RawFrame | None:
        """The next frame, or None if none came within ``timeout_s``."""

    def _do_get_exposure_s(self) -> float:
        raise NotSupportedError(self.name, "exposure")

    def _do_set_exposure_s(self, exposure_s: float) -> None:
        raise NotSupportedError(self.name, "exposure")

    def _do_get_gain(self) -> float:
        raise NotSupportedError(self.name, "gain")

    def _do_set_gain(self, gain: float) -> None:
        raise NotSupportedError(self.name, "gain")
