"""Injected faults surface as the drivers' named errors within 1 s; the emergency stop stops all."""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import pytest

from drivers.can_daq import CanDaq
from drivers.errors import DeviceTimeout, EmergencyStopActive, ProtocolError
from drivers.safety import EmergencyStop
from sim_devices.backends import SimRig, open_sim_rig

from .conftest import SPEED
from .helpers import collect, load_normal, move_tangential


@contextmanager
def within(seconds: float) -> Iterator[None]:
    t0 = time.monotonic()
    yield
    elapsed = time.monotonic() - t0
    assert elapsed < seconds, f"took {elapsed:.2f} s"


@pytest.fixture
def wire(estop: EmergencyStop) -> Iterator[SimRig]:
    with open_sim_rig("sim-wire", speed=SPEED, emergency_stop=estop) as rig:
        yield rig


# ------------------------------------------------------------------------------- both backends
def test_silent_stage_times_out_then_recovers(sim: SimRig) -> None:
    stage = sim.devices.tangential_stage
    sim.faults["tangential_stage"].silent = True
    with within(1.0), pytest.raises(DeviceTimeout) as err:
        stage.status()
    assert err.value.device == "tangential"
    sim.faults["tangential_stage"].silent = False
    assert not stage.status().fault


def test_stuck_stage_freezes_its_readings(sim: SimRig) -> None:
    stage = sim.devices.tangential_stage
    stage.enable()
    stage.move_relative(2e-3, 1e-3)
    sim.faults["tangential_stage"].stuck = True
    frozen = stage.position_m()
    assert sim.rig.wait_until(sim.rig.t_s + 0.5, 2.0)
    assert stage.position_m() == frozen and stage.status().moving
    assert sim.rig.state.x_stage_m > frozen + 1e-4  # the stage itself kept moving
    sim.faults["tangential_stage"].stuck = False
    assert stage.position_m() > frozen + 1e-4


def test_silent_daq_times_out_while_streaming(sim: SimRig) -> None:
    daq = sim.devices.daq
    daq.start()
    collect(daq, 32)
    sim.faults["daq"].silent = True
    time.sleep(0.05)  # frames already on their way still arrive
    with within(1.5), pytest.raises(DeviceTimeout):
        for _ in range(20):
            daq.read_block(1024, 0.2)
    with within(1.0), pytest.raises(DeviceTimeout):
        daq.tare()
    sim.faults["daq"].silent = False
    daq.stop()


def test_dropped_samples_are_counted_never_invented(sim: SimRig) -> None:
    daq = sim.devices.daq
    sim.faults["daq"].drop_pct = 20.0
    daq.start()
    try:
        first = daq.read_block(1, 1.0)
        s = collect(daq, 1000)
        dropped = daq.dropped_samples - first.dropped_total
    finally:
        daq.stop()
    counter = s["counter"]
    assert np.all(np.diff(counter) >= 1)
    assert dropped > 100  # 20 % of samples (or, on CAN, ~36 % losing one of two frames)
    assert counter[-1] - first.counter[-1] == len(counter) + dropped


def test_stuck_daq_repeats_its_values(sim: SimRig) -> None:
    load_normal(sim, 150.0)
    daq = sim.devices.daq
    daq.start()
    try:
        live = collect(daq, 256)
        sim.faults["daq"].stuck = True
        time.sleep(0.05)
        daq.read_block(4096, 0.1)  # flush what was sent before
        stuck = collect(daq, 256)
    finally:
        daq.stop()
    assert np.ptp(live["fn"]) > 0.1  # live readings carry the sensor noise
    assert np.ptp(stuck["fn"][-128:]) == 0.0 and np.ptp(stuck["ft"][-128:]) == 0.0


def test_silent_and_stuck_probe(sim: SimRig) -> None:
    probe = sim.devices.d1
    sim.faults["d1"].stuck = True
    before = probe.read_m()
    move_tangential(sim, 5e-6)
    assert probe.read_m() == before
    sim.faults["d1"].stuck = False
    moved = sim.rig.state.d1_m  # 5 um asked, 5.12 um done: the stage moves in 0.32 um counts
    assert moved == pytest.approx(5e-6, abs=0.33e-6)
    assert probe.read_m() == pytest.approx(before + moved, abs=0.05e-6)
    sim.faults["d1"].silent = True
    with within(1.0), pytest.raises(DeviceTimeout):
        probe.read_m()


def test_emergency_stop_halts_both_moving_stages(sim: SimRig, estop: EmergencyStop) -> None:
    tan, nor = sim.devices.tangential_stage, sim.devices.normal_stage
    for stage, delta in ((tan, 10e-3), (nor, -5e-3)):
        stage.enable()
        stage.move_relative(delta, 2e-3)
    assert tan.status().moving and nor.status().moving
    with within(1.0):
        failures = estop.trigger("test: operator pressed the button")
        assert not failures
        statuses = [tan.status(), nor.status()]
    assert all(not s.moving and s.fault and s.alarm_code == 5 for s in statuses)
    frozen = (tan.position_m(), nor.position_m())
    assert sim.rig.wait_until(sim.rig.t_s + 0.5, 2.0)
    assert (tan.position_m(), nor.position_m()) == frozen
    with pytest.raises(EmergencyStopActive):
        tan.move_relative(1e-3, 1e-3)
    estop.reset()
    tan.reset_alarm()
    tan.move_relative(1e-4, 1e-3)
    assert not tan.wait_for_motion(2.0).fault


# ----------------------------------------------------------------------------------- wire only
@pytest.mark.parametrize("fault", ["corrupt_pct", "short_pct"])
def test_garbled_modbus_replies_are_protocol_errors(wire: SimRig, fault: str) -> None:
    setattr(wire.faults["normal_stage"], fault, 100.0)
    with within(1.0), pytest.raises(ProtocolError) as err:
        wire.devices.normal_stage.status()
    assert err.value.device == "normal" and err.value.data
    setattr(wire.faults["normal_stage"], fault, 0.0)
    assert not wire.devices.normal_stage.status().fault


@pytest.mark.parametrize("fault", ["corrupt_pct", "short_pct"])
def test_garbled_probe_lines_are_protocol_errors(wire: SimRig, fault: str) -> None:
    setattr(wire.faults["d2"], fault, 100.0)
    with within(1.0), pytest.raises(ProtocolError):
        wire.devices.d2.read_m()


def test_short_and_corrupt_can_frames_are_counted(wire: SimRig) -> None:
    daq = wire.devices.daq
    assert isinstance(daq, CanDaq)
    faults = wire.faults["daq"]
    daq.start()
    try:
        collect(daq, 64)
        assert daq.protocol_errors == 0
        faults.short_pct = 5.0
        collect(daq, 512)
        faults.short_pct = 0.0
        assert daq.protocol_errors > 0  # malformed frames: counted and skipped
        anomalies_before = daq.dropped_samples + daq.stale_frames
        faults.corrupt_pct = 2.0
        collect(daq, 512)
        faults.corrupt_pct = 0.0
    finally:
        daq.stop()
    assert daq.dropped_samples + daq.stale_frames > anomalies_before  # counter anomalies
