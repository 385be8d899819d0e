"""A stage controller on Modbus TCP (pymodbus 3.16), speaking the register map of docs/protocols.md.

The real :mod:`drivers.modbus_stage` driver talks to it unchanged. Registers are computed on read from
the virtual rig's stage (``SimDevice(action=...)``: status, actual position and alarm code come from
the axis at the rig's current time), and control bits act on that stage when written: enable,
start move to target, home, stop (decelerate), reset alarm, emergency stop, disable. Each control bit
is a one-shot command: the device clears it once acted on. A target outside the travel latches
alarm 1 (over-travel) and nothing moves; a velocity outside (0, max] or a move while disabled latches
alarm 4 (driver fault); an over-load of the normal stage latches alarm 3 (see ``virtual_rig.py``).

The server binds to 127.0.0.1 only (port 0 = chosen by the OS) and runs its asyncio loop in its
own thread. Faults (see :mod:`sim_devices.faults`): ``silent`` (requests are not acted on and no
reply leaves: the client times out), ``corrupt_pct`` (the reply's function code is garbled: the
client cannot decode it), ``short_pct`` (the reply is cut in half: the client never gets a whole
frame), ``stuck`` (status / position / alarm registers freeze), ``alarm_code`` (latched on the stage
at the next request).
"""

from __future__ import annotations

import asyncio
import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Self

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers.modbus_codec import (
    ControlBit,
    RegisterMap,
    WordOrder,
    encode_status,
    int32_to_words,
    words_to_int32,
)
from drivers.modbus_stage import NORMAL_COUNTS_PER_M, TANGENTIAL_COUNTS_PER_M, VELOCITY_COUNTS_PER_M_S
from drivers.validate import check_integer, check_number
from sim_devices.faults import Faults, StuckReading
from sim_devices.service import SimService
from sim_devices.stage_axis import Alarm
from sim_devices.virtual_rig import StageControl

_log = logging.getLogger(__name__)

LOOPBACK = "127.0.0.1"  # the simulators listen on this host only, never on the network
_GARBLED_FUNCTION_CODE = 0x42  # not a Modbus function code: the client cannot decode the reply


@dataclass(frozen=True)
class StageWireConfig:
    """Scales and layout of one controller's registers (docs/protocols.md defaults)."""

    counts_per_m: float
    velocity_counts_per_m_s: float = VELOCITY_COUNTS_PER_M_S
    word_order: WordOrder = "high_first"
    device_id: int = 1
    registers: RegisterMap = field(default_factory=RegisterMap)

    def __post_init__(self) -> None:
        owner = "stage wire"
        check_number(owner, "counts_per_m", self.counts_per_m, unit="counts/m", gt=0.0)
        check_number(owner, "velocity_counts_per_m_s", self.velocity_counts_per_m_s,
                     unit="counts/(m/s)", gt=0.0)
        check_integer(owner, "device_id", self.device_id, 1, 247)


TANGENTIAL_WIRE = StageWireConfig(counts_per_m=TANGENTIAL_COUNTS_PER_M)
"""0.32 um per count: the driver's scale (docs/protocols.md)."""
NORMAL_WIRE = StageWireConfig(counts_per_m=NORMAL_COUNTS_PER_M)
"""0.6 um per count: the driver's scale (docs/protocols.md)."""


