"""ModbusStage: the exact register conversation for each call, limits, timeouts, reconnects."""

from __future__ import annotations

import struct
import threading
import time
from collections.abc import Iterator

import pytest

from drivers.errors import (
    DeviceStateError,
    DeviceTimeout,
    EmergencyStopActive,
    ForceLimitError,
    InvalidValueError,
    LimitError,
    MotionTimeout,
    ProtocolError,
    StageAlarm,
)
from drivers.modbus_codec import ControlBit, RegisterMap, StatusBit
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    NORMAL_LIMITS,
    TANGENTIAL_COUNTS_PER_M,
    TANGENTIAL_LIMITS,
    ModbusStage,
    StageConfig,
)
from drivers.safety import EmergencyStop, ForceGuard

from .drv_modbus_peer import ModbusPeer
from .drv_pty_peer import RtuPeer

READY = int(StatusBit.ENABLED | StatusBit.IN_POSITION | StatusBit.HOMED)


def tangential(peer: ModbusPeer, estop: EmergencyStop, **overrides: object) -> ModbusStage:
    kwargs: dict[str, object] = {"limits": TANGENTIAL_LIMITS, "port": peer.port, **overrides}
    config = StageConfig("tangential", counts_per_m=TANGENTIAL_COUNTS_PER_M, **kwargs)  # type: ignore[arg-type]
    return ModbusStage(config, emergency_stop=estop)


@pytest.fixture
def stage(peer: ModbusPeer, estop: EmergencyStop) -> Iterator[ModbusStage]:
    peer.registers[1] = READY
    with tangential(peer, estop) as s:
        yield s


def fc06(address: int, value: int) -> tuple[int, bytes]:
    return 6, struct.pack(">HH", address, value)


def fc16(address: int, words: list[int]) -> tuple[int, bytes]:
    return 16, struct.pack(f">HHB{len(words)}H", address, len(words), 2 * len(words), *words)


# conversations ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("call", "bit"),
    [
        ("enable", ControlBit.ENABLE),
        ("disable", ControlBit.DISABLE),
        ("stop", ControlBit.STOP),
        ("emergency_stop", ControlBit.EMERGENCY_STOP),
        ("reset_alarm", ControlBit.RESET_ALARM),
    ],
)
def test_single_bit_commands_write_one_control_word(
    stage: ModbusStage, peer: ModbusPeer, call: str, bit: ControlBit
) -> None:
    getattr(stage, call)()
    assert peer.writes() == [fc06(0, int(bit))]
    assert all(r.unit == 1 for r in peer.requests)


def test_home_reads_status_then_writes_home_bit(stage: ModbusStage, peer: ModbusPeer) -> None:
    stage.home()
    assert [(r.function, r.data) for r in peer.requests] == [
        (3, struct.pack(">HH", 1, 8)),
        fc06(0, int(ControlBit.HOME)),
    ]


def test_move_absolute_conversation_high_word_first(stage: ModbusStage, peer: ModbusPeer) -> None:
    stage.move_absolute(0.1, 1.3e-6)
    # 0.1 m * 3,125,000 counts/m = 312,500 = 0x0004_C4B4; 1.3 um/s = 1300 nm/s = 0x0514
    assert [(r.function, r.data) for r in peer.requests] == [
        (3, struct.pack(">HH", 1, 8)),
        fc16(2, [0x0004, 0xC4B4, 0x0000, 0x0514]),
        fc06(0, int(ControlBit.START)),
    ]


def test_move_low_word_first_and_negative_target(peer: ModbusPeer, estop: EmergencyStop) -> None:
    peer.registers[1] = READY
    limits = TANGENTIAL_LIMITS.__class__(-0.01, 0.01, 1e-3)
    with tangential(peer, estop, word_order="low_first", limits=limits) as stage:
        stage.move_absolute(-0.001, 1e-5)
    counts = -3125 & 0xFFFFFFFF  # -0.001 m -> -3125 counts
    assert peer.writes()[0] == fc16(2, [counts & 0xFFFF, counts >> 16, 10000, 0])


