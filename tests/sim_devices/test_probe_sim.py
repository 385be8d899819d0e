"""The probe simulator's ASCII conversation over its pty, byte for byte (pymeasure style)."""

from __future__ import annotations

import os
import select
import time
from collections.abc import Iterator

import pytest

from sim_devices.probe_sim import ProbeSim
from sim_devices.sensors import ProbeSpec
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig


class Host:
    """The host side of the serial line: the pty slave opened by path, raw bytes in and out."""

    def __init__(self, path: str) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        self.buffer = b""

    def ask(self, command: bytes, timeout_s: float = 1.0) -> bytes:
        os.write(self.fd, command + b"\r")
        return self.line(timeout_s)

    def line(self, timeout_s: float = 1.0) -> bytes:
        deadline = time.monotonic() + timeout_s
        while b"\r" not in self.buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"no line; got {self.buffer!r}")
            if select.select([self.fd], [], [], remaining)[0]:
                self.buffer += os.read(self.fd, 4096)
        line, _, self.buffer = self.buffer.partition(b"\r")
        return line

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def rig() -> VirtualRig:
    quiet = ProbeSpec(serial="SIM-D1", noise_rms_m=0.0)
    return VirtualRig(config=VirtualRigConfig(probes=(quiet, ProbeSpec(serial="SIM-D2", noise_rms_m=0.0))))


@pytest.fixture
def host(rig: VirtualRig) -> Iterator[Host]:
    with ProbeSim(rig, 0) as sim:
        h = Host(sim.path)
        yield h
        h.close()


def displace(rig: VirtualRig, delta_m: float) -> None:
    """Move the (unloaded) driven specimen by ``delta_m`` with the tangential stage."""
    rig.tangential.enable()
    rig.tangential.move_to(rig.state.x_stage_m + delta_m, 1e-4)
    rig.advance_to(rig.t_s + abs(delta_m) / 1e-4 + 0.5)


def test_identity_and_range(host: Host) -> None:
    assert host.ask(b"ID") == b"ID,MTI-2100/RS2032R-sim,SIM-D1"
    assert host.ask(b"RG") == b"RG,74.0000,0.0190"


def test_measurement_quantised_to_the_resolution(rig: VirtualRig, host: Host) -> None:
    assert host.ask(b"MS") == b"MS,+0000.0000"
    displace(rig, 12.345e-6)
    d_um = rig.state.d1_m * 1e6
    expected = round(d_um / 0.019) * 0.019
    reply = host.ask(b"MS")
    assert reply == f"MS,{expected:+010.4f}".encode()
    assert abs(float(reply[3:]) - d_um) <= 0.0095 + 1e-9


def test_over_range_beyond_37_um_of_the_zero_then_zero(rig: VirtualRig, host: Host) -> None:
    displace(rig, 36.0e-6)
    assert host.ask(b"MS") != b"MS,+OVER"
    displace(rig, 2.0e-6)  # 38 um: beyond +-37 um
    assert host.ask(b"MS") == b"MS,+OVER"
    assert host.ask(b"ZR") == b"ZR"
    assert host.ask(b"MS") == b"MS,+0000.0000"
    displace(rig, -40.0e-6)
    assert host.ask(b"MS") == b"MS,-OVER"


def test_errors(host: Host) -> None:
    assert host.ask(b"XX") == b"ER,XX,01"
    assert host.ask(b"MS,1") == b"ER,MS,02"
    assert host.ask(b"ST,abc") == b"ER,ST,02"
    assert host.ask(b"ST,5000") == b"ER,ST,02"  # above the rig's sample rate


def test_stream_follows_the_rig_clock(rig: VirtualRig, host: Host) -> None:
    assert host.ask(b"ST,512") == b"ST"
    assert host.ask(b"MS") == b"ER,MS,03"  # one measurement at a time: busy while streaming
    rig.advance_by(0.25)
    lines = [host.line() for _ in range(128)]
    assert [ln.split(b",")[1] for ln in lines] == [str(i).encode() for i in range(128)]
    assert all(ln.startswith(b"D,") and ln.endswith(b"+0000.0000") for ln in lines)
    with pytest.raises(TimeoutError):  # the rig has not reached sample 128 yet
        host.line(0.1)
    assert host.ask(b"SP") == b"SP"


def test_line_faults(rig: VirtualRig) -> None:
    with ProbeSim(rig, 1) as sim:
        h = Host(sim.path)
        try:
            full = h.ask(b"ID")
            assert full == b"ID,MTI-2100/RS2032R-sim,SIM-D2"
            sim.faults.short_pct = 100.0
            assert h.ask(b"ID") == full[: len(full) // 2]  # cut before its end, CR still sent
            sim.faults.short_pct = 0.0
            sim.faults.corrupt_pct = 100.0
            assert any(b >= 0x80 for b in h.ask(b"ID"))  # unreadable bytes
            sim.faults.corrupt_pct = 0.0
            sim.faults.silent = True
            with pytest.raises(TimeoutError):
                h.ask(b"ID", timeout_s=0.2)
            sim.faults.silent = False
            assert h.ask(b"RG") == b"RG,74.0000,0.0190"
        finally:
            h.close()
