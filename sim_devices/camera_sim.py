"""The contact camera, simulated in process (OpenCV has no pluggable Python capture backend).

:class:`SimCamera` implements :class:`drivers.interfaces.Camera`. Frame j is exposed at simulated
time ``t0 + j / 60`` (``t0`` = the first frame time after ``start()``) and delivered once the rig's
clock has reached it, rendered by :class:`~sim_devices.contact_image.ContactImageRenderer` from the
rig's state at the nearest sample: Fn, the stage (initial / stable) and with it the element load
shares P, and which elements slide. Its timestamp is the host monotonic instant at which the rig's
clock reached ``t_j`` (``SimClock.host_ns_at``), on the same clock as the DAQ's host times, and,
while the simulated DAQ streams, its time on the DAQ's sample clock, ``t_j`` minus the rig time of
the DAQ stream's sample 0 (``RawFrame.t_device_s``: the camera is synchronised to the DAQ, as one
triggered by it would be), so frame times are exact however unevenly an accelerated rig advances.

Frames are rendered when read, so an accelerated rig does not pay for frames nobody reads; but the
camera's buffer holds only ``buffer_frames`` frames: a reader more than that far behind loses the
oldest ones, which shows as a gap in ``seq`` (counted in ``frames_dropped``), as with a real
camera's ring buffer. While it runs, the camera tells the rig the time of the next frame it owes
(``VirtualRig.owe``): an accelerated (paced) rig waits for it, so at ``--speed N|max`` every frame
of the frame rate is rendered, in rig time, as fast as rendering allows.

Faults (:mod:`sim_devices.faults`): ``silent`` (no frames: ``read_frame`` times out with
DeviceTimeout), ``drop_pct`` (frames lost: seq gaps), ``stuck`` (the same image repeats).
"""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from drivers.interfaces import Camera, RawFrame
from sim_devices.contact_image import CameraOptics, ContactImageRenderer, ContactOptics
from sim_devices.faults import Faults
from sim_devices.sample_ring import SamplesLostError
from sim_devices.virtual_rig import VirtualRig

FRAME_RATE_HZ = 60.0
"""Camera frame rate of the paper's rig (Han et al. 2022, Section 2.1)."""


class SimCamera(Camera):
    """A :class:`Camera` rendering total-reflection contact images of the virtual rig."""

    def __init__(
        self,
        rig: VirtualRig,
        name: str = "camera",
        *,
        optics: CameraOptics | None = None,
        contact: ContactOptics | None = None,
        frame_rate_hz: float = FRAME_RATE_HZ,
        buffer_frames: int = 120,
        faults: Faults | None = None,
    ) -> None:
        super().__init__(name)
        if not (math.isfinite(frame_rate_hz) and 0 < frame_rate_hz <= rig.rate_hz):
            raise ValueError(f"frame rate must be in (0, {rig.rate_hz:g}] Hz")
        if buffer_frames < 1:
            raise ValueError("buffer_frames must be >= 1")
        self.rig = rig
        self.renderer = ContactImageRenderer(optics, contact)
        self._rate_hz = float(frame_rate_hz)
        self.buffer_frames = buffer_frames
        self.faults = faults if faults is not None else Faults(seed=300)
        self._t0_s = 0.0
        self._j_next = 0
        self._last_image: NDArray[np.uint8] | None = None

    @property
    def frame_rate_hz(self) -> float:
        return self._rate_hz

    def _do_start(self) -> None:
        self._t0_s = math.ceil(self.rig.t_s * self._rate_hz + 1e-9) / self._rate_hz
        self._j_next = 0
        self._last_image = None
        self.rig.owe(self, self._t0_s)

    def _do_stop(self) -> None:
        """Nothing runs in the background (frames are rendered on read): the rig is owed nothing."""
        self.rig.owe(self, None)

    def _do_close(self) -> None:
        self.rig.owe(self, None)

    def _do_read_frame(self, timeout_s: float) -> RawFrame | None:
        if self.faults.silent:
            time.sleep(timeout_s)
            return None
        rig, rate = self.rig, self._rate_hz
        deadline = time.monotonic() + timeout_s
        t_seen = rig.t_s
        while True:
            j = self._j_next
            if not rig.wait_until(self._t0_s + j / rate, max(0.0, deadline - time.monotonic())):
                rig.check()
                if rig.t_s > t_seen:
                    # the rig moves, only slower than the host clock (a paced rig computing a
                    # loading step sample by sample): the frame is coming, the camera answers
                    t_seen = rig.t_s
                    deadline = time.monotonic() + timeout_s
                    continue
                return None
            newest = math.floor((rig.t_s - self._t0_s) * rate + 1e-9)
            j = max(j, newest - self.buffer_frames + 1)  # overwritten in the camera's buffer
            self._j_next = j + 1
            t_j = self._t0_s + j / rate
            if self.faults.roll(self.faults.drop_pct):
                rig.owe(self, self._t0_s + self._j_next / rate)
                continue
            try:
                image = self._image_at(t_j)
            except SamplesLostError:
                rig.owe(self, self._t0_s + self._j_next / rate)
                continue
            rig.owe(self, self._t0_s + self._j_next / rate)
            daq0 = rig.daq_stream_start_s
            t_device = t_j - daq0 if daq0 is not None else math.nan
            return RawFrame(image, rig.clock.host_ns_at(t_j), j, t_device)

    def _image_at(self, t_s: float) -> NDArray[np.uint8]:
        if self.faults.stuck and self._last_image is not None:
            return self._last_image
        image = self.frame_at(t_s)
        self._last_image = image
        return image

    def frame_at(self, t_s: float) -> NDArray[np.uint8]:
        """The image exposed at simulated time ``t_s`` (from the rig's history; for analysis).

        Raises :class:`~sim_devices.sample_ring.SamplesLostError` if ``t_s`` left the history and
        ValueError if the rig has not reached it yet.
        """
        k = round(t_s * self.rig.rate_hz)
        s = self.rig.samples(k, k + 1)
        if len(s) == 0:
            raise ValueError(f"the rig has not reached t = {t_s:.6f} s yet")
        stage = int(s.stage[0])
        return self.renderer.render(
            float(s.fn_N[0]), self.rig.p_tables[stage], s.sliding_elements[0], stage
        )
