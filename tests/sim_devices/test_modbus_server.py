"""The stage controller simulator at register level (docs/protocols.md), with a raw pymodbus client."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from pymodbus.client import ModbusTcpClient

from drivers.modbus_codec import ControlBit, StatusBit, int32_to_words, words_to_int32
from sim_devices.modbus_stage_server import (
    NORMAL_WIRE,
    TANGENTIAL_WIRE,
    ModbusStageServer,
    StageWireConfig,
)
from sim_devices.virtual_rig import VirtualRig, VirtualRigConfig

UNIT = 1


@pytest.fixture
def rig() -> VirtualRig:
    return VirtualRig()  # manual clock: the test advances time


def connect(port: int) -> ModbusTcpClient:
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=0.5, retries=0)
    assert client.connect()
    return client


@pytest.fixture
def client(rig: VirtualRig) -> Iterator[ModbusTcpClient]:
    with ModbusStageServer(rig.tangential, TANGENTIAL_WIRE) as server:
        c = connect(server.port)
        yield c
        c.close()


def regs(c: ModbusTcpClient) -> list[int]:
    return list(c.read_holding_registers(0, count=9, device_id=UNIT).registers)


def command(c: ModbusTcpClient, bit: ControlBit) -> None:
    assert not c.write_register(0, int(bit), device_id=UNIT).isError()


def start_move(c: ModbusTcpClient, target_counts: int, velocity_nm_s: int) -> None:
    words = int32_to_words(target_counts, "high_first") + int32_to_words(velocity_nm_s, "high_first")
    assert not c.write_registers(2, words, device_id=UNIT).isError()
    command(c, ControlBit.START)


def test_binds_to_loopback_on_an_os_chosen_port(rig: VirtualRig) -> None:
    with ModbusStageServer(rig.tangential, TANGENTIAL_WIRE) as a, \
            ModbusStageServer(rig.normal, NORMAL_WIRE) as b:
        assert a.host == "127.0.0.1" and a.port != b.port and a.port > 0


def test_enable_move_and_the_control_bits_clear(rig: VirtualRig, client: ModbusTcpClient) -> None:
    r = regs(client)
    assert r[0] == 0 and not r[1] & StatusBit.ENABLED
    assert words_to_int32(r[6:8], "high_first") == 312_500  # 100 mm at 0.32 um per count
    command(client, ControlBit.ENABLE)
    start_move(client, 312_500 + 3125, 1_000_000)  # +1 mm at 1 mm/s
    r = regs(client)
    assert r[0] == 0  # one-shot bits are cleared once acted on
    assert r[1] & StatusBit.ENABLED and r[1] & StatusBit.MOVING and not r[1] & StatusBit.IN_POSITION
    rig.advance_to(0.6)
    mid = words_to_int32(regs(client)[6:8], "high_first")
    assert 312_500 < mid < 312_500 + 3125
    rig.advance_to(1.5)
    r = regs(client)
    assert words_to_int32(r[6:8], "high_first") == 312_500 + 3125
    assert r[1] & StatusBit.IN_POSITION and not r[1] & StatusBit.MOVING and r[8] == 0


def test_target_beyond_travel_raises_alarm_1_and_nothing_moves(
    rig: VirtualRig, client: ModbusTcpClient
) -> None:
    command(client, ControlBit.ENABLE)
    start_move(client, 625_001, 1_000_000)  # 200.0003 mm: beyond the 200 mm stroke
    rig.advance_to(1.0)
    r = regs(client)
    assert r[8] == 1 and r[1] & StatusBit.FAULT and not r[1] & StatusBit.MOVING
    assert words_to_int32(r[6:8], "high_first") == 312_500
    start_move(client, 312_600, 1_000_000)  # refused while the alarm is latched
    rig.advance_to(2.0)
    assert words_to_int32(regs(client)[6:8], "high_first") == 312_500
    command(client, ControlBit.RESET_ALARM)
    assert regs(client)[8] == 0


def test_move_without_enable_and_bad_velocity_raise_alarm_4(
    rig: VirtualRig, client: ModbusTcpClient
) -> None:
    start_move(client, 312_600, 1_000_000)
    assert regs(client)[8] == 4
    command(client, ControlBit.RESET_ALARM)
    command(client, ControlBit.ENABLE)
    start_move(client, 312_600, 0)
    assert regs(client)[8] == 4


def test_emergency_stop_halts_at_once_and_latches_alarm_5(
    rig: VirtualRig, client: ModbusTcpClient
) -> None:
    command(client, ControlBit.ENABLE)
    start_move(client, 312_500 + 31_250, 5_000_000)
    rig.advance_to(1.0)
    command(client, ControlBit.EMERGENCY_STOP)
    here = words_to_int32(regs(client)[6:8], "high_first")
    rig.advance_to(2.0)
    r = regs(client)
    assert words_to_int32(r[6:8], "high_first") == here and r[8] == 5
    assert not r[1] & StatusBit.MOVING


def test_home_sets_homed_when_the_switch_is_reached(rig: VirtualRig) -> None:
    with ModbusStageServer(rig.normal, NORMAL_WIRE) as server:
        c = connect(server.port)
        try:
            command(c, ControlBit.ENABLE)
            command(c, ControlBit.HOME)
            assert regs(c)[1] & StatusBit.MOVING and not regs(c)[1] & StatusBit.HOMED
            rig.advance_to(21.0)  # 19.5 mm at the 1 mm/s homing velocity
            r = regs(c)
            assert r[1] & StatusBit.HOMED and r[1] & StatusBit.LIMIT
            assert words_to_int32(r[6:8], "high_first") == 0
        finally:
            c.close()


def test_over_load_of_the_normal_stage_raises_alarm_3() -> None:
    rig = VirtualRig(config=VirtualRigConfig(max_load_N=300.0))
    with ModbusStageServer(rig.normal, NORMAL_WIRE) as server:
        c = connect(server.port)
        try:
            command(c, ControlBit.ENABLE)
            target = round((rig.config.contact.z_contact_m + 100e-6) * NORMAL_WIRE.counts_per_m)
            words = int32_to_words(target, "high_first") + int32_to_words(200_000, "high_first")
            c.write_registers(2, words, device_id=UNIT)
            command(c, ControlBit.START)
            rig.advance_to(5.0)
            assert regs(c)[8] == 3 and rig.state.fn_N <= 300.0
        finally:
            c.close()


def test_low_word_first_and_read_only_registers(rig: VirtualRig) -> None:
    wire = StageWireConfig(counts_per_m=TANGENTIAL_WIRE.counts_per_m, word_order="low_first")
    with ModbusStageServer(rig.tangential, wire) as server:
        c = connect(server.port)
        try:
            r = regs(c)
            assert words_to_int32(r[6:8], "low_first") == 312_500
            assert r[6:8] == int32_to_words(312_500, "low_first")
            assert c.write_register(1, 0xFFFF, device_id=UNIT).isError()  # status is read-only
            assert c.write_register(6, 1, device_id=UNIT).isError()  # so is the actual position
        finally:
            c.close()
