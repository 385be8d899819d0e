"""The simulated camera on an accelerated rig: what it owes the rig, and its frames' DAQ times.

A paced rig (``rigctl.rigs.Pacer``) may not run further ahead of the camera than the next frame it
owes (``VirtualRig.owed_s``); the camera stamps each frame with its time on the DAQ's sample clock
while the simulated DAQ streams; a rig that advances more slowly than the host clock is not a
camera that stopped answering.
"""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

from drivers.errors import DeviceTimeout
from drivers.interfaces import FrameDropDetector
from sim_devices.camera_sim import SimCamera
from sim_devices.inprocess import InProcessDaq
from sim_devices.virtual_rig import VirtualRig


def test_the_camera_owes_its_next_frame_while_it_runs() -> None:
    rig = VirtualRig()  # manual clock
    rig.advance_to(0.5)
    cam = SimCamera(rig, frame_rate_hz=20.0)
    assert rig.owed_s() == math.inf  # not started: owes nothing
    cam.start()
    t0 = math.ceil(0.5 * 20.0 + 1e-9) / 20.0
    assert rig.owed_s() == pytest.approx(t0)
    rig.advance_to(0.8)
    frames = [cam.read_frame(0.5) for _ in range(3)]
    assert [f.seq for f in frames] == [0, 1, 2]
    assert rig.owed_s() == pytest.approx(t0 + 3 / 20.0)
    cam.stop()
    assert rig.owed_s() == math.inf
    cam.start()
    cam.close()  # a closed camera owes nothing either
    assert rig.owed_s() == math.inf


def test_frames_carry_their_time_on_the_daq_clock_while_the_daq_streams() -> None:
    rig = VirtualRig()
    rig.advance_to(0.3)
    cam = SimCamera(rig, frame_rate_hz=10.0)
    daq = InProcessDaq(rig)
    cam.start()
    rig.advance_to(0.45)
    assert math.isnan(cam.read_frame(0.5).t_device_s)  # no DAQ stream: only host time known
    daq.start()
    t_start = rig.daq_stream_start_s
    assert t_start is not None and t_start == pytest.approx(rig.t_s + 1 / rig.rate_hz)
    rig.advance_to(1.5)
    block = daq.read_block(4096, 0.5)
    frames = [cam.read_frame(0.5) for _ in range(5)]
    t_dev = np.array([f.t_device_s for f in frames])
    t_rig = cam._t0_s + np.array([f.seq for f in frames]) / 10.0
    np.testing.assert_allclose(t_dev, t_rig - t_start, atol=1e-12)
    # the DAQ's own clock agrees: its sample n is at rig time t_start + n / rate
    assert block.t_s[0] == 0.0
    np.testing.assert_allclose(block.t_s[-1], rig.t_s - t_start, atol=1e-9)
    daq.stop()
    assert rig.daq_stream_start_s is None
    cam.close()
    daq.close()


@pytest.mark.slow
def test_a_rig_slower_than_the_host_clock_does_not_time_the_camera_out() -> None:
    rig = VirtualRig()
    cam = SimCamera(rig, frame_rate_hz=10.0)
    cam.start()
    stop = threading.Event()

    def crawl() -> None:  # 1/20 of a frame period every 50 ms: the next frame takes 1 s of host
        while not stop.is_set() and rig.t_s < 1.0:
            rig.advance_by(0.005)
            time.sleep(0.05)

    th = threading.Thread(target=crawl)
    th.start()
    try:
        t0 = time.monotonic()
        # frames 0 and 1 at 0.1 and 0.2 s of rig time: 20 crawl steps (1 s of host) each, far
        # beyond the 0.3 s timeout, but the rig keeps moving
        frame = cam.read_frame(0.3)
        frame = cam.read_frame(0.3)
        assert frame.seq == 1 and time.monotonic() - t0 > 0.6
    finally:
        stop.set()
        th.join()
    with pytest.raises(DeviceTimeout):  # a rig that stopped: the camera times out
        cam.read_frame(0.3)
    cam.close()


def test_drops_are_judged_on_device_time_when_frames_have_it() -> None:
    det = FrameDropDetector(60.0)
    # host intervals of an unevenly paced rig (a 200 ms hold), device intervals of 1/60 s
    host_ns = [0, 2_000_000, 202_000_000, 204_000_000]
    assert [det.update(i, h, i / 60.0) for i, h in enumerate(host_ns)] == [0, 0, 0, 0]
    # a seq gap is a loss on any clock; so is a long device interval
    assert det.update(5, 206_000_000, 5 / 60.0) == 1
    assert det.update(6, 208_000_000, 9 / 60.0) == 3
    plain = FrameDropDetector(60.0)  # host time only: the hold reads as lost frames
    assert [plain.update(i, h) for i, h in enumerate(host_ns)] == [0, 0, 11, 0]
