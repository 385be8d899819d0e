"""A loading stage behind a Modbus (TCP or RTU) motion controller, over pymodbus 3.16 sync clients.

The register map, word order and scales are configuration (:class:`StageConfig`, defaults from
docs/protocols.md), so another controller with the same kind of map needs no code. Conversations:

* enable / disable / home / stop / reset alarm / emergency stop: FC06 write of one command bit to
  ``control``;
* move: FC16 write of ``target_position`` and ``velocity`` (one write if they are adjacent), then
  FC06 ``control = START``; the base class first reads the status (refusing a move while in alarm
  or disabled);
* position: FC03 read of ``actual_position`` (2 registers);
* status: one FC03 read spanning ``status``, ``actual_position`` and ``alarm_code``.

Timing: pymodbus waits ``timeout_s`` (0.3 s) per attempt and makes ``1 + retries`` (2) attempts,
so a silent controller gives :class:`DeviceTimeout` after about 0.6 s. On a lost connection the
driver closes and reconnects once, then raises :class:`DeviceTimeout`. Bytes that arrive but never
form a valid response give :class:`ProtocolError` with those bytes. One lock serialises all traffic,
so the stage can be used (and emergency-stopped) from several threads.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.client.base import ModbusBaseSyncClient
from pymodbus.exceptions import ConnectionException, ModbusIOException
from pymodbus.pdu import ModbusPDU

from drivers.errors import DeviceTimeout, InvalidValueError, ProtocolError
from drivers.interfaces import LoadingStage, StageLimits, StageStatus
from drivers.modbus_codec import (
    INT32_MAX,
    INT32_MIN,
    WORD_ORDERS,
    ControlBit,
    RegisterMap,
    WordOrder,
    decode_status,
    int32_to_words,
    words_to_int32,
)
from drivers.safety import EmergencyStop
from drivers.validate import check_integer, check_number, refused

TANGENTIAL_COUNTS_PER_M = 3_125_000.0
"""Tangential stage: 0.32 um per count (Han et al. 2022, Section 2.1; docs/protocols.md)."""
NORMAL_COUNTS_PER_M = 1_666_667.0
"""Normal stage: 0.6 um per count (Han et al. 2022, Section 2.1; docs/protocols.md)."""
VELOCITY_COUNTS_PER_M_S = 1e9
"""Velocity register scale of both controllers: nm/s (docs/protocols.md)."""

TANGENTIAL_LIMITS = StageLimits(min_position_m=0.0, max_position_m=0.200, max_velocity_m_s=5e-3)
"""Stroke 200 mm (Han et al. 2022); the speed limit is a choice (the experiments use about 1.3 um/s)."""
NORMAL_LIMITS = StageLimits(min_position_m=0.0, max_position_m=0.025, max_velocity_m_s=2e-3)
"""Stroke 25 mm (Han et al. 2022); the speed limit is a choice."""

MODBUS_EXCEPTION_NAMES: dict[int, str] = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target failed to respond",
}


@dataclass(frozen=True)
class StageConfig:
    """Everything a :class:`ModbusStage` needs; defaults follow docs/protocols.md."""

    name: str
    limits: StageLimits
    counts_per_m: float
    transport: Literal["tcp", "rtu"] = "tcp"
    host: str = "127.0.0.1"
    port: int = 502
    serial_port: str = ""
    baudrate: int = 115200
    parity: Literal["N", "E", "O"] = "N"
    stopbits: int = 1
    bytesize: int = 8
    device_id: int = 1
    word_order: WordOrder = "high_first"
    velocity_counts_per_m_s: float = VELOCITY_COUNTS_PER_M_S
    timeout_s: float = 0.3
    retries: int = 1
    registers: RegisterMap = field(default_factory=RegisterMap)

    def __post_init__(self) -> None:
        owner = f"stage {self.name!r}"

        if self.transport not in ("tcp", "rtu"):
            raise refused(owner, self, "transport", "must be 'tcp' or 'rtu'")
        if self.transport == "rtu" and not self.serial_port:
            raise refused(owner, self, "serial_port", "required for transport 'rtu'")
        if self.word_order not in WORD_ORDERS:
            raise refused(owner, self, "word_order", f"must be one of {WORD_ORDERS}")
        if self.parity not in ("N", "E", "O"):
            raise refused(owner, self, "parity", "must be 'N', 'E' or 'O'")
        for key, unit in (("counts_per_m", "counts/m"), ("velocity_counts_per_m_s", "counts/(m/s)"),
                          ("timeout_s", "s")):
            check_number(owner, key, getattr(self, key), unit=unit, gt=0.0)
        for key, low, high in (
            ("port", 0, 65535),
            ("device_id", 0, 247),
            ("retries", 0, 3),
            ("baudrate", 1, 10_000_000),
            ("stopbits", 1, 2),
            ("bytesize", 5, 8),
        ):
            check_integer(owner, key, getattr(self, key), low, high)
        if not isinstance(self.limits, StageLimits):
            raise refused(owner, self, "limits", "must be a StageLimits")
        if not isinstance(self.registers, RegisterMap):
            raise refused(owner, self, "registers", "must be a RegisterMap")
        for key in ("min_position_m", "max_position_m"):
            counts = getattr(self.limits, key) * self.counts_per_m
            if not INT32_MIN <= counts <= INT32_MAX:
                raise ValueError(f"stage {self.name!r}: limits.{key} does not fit in INT32 counts")
        if self.limits.max_velocity_m_s * self.velocity_counts_per_m_s > INT32_MAX:
            raise ValueError(f"stage {self.name!r}: limits.max_velocity_m_s overflows INT32")

    @property
    def poll_timeout_s(self) -> float:
        """Worst-case wait for one request on a silent device: ``timeout_s * (1 + retries)``."""
        return self.timeout_s * (1 + self.retries)


def make_client(config: StageConfig) -> ModbusBaseSyncClient:
    """A pymodbus sync client (TCP or RTU) with the config's short timeout and few retries."""
    if config.transport == "tcp":
        return ModbusTcpClient(
            config.host,
            port=config.port,
            timeout=config.timeout_s,
            retries=config.retries,
            reconnect_delay=0.0,
            name=config.name,
        )
    return ModbusSerialClient(
        config.serial_port,
        baudrate=config.baudrate,
        parity=config.parity,
        stopbits=config.stopbits,
        bytesize=config.bytesize,
        timeout=config.timeout_s,
        retries=config.retries,
        reconnect_delay=0.0,
        name=config.name,
    )