def test_split_target_and_velocity_registers(peer: ModbusPeer, estop: EmergencyStop) -> None:
    peer.registers[1] = READY
    regs = RegisterMap(target_position=10, velocity=4)
    with tangential(peer, estop, registers=regs) as stage:
        stage.move_absolute(0.0, 1e-6)
    assert peer.writes() == [fc16(10, [0, 0]), fc16(4, [0, 1000]), fc06(0, 2)]


def test_device_id_and_position_decoding(peer: ModbusPeer, estop: EmergencyStop) -> None:
    peer.set_int32(6, 41_667)  # normal stage, 0.6 um/count
    config = StageConfig(
        name="normal",
        limits=NORMAL_LIMITS,
        counts_per_m=NORMAL_COUNTS_PER_M,
        port=peer.port,
        device_id=3,
    )
    with ModbusStage(config, emergency_stop=estop) as stage:
        assert stage.position_m() == pytest.approx(41_667 / NORMAL_COUNTS_PER_M)
    assert peer.requests == [peer.requests[0]]
    assert peer.requests[0].unit == 3
    assert peer.requests[0].data == struct.pack(">HH", 6, 2)


def test_negative_position(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.set_int32(6, -312_500)
    assert stage.position_m() == pytest.approx(-0.1)


def test_status_bits_and_alarm_decoded(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.registers[1] = int(StatusBit.ENABLED | StatusBit.FAULT | StatusBit.LIMIT)
    peer.registers[8] = 1
    status = stage.status()
    assert (status.enabled, status.fault, status.limit, status.moving) == (True, True, True, False)
    assert status.alarm_code == 1
    assert status.alarm_name == "over-travel (limit)"


def test_move_refused_while_in_alarm(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.registers[1] = int(StatusBit.ENABLED | StatusBit.FAULT)
    peer.registers[8] = 3
    with pytest.raises(StageAlarm, match="over-load") as info:
        stage.move_absolute(0.05, 1e-5)
    assert info.value.alarm_code == 3
    assert peer.writes() == []


def test_move_refused_while_disabled(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.registers[1] = 0
    with pytest.raises(DeviceStateError, match="not enabled"):
        stage.move_absolute(0.05, 1e-5)
    assert peer.writes() == []


def test_wait_for_motion_polls_until_stopped(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.registers[1] = READY | int(StatusBit.MOVING)
    arrive = threading.Timer(0.1, lambda: peer.registers.__setitem__(1, READY))
    arrive.start()
    started = time.monotonic()
    try:
        status = stage.wait_for_motion(timeout_s=2.0, poll_interval_s=0.01)
    finally:
        arrive.join()
    assert not status.moving and status.in_position
    assert 0.08 < time.monotonic() - started < 1.0


def test_wait_for_motion_times_out_and_reports_alarms(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.registers[1] = READY | int(StatusBit.MOVING)
    with pytest.raises(MotionTimeout):
        stage.wait_for_motion(timeout_s=0.05, poll_interval_s=0.01)
    peer.registers[1] = int(StatusBit.ENABLED | StatusBit.FAULT)
    peer.registers[8] = 2
    with pytest.raises(StageAlarm, match="following error"):
        stage.wait_for_motion(timeout_s=1.0)


# limits: refused before anything is sent -------------------------------------------------------


@pytest.mark.parametrize(
    ("target_m", "velocity_m_s", "error", "words"),
    [
        (0.2001, 1e-5, LimitError, "target_m"),
        (-1e-6, 1e-5, LimitError, "below the minimum"),
        (0.1, 6e-3, LimitError, "velocity_m_s"),
        (float("nan"), 1e-5, InvalidValueError, "not finite"),
        (0.1, float("inf"), InvalidValueError, "not finite"),
        (0.1, 0.0, InvalidValueError, "> 0"),
        (0.1, -1e-5, InvalidValueError, "> 0"),
        (0.1, 1e-10, InvalidValueError, "resolution"),
        ("0.1", 1e-5, InvalidValueError, "not a real number"),
    ],
)
def test_bad_moves_refused_before_anything_is_sent(
    stage: ModbusStage,
    peer: ModbusPeer,
    target_m: float,
    velocity_m_s: float,
    error: type[Exception],
    words: str,
) -> None:
    with pytest.raises(error, match=words):
        stage.move_absolute(target_m, velocity_m_s)
    assert peer.requests == []


def test_limit_error_names_quantity_value_and_limit(stage: ModbusStage) -> None:
    with pytest.raises(LimitError) as info:
        stage.move_absolute(0.25, 1e-5)
    err = info.value
    assert (err.quantity, err.value, err.limit, err.unit) == ("target_m", 0.25, 0.2, "m")
    assert isinstance(err, ValueError)  # the CLI prints it as a one-line usage error
    assert "tangential" in str(err) and "0.25" in str(err) and "0.2 m" in str(err)


def test_relative_move_beyond_limit_refused_after_reading_position(
    stage: ModbusStage, peer: ModbusPeer
) -> None:
    peer.set_int32(6, 612_500)  # 0.196 m
    with pytest.raises(LimitError):
        stage.move_relative(0.005, 1e-5)
    assert peer.writes() == []
    stage.move_relative(0.003, 1e-5)
    assert peer.writes()[0] == fc16(2, [0x0009, 0x7D33, 0, 10_000])  # 621,875 counts


# timeouts, reconnects, corrupt replies ----------------------------------------------------------


def test_silent_device_times_out_within_one_second(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.mode = "silent"
    started = time.monotonic()
    with pytest.raises(DeviceTimeout, match=r"tangential did not answer within 0\.6 s"):
        stage.position_m()
    elapsed = time.monotonic() - started
    assert elapsed < 1.0
    assert len(peer.requests) == 2  # one retry


def test_refused_connection_is_a_timeout_quickly(estop: EmergencyStop) -> None:
    dead = ModbusPeer()
    port = dead.port
    dead.close()
    config = StageConfig("tangential", TANGENTIAL_LIMITS, TANGENTIAL_COUNTS_PER_M, port=port)
    with ModbusStage(config, emergency_stop=estop) as stage:
        started = time.monotonic()
        with pytest.raises(DeviceTimeout):
            stage.status()
        assert time.monotonic() - started < 1.0


def test_reconnects_once_after_a_dropped_connection(stage: ModbusStage, peer: ModbusPeer) -> None:
    stage.status()
    peer.drops_left = 1
    peer.set_int32(6, 3125)
    assert stage.position_m() == pytest.approx(0.001)
    assert peer.connections == 2


def test_connection_that_keeps_dropping_gives_timeout(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.mode = "drop"
    started = time.monotonic()
    with pytest.raises(DeviceTimeout):
        stage.status()
    assert time.monotonic() - started < 1.0


def test_garbage_reply_is_a_protocol_error_with_the_bytes(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.mode = "garbage"
    with pytest.raises(ProtocolError) as info:
        stage.status()
    assert b"garbage!" in info.value.data


def test_reply_from_the_wrong_unit_is_a_protocol_error(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.mode = "raw"
    # a well-formed answer for transaction 1, but from unit 9
    peer.raw_reply = struct.pack(">HHHB", 1, 0, 7, 9) + bytes([3, 4, 0, 0, 0, 0])
    with pytest.raises(ProtocolError):
        stage.position_m()


def test_modbus_exception_reply_is_a_protocol_error(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.mode = "exception"
    with pytest.raises(ProtocolError, match="illegal data address"):
        stage.enable()


# safety ---------------------------------------------------------------------------------------


def test_emergency_stop_from_another_thread_stops_every_stage(estop: EmergencyStop) -> None:
    peers = [ModbusPeer(), ModbusPeer()]
    try:
        for p in peers:
            p.registers[1] = READY
        stages = [tangential(p, estop) for p in peers]
        stages[0].move_absolute(0.1, 1e-5)
        worker = threading.Thread(target=estop.trigger, args=("operator pressed STOP",))
        worker.start()
        worker.join(timeout=2)
        for p in peers:
            assert p.writes()[-1] == fc06(0, int(ControlBit.EMERGENCY_STOP))
        sent = [len(p.requests) for p in peers]
        with pytest.raises(EmergencyStopActive, match="operator pressed STOP"):
            stages[1].move_absolute(0.1, 1e-5)
        with pytest.raises(EmergencyStopActive):
            stages[0].enable()
        assert [len(p.requests) for p in peers] == sent  # nothing sent while latched
        stages[1].stop()  # stopping is never refused
        estop.reset()
        stages[1].move_absolute(0.1, 1e-5)
        assert peers[1].writes()[-1] == fc06(0, int(ControlBit.START))
        for s in stages:
            s.close()
    finally:
        for p in peers:
            p.close()


def test_force_guard_stops_normal_stage_and_refuses_commands(peer: ModbusPeer, estop: EmergencyStop) -> None:
    peer.registers[1] = READY
    config = StageConfig("normal", NORMAL_LIMITS, NORMAL_COUNTS_PER_M, port=peer.port)
    with ModbusStage(config, emergency_stop=estop) as stage:
        guard = ForceGuard(stage, limit_N=800.0)
        assert guard.feed([299.0, 300.5, -310.0]) is None
        assert peer.writes() == []
        trip = guard.feed([300.0, 801.0, 900.0])
        assert isinstance(trip, ForceLimitError) and trip.force_N == 801.0
        assert peer.writes() == [fc06(0, int(ControlBit.EMERGENCY_STOP))]
        before = len(peer.requests)
        with pytest.raises(ForceLimitError, match="801 N exceeds 800 N"):
            stage.move_absolute(0.01, 1e-5)
        assert len(peer.requests) == before
        assert guard.feed([900.0]) is None  # already tripped: no second stop
        guard.reset()
        stage.move_absolute(0.01, 1e-5)
        assert peer.writes()[-1] == fc06(0, int(ControlBit.START))


def test_closed_stage_unregisters_and_refuses(stage: ModbusStage, estop: EmergencyStop) -> None:
    assert stage in estop.stages()
    stage.close()
    assert stage not in estop.stages()
    with pytest.raises(DeviceStateError):
        stage.position_m()


def test_concurrent_callers_share_one_connection_safely(stage: ModbusStage, peer: ModbusPeer) -> None:
    peer.set_int32(6, 3125)
    results: list[float] = []
    errors: list[BaseException] = []

    def poll() -> None:
        try:
            for _ in range(20):
                results.append(stage.position_m())
        except BaseException as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=poll) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(timeout=5)
    assert errors == []
    assert results == [pytest.approx(0.001)] * 80


def test_config_rejects_limits_that_overflow_int32() -> None:
    with pytest.raises(ValueError, match="INT32"):
        StageConfig("t", TANGENTIAL_LIMITS.__class__(0.0, 1000.0, 1e-3), TANGENTIAL_COUNTS_PER_M)
    with pytest.raises(ValueError, match="word_order"):
        StageConfig("t", TANGENTIAL_LIMITS, TANGENTIAL_COUNTS_PER_M, word_order="big")  # type: ignore[arg-type]


# RTU ------------------------------------------------------------------------------------------


def crc16_modbus(data: bytes) -> bytes:
    """CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF), low byte first on the wire."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return struct.pack("<H", crc)


def test_rtu_transport_exact_frames(estop: EmergencyStop) -> None:
    def answer(request: bytes) -> bytes:
        if request[1] == 6:  # a write-single is echoed
            return request
        reply = request[:1] + bytes([3, 4, 0x00, 0x00, 0x0C, 0x35])  # 3125 counts
        return reply + crc16_modbus(reply)

    peer = RtuPeer(answer)
    config = StageConfig(
        "tangential",
        TANGENTIAL_LIMITS,
        TANGENTIAL_COUNTS_PER_M,
        transport="rtu",
        serial_port=peer.path,
        device_id=2,
    )
    try:
        with ModbusStage(config, emergency_stop=estop) as stage:
            stage.enable()
            assert stage.position_m() == pytest.approx(0.001)
    finally:
        peer.close()
    enable = bytes([2, 6, 0, 0, 0, 1])
    read_position = bytes([2, 3, 0, 6, 0, 2])
    assert peer.requests == [enable + crc16_modbus(enable), read_position + crc16_modbus(read_position)]
