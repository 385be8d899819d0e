"""End to end: stage moved over Modbus, forces read over CAN, camera watching, one virtual rig.

The tangential stage is driven at 10 um/s through the real Modbus driver (rig accelerated); the
real CanDaq driver's Ft must follow the stick-slip cycle of the paper's model (rise to a peak near
mu_s,max * Fn, then drops), and the camera must show the back end of the contact darkening as Ft
rises in the initial stage (seed, Section 3.2).
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from sim_devices.backends import open_sim_rig
from sim_devices.camera_sim import SimCamera

from .helpers import load_normal

SPEED = 20.0
MU_S_MAX = 0.2  # the paper's identified mu_s,max (seed, Section 5.3)


def back_and_front(image: NDArray[np.uint8], camera: SimCamera) -> tuple[float, float]:
    """Mean grey level above dark of the back 30 % and the front 30 % of the boss."""
    r = camera.renderer
    cols = r.boss_columns()
    third = 3 * r.boss_px // 10
    img = image[r.boss_rows()].astype(float) - r.optics.dark_level
    return float(img[:, cols.start : cols.start + third].mean()), float(
        img[:, cols.stop - third : cols.stop].mean()
    )


def test_modbus_drive_can_forces_and_camera_follow_one_stick_slip_rig() -> None:
    with open_sim_rig("sim-wire", speed=SPEED) as sim:
        dev = sim.devices
        camera = dev.camera
        assert isinstance(camera, SimCamera)
        load_normal(sim, 300.0)
        camera.start()
        first = camera.read_frame(2.0)  # through the interface: the loaded contact at rest
        camera.stop()

        dev.daq.start()
        m = dev.daq.channel_map
        dev.tangential_stage.enable()
        k_move = sim.rig.k  # at rest until the move below: the rig's record of it starts here
        # (taken after enabling: on a loaded machine a command's wall-time delay is up to 20 times
        # that in rig time, and the rig's ring keeps only ~24 s of it)
        dev.tangential_stage.move_relative(0.4e-3, 10e-6)  # 10 um/s for 40 s (2 s at 20x)
        t_moved_s = sim.rig.t_s  # the move runs from this rig time at the latest
        ft_parts: list[np.ndarray] = []
        fn_parts: list[np.ndarray] = []
        t_end_s = None
        while True:  # 22 s of the rig's time after the move (counted from the DAQ's start, a
            # wall-time delay of the command on a loaded machine is up to 20 times that in rig time)
            block = dev.daq.read_block(4096, 1.0)
            assert len(block), "the DAQ stopped streaming"
            ft_parts.append(m.ft_N(block))
            fn_parts.append(m.fn_N(block))
            start_s = sim.rig.daq_stream_start_s
            assert start_s is not None
            t_end_s = t_moved_s - start_s + 22.0 if t_end_s is None else t_end_s
            if float(block.t_s[-1]) >= t_end_s:
                break
        dev.daq.stop()
        dev.tangential_stage.stop()
        truth = sim.rig.samples(k_move, sim.rig.k + 1)
        # what the camera exposed when the rig's Ft first reached 30 N (initial stage)
        i30 = int(np.argmax(truth.ft_N >= 30.0))
        assert truth.stage[i30] == 0
        during = camera.frame_at(float(truth.t_s[i30]))

    ft = np.concatenate(ft_parts)
    fn = float(np.mean(np.concatenate(fn_parts)))
    assert fn == pytest.approx(300.0, abs=6.0)  # the normal stage sets Fn within one count
    peak = float(ft.max())
    assert peak == pytest.approx(MU_S_MAX * fn, rel=0.03)
    assert peak == pytest.approx(float(truth.ft_N.max()), abs=0.3)  # the DAQ saw the rig's peak
    i_peak = int(np.argmax(ft))
    start = int(np.argmax(ft > 2.0))
    rising = ft[start:i_peak]
    means = rising[: len(rising) // 512 * 512].reshape(-1, 512).mean(axis=1)
    assert len(means) >= 10 and np.all(np.diff(means) > 0)  # the initial stage loads steadily
    after = ft[i_peak:]
    big_drops = np.flatnonzero(np.diff(after) < -5.0)
    assert after.min() < 0.5 * peak  # the first slip drops far
    assert len(np.unique(big_drops // 512)) >= 3  # and stick-slip goes on in the stable stage

    back0, front0 = back_and_front(first.image, camera)
    back1, front1 = back_and_front(during, camera)
    assert back1 < 0.7 * back0  # the back end darkens (contact separation) ...
    assert front1 == pytest.approx(front0, rel=0.15)  # ... while the front end stays