class ModbusStage(LoadingStage):
    """A :class:`LoadingStage` spoken to over Modbus holding registers."""

    def __init__(
        self,
        config: StageConfig,
        *,
        emergency_stop: EmergencyStop | None = None,
        client: ModbusBaseSyncClient | None = None,
    ) -> None:
        super().__init__(config.name, config.limits, emergency_stop=emergency_stop)
        self._config = config
        self._lock = threading.RLock()
        self._rx = bytearray()
        self._client = client if client is not None else make_client(config)
        self._client.transaction.trace_packet = self._trace_packet

    @property
    def config(self) -> StageConfig:
        """The configuration this stage was built from."""
        return self._config

    # unit conversions ---------------------------------------------------------------------------
    def position_counts(self, position_m: float) -> int:
        """Position [m] to controller counts, ``round(x * counts_per_m)``."""
        return round(position_m * self._config.counts_per_m)

    def velocity_counts(self, velocity_m_s: float) -> int:
        """Velocity [m/s] to controller counts, ``round(v * velocity_counts_per_m_s)``."""
        return round(velocity_m_s * self._config.velocity_counts_per_m_s)

    def check_move(self, target_m: float, velocity_m_s: float) -> tuple[float, float]:
        """The base checks, plus: the velocity must be at least one velocity count."""
        target, velocity = super().check_move(target_m, velocity_m_s)
        if self.velocity_counts(velocity) < 1:
            step = 1.0 / self._config.velocity_counts_per_m_s
            raise InvalidValueError(
                self.name, "velocity_m_s", velocity, f"below the resolution {step:.3g} m/s"
            )
        return target, velocity

    # hooks --------------------------------------------------------------------------------------
    def _do_enable(self) -> None:
        self._command(ControlBit.ENABLE)

    def _do_disable(self) -> None:
        self._command(ControlBit.DISABLE)

    def _do_home(self) -> None:
        self._command(ControlBit.HOME)

    def _do_stop(self) -> None:
        self._command(ControlBit.STOP)

    def _do_emergency_stop(self) -> None:
        self._command(ControlBit.EMERGENCY_STOP)

    def _do_reset_alarm(self) -> None:
        self._command(ControlBit.RESET_ALARM)

    def _do_move_absolute(self, target_m: float, velocity_m_s: float) -> None:
        cfg, regs = self._config, self._config.registers
        target_words = int32_to_words(self.position_counts(target_m), cfg.word_order)
        velocity_words = int32_to_words(self.velocity_counts(velocity_m_s), cfg.word_order)
        with self._lock:
            if regs.velocity == regs.target_position + 2:
                self._write_registers(regs.target_position, target_words + velocity_words)
            else:
                self._write_registers(regs.target_position, target_words)
                self._write_registers(regs.velocity, velocity_words)
            self._command(ControlBit.START)

    def _do_position_m(self) -> float:
        regs = self._config.registers
        words = self._read(regs.actual_position, 2, "read actual_position")
        counts = words_to_int32(words, self._config.word_order, device=self.name)
        return counts / self._config.counts_per_m

    def _do_status(self) -> StageStatus:
        regs = self._config.registers
        first, count = regs.status_span()
        words = self._read(first, count, "read status")
        return decode_status(words[regs.status - first], words[regs.alarm_code - first], device=self.name)

    def _do_close_transport(self) -> None:
        with self._lock:
            self._client.close()

    # transport ----------------------------------------------------------------------------------
    def _command(self, bit: ControlBit) -> None:
        regs, device_id = self._config.registers, self._config.device_id
        self._transact(
            f"write control={bit.name}",
            lambda c: c.write_register(regs.control, int(bit), device_id=device_id),
        )

    def _write_registers(self, address: int, words: list[int]) -> None:
        device_id = self._config.device_id
        self._transact(
            f"write registers {address}..{address + len(words) - 1}",
            lambda c: c.write_registers(address, words, device_id=device_id),
        )

    def _read(self, address: int, count: int, what: str) -> list[int]:
        device_id = self._config.device_id
        response = self._transact(
            what, lambda c: c.read_holding_registers(address, count=count, device_id=device_id)
        )
        words = list(response.registers)
        if len(words) != count:
            raise ProtocolError(self.name, f"{what}: expected {count} registers, got {len(words)}")
        return words

    def _transact(self, what: str, request: Callable[[ModbusBaseSyncClient], ModbusPDU]) -> ModbusPDU:
        """One request under the lock; reconnect once on a lost connection; named errors only."""
        with self._lock:
            try:
                response = self._attempt(request)
            except ConnectionException:
                self._client.close()
                try:
                    response = self._attempt(request)
                except (ConnectionException, ModbusIOException) as exc:
                    raise self._timeout_error(what, exc) from exc
            except ModbusIOException as exc:
                raise self._timeout_error(what, exc) from exc
        if response.isError():
            code = response.exception_code
            name = MODBUS_EXCEPTION_NAMES.get(code, "unknown")
            raise ProtocolError(self.name, f"{what}: Modbus exception {code} ({name})")
        return response

    def _attempt(self, request: Callable[[ModbusBaseSyncClient], ModbusPDU]) -> ModbusPDU:
        self._rx.clear()
        return request(self._client)

    def _timeout_error(self, what: str, exc: Exception) -> Exception:
        if self._rx:
            return ProtocolError(self.name, f"{what}: no valid response frame", bytes(self._rx))
        return DeviceTimeout(self.name, self._config.poll_timeout_s, detail=f"{what}: {exc}")

    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            self._rx[:] = data
        return data
