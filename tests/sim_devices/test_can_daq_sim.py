"""The DAQ node simulator on a python-can virtual bus: commands, frames, counter, quantisation."""

from __future__ import annotations

import struct
import uuid
from collections.abc import Iterator

import can
import numpy as np
import pytest

from sim_devices.can_daq_sim import CanDaqSim, CanDaqSimConfig
from sim_devices.sensors import ForceSensorSpec, ProbeSpec
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig

QUIET = ForceSensorSpec(noise_rms_N=(0.0, 0.0, 0.0), analog_noise_rms_V=0.0)


@pytest.fixture
def rig() -> VirtualRig:
    """Manual clock, noiseless probes (the analog channels then read exactly 0 V at rest)."""
    quiet = (ProbeSpec(noise_rms_m=0.0), ProbeSpec(noise_rms_m=0.0))
    return VirtualRig(config=VirtualRigConfig(probes=quiet))


@pytest.fixture
def node(rig: VirtualRig) -> Iterator[tuple[CanDaqSim, can.BusABC]]:
    channel = f"test-{uuid.uuid4().hex[:8]}"
    with CanDaqSim(rig, CanDaqSimConfig(channel=channel, sensor=QUIET)) as sim:
        host = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
        yield sim, host
        host.shutdown()


def ask(host: can.BusABC, payload: bytes) -> bytes:
    host.send(can.Message(arbitration_id=0x601, data=payload, is_extended_id=False))
    while True:
        msg = host.recv(timeout=1.0)
        assert msg is not None, "no reply"
        if msg.arbitration_id == 0x581:
            return bytes(msg.data)


def frames(host: can.BusABC, n: int) -> list[can.Message]:
    out: list[can.Message] = []
    while len(out) < n:
        msg = host.recv(timeout=1.0)
        assert msg is not None, f"only {len(out)} of {n} frames"
        if msg.arbitration_id in (0x181, 0x281):
            out.append(msg)
    return out


def test_commands_and_status_codes(node: tuple[CanDaqSim, can.BusABC]) -> None:
    _, host = node
    assert ask(host, b"\x05") == bytes([0x85, 0, 0]) + struct.pack("<H", 1024)
    assert ask(host, b"\x09") == bytes([0x89, 1])  # unknown command
    assert ask(host, b"\x04" + struct.pack("<H", 0)) == bytes([0x84, 2])
    assert ask(host, b"\x04" + struct.pack("<H", 2048)) == bytes([0x84, 2])  # > the rig's rate
    assert ask(host, b"\x04\x01") == bytes([0x84, 2])  # no uint16
    assert ask(host, b"\x04" + struct.pack("<H", 512)) == bytes([0x84, 0])
    assert ask(host, b"\x01") == bytes([0x81, 0])
    assert ask(host, b"\x04" + struct.pack("<H", 256)) == bytes([0x84, 3])  # busy: streaming
    assert ask(host, b"\x05") == bytes([0x85, 0, 1]) + struct.pack("<H", 512)
    assert ask(host, b"\x02") == bytes([0x82, 0])


def test_frames_follow_the_rig_clock_quantised(
    rig: VirtualRig, node: tuple[CanDaqSim, can.BusABC]
) -> None:
    _, host = node
    rig.normal.enable()
    rig.normal.move_to(rig.config.contact.z_for_fn_m(123.456), 2e-3)
    rig.advance_to(1.0)
    assert ask(host, b"\x01") == bytes([0x81, 0])
    assert host.recv(timeout=0.1) is None  # nothing until the rig's clock moves
    rig.advance_by(100 / 1024)
    got = frames(host, 200)
    assert host.recv(timeout=0.05) is None  # exactly two frames per sample, no more
    force = [struct.unpack("<Hhhh", bytes(m.data)) for m in got if m.arbitration_id == 0x181]
    analog = [struct.unpack("<Hhhh", bytes(m.data)) for m in got if m.arbitration_id == 0x281]
    assert [f[0] for f in force] == list(range(100)) == [a[0] for a in analog]
    fz = np.array([f[3] for f in force])
    assert np.all(fz == round(rig.state.fn_N / 0.025))  # 123.456 N -> 4938 counts of 0.025 N
    assert all(f[1] == 0 and a[1] == 0 and a[2] == 0 for f, a in zip(force, analog, strict=True))


def test_tare_and_half_rate(rig: VirtualRig, node: tuple[CanDaqSim, can.BusABC]) -> None:
    _, host = node
    rig.normal.enable()
    rig.normal.move_to(rig.config.contact.z_for_fn_m(50.0), 2e-3)
    rig.advance_to(1.0)
    assert ask(host, b"\x03") == bytes([0x83, 0])
    assert ask(host, b"\x04" + struct.pack("<H", 512)) == bytes([0x84, 0])
    assert ask(host, b"\x01") == bytes([0x81, 0])
    rig.advance_by(0.25)
    got = frames(host, 2 * 128)
    force = [struct.unpack("<Hhhh", bytes(m.data)) for m in got if m.arbitration_id == 0x181]
    assert [f[0] for f in force] == list(range(128))  # 512 Hz: half the rig's samples
    assert all(f[3] == 0 for f in force)  # tared


def test_wire_faults(rig: VirtualRig, node: tuple[CanDaqSim, can.BusABC]) -> None:
    sim, host = node
    sim.faults.silent = True
    host.send(can.Message(arbitration_id=0x601, data=b"\x05", is_extended_id=False))
    assert host.recv(timeout=0.2) is None
    sim.faults.silent = False
    assert ask(host, b"\x01") == bytes([0x81, 0])
    sim.faults.short_pct = 100.0
    rig.advance_by(10 / 1024)
    assert all(len(m.data) < 8 for m in frames(host, 20))
    sim.faults.short_pct = 0.0
    sim.faults.drop_pct = 50.0
    rig.advance_by(200 / 1024)
    got = []
    while (msg := host.recv(timeout=0.2)) is not None:
        got.append(msg)
    assert 100 < len(got) < 300 and sim.frames_dropped == 400 - len(got)
