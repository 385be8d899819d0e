"""The probes' motorised mounts: a move shifts the readings by exactly the move from its rig time
on (samples read late keep the mount where it was), is refused beyond the travel, and works through
both backends' drivers (in process, and ``MV`` over the pty)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import LimitError, NotSupportedError
from sim_devices.backends import SimRig, open_sim_rig
from sim_devices.inprocess import InProcessProbe
from sim_devices.probe_sim import ProbeSim
from sim_devices.sensors import ProbeHead, ProbeSpec
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig
from tests.sim_devices.test_probe_sim import Host, displace

QUIET = (ProbeSpec(serial="SIM-D1", noise_rms_m=0.0), ProbeSpec(serial="SIM-D2", noise_rms_m=0.0))


def test_a_mount_move_brings_an_over_range_target_back() -> None:
    rig = VirtualRig(config=VirtualRigConfig(probes=QUIET))
    probe = InProcessProbe(rig, 0)
    probe.zero()
    displace(rig, 50e-6)  # the driven specimen 50 um on: beyond +37 um
    assert not np.isfinite(rig.probes[0].readings_m(rig.probe_ideal_m(0)))[0]
    probe.move_mount(40e-6)
    assert probe.mount_m == pytest.approx(40e-6)
    assert probe.read_m() == pytest.approx(rig.state.d1_m - 40e-6, abs=0.01e-6)
    probe.zero()  # zeroing after a move: the reading is 0 at the new place
    assert probe.read_m() == pytest.approx(0.0, abs=0.01e-6)


def test_samples_before_the_move_keep_the_old_mount_when_read_late() -> None:
    head = ProbeHead(ProbeSpec(noise_rms_m=0.0, mount_speed_m_s=1e-3))
    assert head.move_mount(20e-6, after_t_s=1.0) == pytest.approx(1.02)  # 20 um at 1 mm/s
    t = np.array([0.5, 1.0, 1.01, 1.02, 2.0])
    got = head.readings_m(np.full(5, 30e-6), t)
    np.testing.assert_allclose(got, [30e-6, 30e-6, 20e-6, 10e-6, 10e-6], atol=0.02e-6)
    np.testing.assert_allclose(head.analog_V(np.full(5, 30e-6), 7.4e-6, t) * 7.4e-6, got)


def test_the_mount_moves_at_its_speed_and_a_move_made_while_moving_follows_it() -> None:
    head = ProbeHead(ProbeSpec(noise_rms_m=0.0, mount_speed_m_s=0.5e-3))
    assert head.move_mount(10e-6, after_t_s=1.0) == pytest.approx(1.02)
    assert head.move_mount(-5e-6, after_t_s=1.01) == pytest.approx(1.03)  # queued after the first
    t = np.array([1.0, 1.005, 1.02, 1.025, 1.03, 5.0])
    got = head.readings_m(np.zeros(6), t)
    np.testing.assert_allclose(got, [0.0, -2.5e-6, -10e-6, -7.5e-6, -5e-6, -5e-6], atol=0.02e-6)
    assert head.mount_m == pytest.approx(5e-6)


def test_a_move_beyond_the_travel_is_refused_and_nothing_moves() -> None:
    spec = ProbeSpec(mount_travel_m=100e-6, noise_rms_m=0.0)
    rig = VirtualRig(config=VirtualRigConfig(probes=(spec, spec)))
    probe = InProcessProbe(rig, 0)
    probe.move_mount(40e-6)
    with pytest.raises(LimitError, match="mount_m"):
        probe.move_mount(20e-6)  # to 60 um: beyond +-50 um
    assert probe.mount_m == pytest.approx(40e-6)
    assert rig.probes[0].mount_m == pytest.approx(40e-6)


def test_a_manual_mount_is_refused() -> None:
    manual = ProbeSpec(mount_travel_m=0.0)
    rig = VirtualRig(config=VirtualRigConfig(probes=(manual, manual)))
    with pytest.raises(NotSupportedError, match="manual"):
        InProcessProbe(rig, 0).move_mount(1e-6)


def test_mv_over_the_pty() -> None:
    rig = VirtualRig(config=VirtualRigConfig(probes=QUIET))
    with ProbeSim(rig, 0) as sim:
        host = Host(sim.path)
        try:
            displace(rig, 20e-6)
            before = float(host.ask(b"MS")[3:])
            assert host.ask(b"MV,+0015.0000") == b"MV"
            assert float(host.ask(b"MS")[3:]) == pytest.approx(before - 15.0, abs=0.02)
            assert host.ask(b"MV,+99999.0000") == b"ER,MV,02"  # beyond the 25 mm travel
            assert host.ask(b"MV,abc") == b"ER,MV,02"
        finally:
            host.close()


@pytest.mark.parametrize("backend", ["sim", "sim-wire"])
def test_both_backends_move_the_mount_and_the_daq_sees_it(backend: str) -> None:
    with open_sim_rig(backend, speed=None) as sim:
        assert isinstance(sim, SimRig)
        d1 = sim.devices.d1
        assert d1.mount_travel_m > 0
        assert d1.mount_speed_m_s == sim.rig.probes[0].spec.mount_speed_m_s
        rig = sim.rig
        displace(rig, 30e-6)
        before = d1.read_m()
        d1.move_mount(25e-6)
        rig.advance_by(0.05)
        assert d1.read_m() == pytest.approx(before - 25e-6, abs=0.05e-6)
        head = rig.probes[0]
        s = rig.samples(rig.k - 10, rig.k)
        volts = head.analog_V(s.d1_m, 7.4e-6, s.t_s)
        assert float(np.median(volts)) * 7.4e-6 == pytest.approx(before - 25e-6, abs=0.05e-6)
