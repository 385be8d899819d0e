"""What every backend of the SIMULATED rig must show, on top of the drivers' interface contracts.

The drivers' mixins (tests/drivers/contract.py) check the interfaces; these check that the devices
behave like the physical rig they simulate, through the same public interfaces, so the in-process
backend and the wire-level simulators behind the real drivers are held to one standard. Fixtures to
provide: ``sim`` (a running :class:`SimRig`) and ``stage`` / ``daq`` / ``probe`` / ``camera``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from drivers.errors import DeviceStateError, OverRangeError, StageAlarm
from drivers.interfaces import Camera, Daq, DisplacementProbe, LoadingStage
from sim_devices.backends import SimRig

from .helpers import collect, load_normal, move_tangential


class SimStageContract:
    """A simulated stage takes time to move, honours velocity, stops, and raises its alarms."""

    stage_key = "tangential_stage"
    direction = 1.0  # +1 tangential; the normal stage moves away from the contact (-1)

    def test_move_honours_velocity(self, sim: SimRig, stage: LoadingStage) -> None:
        stage.enable()
        start = stage.position_m()
        distance, velocity = 0.5e-3, 0.1e-3  # 5 s of the rig, 0.25 s of the host
        accel = sim.rig.config.tangential.accel_m_s2 if self.direction > 0 else \
            sim.rig.config.normal.accel_m_s2
        k_cmd = sim.rig.k
        stage.move_relative(self.direction * distance, velocity)
        assert stage.status().moving
        seen = []  # positions reported through the interface while the move runs
        while stage.status().moving:
            seen.append(self.direction * (stage.position_m() - start))
        assert any(0.1 * distance < p < 0.9 * distance for p in seen)  # no jump to the target
        stage.wait_for_motion(5.0)
        # the rig's own history of the stage position: how long the move really took
        hist = sim.rig.samples(k_cmd, sim.rig.k + 1)
        pos = hist.x_stage_m if self.stage_key == "tangential_stage" else hist.z_normal_m
        changing = np.flatnonzero(np.diff(pos) != 0.0)
        duration = hist.t_s[changing[-1] + 1] - hist.t_s[changing[0]]
        expected = distance / velocity + velocity / accel  # trapezoid: cruise + one ramp
        assert duration == pytest.approx(expected, abs=0.01)
        status = stage.status()
        assert status.in_position and not status.moving
        assert stage.position_m() == pytest.approx(start + self.direction * distance, abs=1e-6)

    def test_stop_decelerates_short_of_target(self, sim: SimRig, stage: LoadingStage) -> None:
        stage.enable()
        start = stage.position_m()
        t_cmd = sim.rig.t_s
        stage.move_relative(self.direction * 5e-3, 1e-3)
        assert sim.rig.wait_until(t_cmd + 1.0, 2.0)
        stage.stop()
        status = stage.wait_for_motion(2.0)
        travelled = self.direction * (stage.position_m() - start)
        assert not status.moving and not status.fault
        assert 0.5e-3 < travelled < 4.5e-3  # stopped on the way (when depends on the host's load)

    def test_move_while_disabled_refused(self, stage: LoadingStage) -> None:
        before = stage.position_m()
        with pytest.raises(DeviceStateError):
            stage.move_relative(self.direction * 1e-4, 1e-3)
        assert stage.position_m() == before

    def test_controller_alarm_is_raised_and_reset(self, sim: SimRig, stage: LoadingStage) -> None:
        stage.enable()
        sim.faults[self.stage_key].alarm_code = 2  # following error
        status = stage.status()
        assert status.fault and status.alarm_code == 2 and status.alarm_name == "following error"
        with pytest.raises(StageAlarm) as err:
            stage.move_relative(self.direction * 1e-4, 1e-3)
        assert err.value.alarm_code == 2
        stage.reset_alarm()
        stage.move_relative(self.direction * 1e-4, 1e-3)
        assert not stage.wait_for_motion(2.0).fault


class SimDaqContract:
    """The DAQ shows the rig's forces and probe outputs, quantised to the documented scales."""

    def test_forces_follow_the_normal_load(self, sim: SimRig, daq: Daq) -> None:
        load_normal(sim, 200.0)
        daq.start()
        try:
            s = collect(daq, 256)
        finally:
            daq.stop()
        fn_true = sim.rig.state.fn_N
        assert fn_true == pytest.approx(200.0, abs=6.0)  # one 0.6 um count of the stage
        assert float(np.mean(s["fn"])) == pytest.approx(fn_true, abs=0.1)
        assert abs(float(np.mean(s["ft"]))) < 0.1
        assert np.all(np.abs(s["fy"]) < 0.5)
        counts = s["fn"] / 0.025  # the default scale, 0.025 N/count
        np.testing.assert_allclose(counts, np.rint(counts), atol=1e-6)

    def test_tare_zeroes_the_forces(self, sim: SimRig, daq: Daq) -> None:
        load_normal(sim, 100.0)
        # tare at a steady load, as an operator does: right at the stage's arrival the last 32
        # samples the tare averages can still hold the end of the approach (flaky 2 runs in 5)
        assert sim.rig.wait_until(sim.rig.t_s + 0.1, 2.0)
        daq.tare()
        daq.start()
        try:
            s = collect(daq, 256)
        finally:
            daq.stop()
        assert abs(float(np.mean(s["fn"]))) < 0.1
        assert abs(float(np.mean(s["ft"]))) < 0.05

    def test_analog_probe_channels_follow_the_specimen(self, sim: SimRig, daq: Daq) -> None:
        move_tangential(sim, 10e-6)  # specimens apart: the driven specimen follows the stage
        daq.start()
        try:
            s = collect(daq, 128)
        finally:
            daq.stop()
        assert float(np.mean(s["d1"])) == pytest.approx(sim.rig.state.d1_m, abs=0.05e-6)
        assert float(np.mean(s["d1"])) == pytest.approx(10e-6, abs=0.1e-6)
        assert abs(float(np.mean(s["d2"]))) < 0.05e-6


