"""The stage controllers' Modbus register map and pure encoders/decoders (docs/protocols.md).

Shared by :mod:`drivers.modbus_stage` and by a simulated controller, so both sides agree on bits,
word order and INT32 packing. Every function is pure and raises only
:class:`~drivers.errors.ProtocolError` (malformed data from a device) or
:class:`~drivers.errors.InvalidValueError` (a value that cannot be encoded).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import IntFlag
from typing import Literal

from drivers.errors import InvalidValueError, ProtocolError
from drivers.interfaces import StageStatus

WordOrder = Literal["high_first", "low_first"]
WORD_ORDERS: tuple[WordOrder, ...] = ("high_first", "low_first")

INT32_MIN = -(2**31)  # positions and velocities are INT32 in two registers
INT32_MAX = 2**31 - 1


class ControlBit(IntFlag):
    """Bits of the ``control`` register; each is a one-shot command the device clears."""

    ENABLE = 1 << 0
    START = 1 << 1
    HOME = 1 << 2
    STOP = 1 << 3
    RESET_ALARM = 1 << 4
    EMERGENCY_STOP = 1 << 5
    DISABLE = 1 << 6


class StatusBit(IntFlag):
    """Bits of the ``status`` register."""

    ENABLED = 1 << 0
    IN_POSITION = 1 << 1
    HOMED = 1 << 2
    MOVING = 1 << 3
    FAULT = 1 << 4
    LIMIT = 1 << 5


@dataclass(frozen=True)
class RegisterMap:
    """Holding-register addresses; 32-bit values occupy ``addr`` and ``addr + 1``."""

    control: int = 0
    status: int = 1
    target_position: int = 2
    velocity: int = 4
    actual_position: int = 6
    alarm_code: int = 8

    def __post_init__(self) -> None:
        used: dict[int, str] = {}
        for key, width in (
            ("control", 1),
            ("status", 1),
            ("target_position", 2),
            ("velocity", 2),
            ("actual_position", 2),
            ("alarm_code", 1),
        ):
            addr = getattr(self, key)
            if isinstance(addr, bool) or not isinstance(addr, int) or not 0 <= addr <= 0xFFFE:
                raise ValueError(f"RegisterMap.{key} must be an address 0..65534, got {addr!r}")
            for reg in range(addr, addr + width):
                if reg in used:
                    raise ValueError(f"RegisterMap.{key} overlaps {used[reg]} at register {reg}")
                used[reg] = key

    def status_span(self) -> tuple[int, int]:
        """(first address, count) of one read covering status, actual position and alarm code."""
        first = min(self.status, self.actual_position, self.alarm_code)
        last = max(self.status, self.actual_position + 1, self.alarm_code)
        return first, last - first + 1


def int32_to_words(value: int, word_order: WordOrder, *, device: str = "stage") -> list[int]:
    """Two 16-bit registers holding ``value`` as two's-complement INT32 in ``word_order``."""
    if not INT32_MIN <= value <= INT32_MAX:
        raise InvalidValueError(device, "int32", value, "does not fit in INT32 counts")
    raw = value & 0xFFFFFFFF
    high, low = raw >> 16, raw & 0xFFFF
    return [high, low] if word_order == "high_first" else [low, high]


def words_to_int32(words: Sequence[int], word_order: WordOrder, *, device: str = "stage") -> int:
    """The INT32 held in two 16-bit registers in ``word_order``."""
    if len(words) != 2 or not all(isinstance(w, int) and 0 <= w <= 0xFFFF for w in words):
        raise ProtocolError(device, "an INT32 needs two 16-bit registers", _as_bytes(words))
    high, low = (words[0], words[1]) if word_order == "high_first" else (words[1], words[0])
    raw = (high << 16) | low
    return raw - (1 << 32) if raw & 0x80000000 else raw


def decode_status(status_word: int, alarm_code: int, *, device: str = "stage") -> StageStatus:
    """A :class:`StageStatus` from the status register and the alarm-code register."""
    for label, word in (("status", status_word), ("alarm_code", alarm_code)):
        if not isinstance(word, int) or not 0 <= word <= 0xFFFF:
            raise ProtocolError(device, f"{label} register out of 16-bit range", _as_bytes([word]))
    bits = StatusBit(status_word & 0x3F)
    return StageStatus(
        enabled=StatusBit.ENABLED in bits,
        in_position=StatusBit.IN_POSITION in bits,
        homed=StatusBit.HOMED in bits,
        moving=StatusBit.MOVING in bits,
        fault=StatusBit.FAULT in bits,
        limit=StatusBit.LIMIT in bits,
        alarm_code=alarm_code,
    )


def encode_status(status: StageStatus) -> int:
    """The status register word for ``status`` (for simulated controllers)."""
    word = StatusBit(0)
    for flag, on in (
        (StatusBit.ENABLED, status.enabled),
        (StatusBit.IN_POSITION, status.in_position),
        (StatusBit.HOMED, status.homed),
        (StatusBit.MOVING, status.moving),
        (StatusBit.FAULT, status.fault),
        (StatusBit.LIMIT, status.limit),
    ):
        if on:
            word |= flag
    return int(word)


def _as_bytes(words: Sequence[object]) -> bytes:
    """Best-effort bytes of a register list for an error message (never raises)."""
    out = bytearray()
    for w in words:
        if isinstance(w, int) and 0 <= w <= 0xFFFF:
            out += w.to_bytes(2, "big")
        else:
            out += repr(w).encode("ascii", "backslashreplace")
    return bytes(out)
