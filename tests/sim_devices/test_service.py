"""Shared plumbing of the simulated devices: the service base, the stuck fault, status, scales."""

from __future__ import annotations

import threading

import numpy as np

from drivers.modbus_codec import decode_status, encode_status
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    TANGENTIAL_COUNTS_PER_M,
    VELOCITY_COUNTS_PER_M_S,
    StageConfig,
)
from sim_devices.can_daq_sim import CanDaqSim
from sim_devices.faults import Faults, StuckReading
from sim_devices.modbus_stage_server import NORMAL_WIRE, TANGENTIAL_WIRE, ModbusStageServer
from sim_devices.probe_sim import ProbeSim
from sim_devices.service import SimService
from sim_devices.stage_axis import Alarm, AxisStatus
from sim_devices.virtual_rig import VirtualRig


class Ticker(SimService):
    def __init__(self) -> None:
        super().__init__("ticker")
        self.events: list[str] = []
        self.ticks = 0
        self.woken = threading.Event()

    def _open(self) -> None:
        self.events.append("open")

    def _loops(self):  # type: ignore[no-untyped-def]
        return [(self._tick, "a"), (self._tick, "b")]

    def _tick(self) -> None:
        while self.running:
            self.ticks += 1
            self.woken.wait(0.01)

    def _wake(self) -> None:
        self.events.append("wake")
        self.woken.set()

    def _close(self) -> None:
        self.events.append("close")


def test_service_lifecycle() -> None:
    t = Ticker()
    assert not t.running
    t.stop()  # before start: nothing to do
    assert t.events == []
    with t as same:
        assert same is t and t.running
        assert t.start() is t  # a second start does nothing
        names = sorted(th.name for th in t._threads)
        assert names == ["ticker-a", "ticker-b"]
        threads = list(t._threads)
    assert not t.running and t.events == ["open", "wake", "close"]
    assert not any(th.is_alive() for th in threads)
    t.stop()
    assert t.events == ["open", "wake", "close"]
    t.start()  # restartable
    t.stop()
    assert t.events == ["open", "wake", "close"] * 2


def test_every_simulated_server_is_a_service() -> None:
    for cls in (ModbusStageServer, CanDaqSim, ProbeSim, VirtualRig):
        assert issubclass(cls, SimService)
        for name in ("start", "stop", "__enter__", "__exit__"):
            assert name not in vars(cls) or name == "start", (cls, name)


def test_virtual_rig_clock_thread_starts_and_stops() -> None:
    with VirtualRig(speed=1.0) as rig:
        assert rig.running and [th.name for th in rig._threads] == ["virtual-rig-clock"]
        thread = rig._threads[0]
    assert not thread.is_alive() and not rig.running
    manual = VirtualRig(speed=None).start()
    assert manual._threads == []
    manual.close()


def test_stuck_reading() -> None:
    faults = Faults()
    stuck: StuckReading[int] = StuckReading(faults)
    assert stuck.hold(1) == 1
    faults.stuck = True
    assert [stuck.hold(v) for v in (2, 3, 4)] == [2, 2, 2]
    np.testing.assert_array_equal(stuck.hold_array(np.array([5.0, 6.0])), [2.0, 2.0])
    faults.stuck = False
    assert stuck.hold(7) == 7
    faults.stuck = True
    np.testing.assert_array_equal(stuck.hold_array(np.array([8.0, 9.0])), [8.0, 8.0])


def test_axis_status_converts_once_for_wire_and_in_process() -> None:
    for alarm in Alarm:
        for bits in range(64):
            flags = [bool(bits >> i & 1) for i in range(6)]
            st = AxisStatus(0.0, 0.01, 0.0, 0.01, *flags, alarm)
            status = st.stage_status()
            assert decode_status(encode_status(status), int(alarm)) == status


def test_wire_scales_are_the_drivers() -> None:
    assert TANGENTIAL_WIRE.counts_per_m == TANGENTIAL_COUNTS_PER_M
    assert NORMAL_WIRE.counts_per_m == NORMAL_COUNTS_PER_M
    for wire in (TANGENTIAL_WIRE, NORMAL_WIRE):
        assert wire.velocity_counts_per_m_s == VELOCITY_COUNTS_PER_M_S
    assert StageConfig.__dataclass_fields__["velocity_counts_per_m_s"].default == VELOCITY_COUNTS_PER_M_S
