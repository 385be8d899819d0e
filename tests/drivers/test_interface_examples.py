"""The usage examples in the driver interfaces' docstrings run as written (on the simulated rig)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.interfaces import Camera, Daq, DisplacementProbe, LoadingStage
from sim_devices.backends import open_sim_rig


@pytest.mark.parametrize("cls", [LoadingStage, Daq, DisplacementProbe, Camera])
def test_every_interface_shows_a_usage_example(cls: type) -> None:
    assert "Usage" in (cls.__doc__ or "") and "::" in (cls.__doc__ or "")


def test_the_examples_run_on_the_simulated_rig() -> None:
    with open_sim_rig("sim", speed=50.0) as sim:
        stage = sim.devices.tangential_stage
        stage.enable()
        target = stage.position_m() + 20e-6
        stage.move_absolute(target, 100e-6)
        stage.wait_for_motion(timeout_s=30.0)
        assert stage.position_m() == pytest.approx(target, abs=1e-6)

        daq = sim.devices.daq
        daq.start()
        block = daq.read_block(1024, timeout_s=1.0)
        fn_N = daq.channel_map.fn_N(block)
        daq.stop()
        assert fn_N.shape == block.t_s.shape and fn_N.size > 0

        probe = sim.devices.d1
        probe.zero()
        assert abs(probe.read_m()) < 5e-6
        probe.start_stream(1000.0)
        samples = probe.read_stream(1000, timeout_s=1.0)
        probe.stop_stream()
        assert samples.values_m.size == samples.seq.size > 0

        camera = sim.devices.camera
        camera.start()
        frame = camera.read_frame(timeout_s=1.0)
        camera.stop()
        assert frame.image.dtype == np.uint8 and frame.seq == 0