class SimProbeContract:
    """Probe readings are quantised to 0.019 um, relative to the zero, and over range beyond 37 um."""

    probe_index = 0

    def test_reading_quantised_and_zeroed(self, sim: SimRig, probe: DisplacementProbe) -> None:
        move_tangential(sim, 7.3e-6)
        value = probe.read_m()
        ideal = sim.rig.state.d1_m if self.probe_index == 0 else sim.rig.state.d2_m
        assert value == pytest.approx(ideal, abs=probe.resolution_m)
        steps = value / probe.resolution_m
        assert steps == pytest.approx(round(steps), abs=1e-6)
        probe.zero()
        assert abs(probe.read_m()) <= probe.resolution_m

    def test_over_range_reported_never_clipped(self, sim: SimRig, probe: DisplacementProbe) -> None:
        move_tangential(sim, 40e-6)
        if self.probe_index == 1:  # D2 watches the fixed specimen: it stays at its zero
            assert abs(probe.read_m()) <= probe.resolution_m
            return
        with pytest.raises(OverRangeError) as err:
            probe.read_m()
        assert err.value.direction == 1
        probe.start_stream(256)
        try:
            _, values, _ = probe.read_stream(16, timeout_s=1.0)
        finally:
            probe.stop_stream()
        assert len(values) > 0 and np.all(values == math.inf)
        probe.zero()
        assert abs(probe.read_m()) <= probe.resolution_m


class SimCameraContract:
    """The camera sees the contact: brighter under load, dark when the specimens are apart."""

    def test_contact_brightens_with_load(self, sim: SimRig, camera: Camera) -> None:
        camera.start()
        apart = camera.read_frame(2.0).image.astype(float)
        camera.stop()
        load_normal(sim, 300.0)
        camera.start()
        loaded = camera.read_frame(2.0).image.astype(float)
        camera.stop()
        boss = sim.devices.camera.renderer  # type: ignore[attr-defined]
        rows, cols = boss.boss_rows(), boss.boss_columns()
        assert apart[rows, cols].mean() < boss.optics.dark_level + 0.5
        assert loaded[rows, cols].mean() > apart[rows, cols].mean() + 1.0
        assert (loaded[rows, cols] > 60).mean() > 0.005  # bright contact spots exist