class ModbusStageServer(SimService):
    """One simulated stage controller behind a Modbus TCP server on 127.0.0.1."""

    def __init__(
        self,
        stage: StageControl,
        wire: StageWireConfig,
        *,
        port: int = 0,
        faults: Faults | None = None,
    ) -> None:
        super().__init__(f"modbus-{stage.name}")
        self.stage = stage
        self.wire = wire
        self.faults = faults if faults is not None else Faults()
        self._requested_port = port
        self._port: int | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._ready = threading.Event()
        self._start_error: BaseException | None = None
        self._stuck: StuckReading[dict[int, int]] = StuckReading(self.faults)
        regs = wire.registers
        self._addr_lo = min(regs.control, regs.status, regs.target_position, regs.velocity,
                            regs.actual_position, regs.alarm_code)

    # ---------------------------------------------------------------------------- lifecycle
    @property
    def host(self) -> str:
        return LOOPBACK

    @property
    def port(self) -> int:
        if self._port is None:
            raise RuntimeError("server not started")
        return self._port

    def start(self, timeout_s: float = 5.0) -> Self:
        """Serve on 127.0.0.1 (the port is known on return); a second call does nothing."""
        if self._started:
            return self
        super().start()
        if not self._ready.wait(timeout_s):
            raise RuntimeError(f"Modbus server for {self.stage.name} did not start")
        if self._start_error is not None:
            raise RuntimeError(f"Modbus server for {self.stage.name} failed: {self._start_error}")
        return self

    def _loops(self) -> list[tuple[Callable[[], None], str]]:
        return [(self._serve, "serve")]

    def _wake(self) -> None:
        loop = self._loop
        if loop is not None and loop.is_running():
            asyncio.run_coroutine_threadsafe(self._shutdown(), loop)

    def _close(self) -> None:
        self._loop = None

    def _serve(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._main())
        except BaseException as exc:
            self._start_error = exc
            self._ready.set()
        finally:
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _main(self) -> None:
        self._server = ModbusTcpServer(
            self._device(),
            address=(LOOPBACK, self._requested_port),
            trace_packet=self._trace_packet,
        )
        await self._server.serve_forever(background=True)
        sockets = getattr(self._server.transport, "sockets", None)
        if not sockets:
            raise RuntimeError("pymodbus did not expose the listening socket")
        self._port = int(sockets[0].getsockname()[1])
        self._ready.set()
        await self._server.serving

    async def _shutdown(self) -> None:
        if self._server is not None:
            await self._server.shutdown()

    # ----------------------------------------------------------------------------- registers
    def _device(self) -> SimDevice:
        r = self.wire.registers
        simdata = [
            SimData(r.control, values=0, datatype=DataType.REGISTERS),
            SimData(r.status, values=0, datatype=DataType.REGISTERS, readonly=True),
            SimData(r.target_position, count=2, values=0, datatype=DataType.REGISTERS),
            SimData(r.velocity, count=2, values=0, datatype=DataType.REGISTERS),
            SimData(r.actual_position, count=2, values=0, datatype=DataType.REGISTERS,
                    readonly=True),
            SimData(r.alarm_code, values=0, datatype=DataType.REGISTERS, readonly=True),
        ]
        return SimDevice(id=self.wire.device_id, simdata=simdata, action=self._action)

    def _live_registers(self) -> dict[int, int]:
        """The read-only registers from the rig's stage now (or frozen while ``stuck``)."""
        st = self.stage.status()
        r, w = self.wire.registers, self.wire
        counts = round(st.position_m * w.counts_per_m)
        pos = int32_to_words(counts, w.word_order, device=self.stage.name)
        regs = {
            r.status: encode_status(st.stage_status()),
            r.actual_position: pos[0],
            r.actual_position + 1: pos[1],
            r.alarm_code: int(st.alarm),
        }
        return self._stuck.hold(regs)

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        """pymodbus hook: runs before a read is answered or a write is stored."""
        if self.faults.silent:  # a dead controller acts on nothing; its reply is swallowed too
            return ExcCodes.DEVICE_FAILURE
        try:
            code = self.faults.take_alarm()
            if code:
                self.stage.raise_alarm(Alarm(code) if code in Alarm._value2member_map_ else
                                       Alarm.DRIVER_FAULT)
            if set_values is None:
                for addr, value in self._live_registers().items():
                    registers[addr - start_address] = value
                return None
            values = [int(v) for v in set_values]
            image = list(registers)
            image[address - start_address : address - start_address + len(values)] = values
            ctrl = self.wire.registers.control
            if address <= ctrl < address + len(values):
                self._act(values[ctrl - address], image, start_address)
                cleared: list[int] = set_values  # type: ignore[assignment]  # registers, not coils
                cleared[ctrl - address] = 0  # one-shot: the device clears its control bits
            return None
        except Exception:  # a bug here must not kill the server loop; the client sees a failure
            _log.exception("simulated stage %s failed on a request", self.stage.name)
            return ExcCodes.DEVICE_FAILURE

    def _act(self, bits: int, image: list[int], base: int) -> None:
        """Apply control bits in safety order: stop first, start last."""
        s, r, w = self.stage, self.wire.registers, self.wire
        if bits & ControlBit.EMERGENCY_STOP:
            s.emergency_stop()
            return
        if bits & ControlBit.STOP:
            s.stop()
        if bits & ControlBit.DISABLE:
            s.enable(False)
        if bits & ControlBit.RESET_ALARM:
            s.reset_alarm()
        if bits & ControlBit.ENABLE:
            s.enable(True)
        if bits & ControlBit.HOME:
            s.home()
        if bits & ControlBit.START:
            t_off, v_off = r.target_position - base, r.velocity - base
            target = words_to_int32(image[t_off : t_off + 2], w.word_order, device=s.name)
            velocity = words_to_int32(image[v_off : v_off + 2], w.word_order, device=s.name)
            target_m = target / w.counts_per_m
            velocity_m_s = velocity / w.velocity_counts_per_m_s
            if not math.isfinite(target_m):
                s.raise_alarm(Alarm.OVER_TRAVEL)
                return
            s.move_to(target_m, velocity_m_s)

    # ---------------------------------------------------------------------------------- wire
    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        """pymodbus hook on every packet in (sending False) and out (True): wire faults."""
        f = self.faults
        if not sending or len(data) < 8:
            return data
        if f.silent:
            return b""  # nothing goes out (the request was refused by _action)
        if f.roll(f.short_pct):
            return data[: len(data) // 2]
        if f.roll(f.corrupt_pct):
            return data[:7] + bytes([_GARBLED_FUNCTION_CODE]) + data[8:]
        return data
