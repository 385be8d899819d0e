"""ModbusStage against a real pymodbus 3.16 server (SimDevice datastore with an action callback)."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Iterator
from typing import cast

import pytest
from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.errors import LimitError
from drivers.modbus_codec import ControlBit, StatusBit, int32_to_words, words_to_int32
from drivers.modbus_stage import (
    NORMAL_COUNTS_PER_M,
    NORMAL_LIMITS,
    ModbusStage,
    StageConfig,
)
from drivers.safety import EmergencyStop

from .contract import StageContract


class Controller:
    """A toy controller: START copies target into actual position; ENABLE/E-STOP set status."""

    def __init__(self) -> None:
        self.commands: list[int] = []

    async def action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        if function_code == 6 and address == 0 and set_values:
            bit = int(set_values[0])
            self.commands.append(bit)
            if bit == ControlBit.ENABLE:
                registers[1] = int(StatusBit.ENABLED | StatusBit.IN_POSITION)
            elif bit == ControlBit.START:
                registers[6:8] = registers[2:4]
            elif bit == ControlBit.EMERGENCY_STOP:
                registers[1] = int(StatusBit.FAULT)
                registers[8] = 5
            elif bit == ControlBit.RESET_ALARM:
                registers[1] &= ~int(StatusBit.FAULT)
                registers[8] = 0
            cast(list[int], set_values)[0] = 0  # the device clears control bits once acted on
        return None


class ServerThread:
    def __init__(self, device: SimDevice) -> None:
        self._device = device
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self.port = 0
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()
        assert self._ready.wait(5), "pymodbus server did not start"

    def _run(self) -> None:
        asyncio.set_event_loop(self._loop)
        self._loop.run_until_complete(self._start())
        self._ready.set()
        self._loop.run_forever()

    async def _start(self) -> None:
        self.server = ModbusTcpServer(self._device, address=("127.0.0.1", 0))
        await self.server.serve_forever(background=True)
        self.port = self.server.transport.sockets[0].getsockname()[1]  # type: ignore[attr-defined]

    def close(self) -> None:
        asyncio.run_coroutine_threadsafe(self.server.shutdown(), self._loop).result(5)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout=5)
        self._loop.close()


@pytest.fixture
def controller() -> Iterator[tuple[Controller, ServerThread]]:
    ctl = Controller()
    device = SimDevice(
        id=1,
        simdata=[SimData(0, count=16, values=0, datatype=DataType.REGISTERS)],
        action=ctl.action,
    )
    server = ServerThread(device)
    yield ctl, server
    server.close()


def test_enable_move_read_back_and_estop(controller: tuple[Controller, ServerThread]) -> None:
    ctl, server = controller
    config = StageConfig("normal", NORMAL_LIMITS, NORMAL_COUNTS_PER_M, port=server.port)
    with ModbusStage(config, emergency_stop=EmergencyStop()) as stage:
        assert not stage.status().enabled
        stage.enable()
        assert stage.status().enabled
        stage.move_absolute(0.012, 5e-6)
        assert stage.position_m() == pytest.approx(0.012, abs=0.6e-6)
        with pytest.raises(LimitError):
            stage.move_absolute(0.026, 5e-6)
        stage.emergency_stop()
        status = stage.status()
        assert status.fault and status.alarm_name == "emergency stop"
    assert ctl.commands == [ControlBit.ENABLE, ControlBit.START, ControlBit.EMERGENCY_STOP]


def test_codec_matches_pymodbus_int32_conversion() -> None:
    from pymodbus.client import ModbusTcpClient

    for value in (0, 1, -1, 312_500, -(2**31), 2**31 - 1):
        ours = int32_to_words(value, "high_first")
        theirs = ModbusTcpClient.convert_to_registers(value, ModbusTcpClient.DATATYPE.INT32)
        assert ours == theirs
        little = ModbusTcpClient.convert_to_registers(
            value, ModbusTcpClient.DATATYPE.INT32, word_order="little"
        )
        assert int32_to_words(value, "low_first") == little
        assert words_to_int32(ours, "high_first") == value


class TestModbusStageContract(StageContract):
    """The shared stage behaviour, through the real driver and a real pymodbus server."""

    position_tolerance_m = 0.6e-6  # one count of the normal stage

    @pytest.fixture
    def stage(
        self, controller: tuple[Controller, ServerThread], estop: EmergencyStop
    ) -> Iterator[ModbusStage]:
        _, server = controller
        config = StageConfig("normal", NORMAL_LIMITS, NORMAL_COUNTS_PER_M, port=server.port)
        with ModbusStage(config, emergency_stop=estop) as stage:
            yield stage
