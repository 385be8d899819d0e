"""CAN frames of the DAQ shim (docs/protocols.md), as pure functions, plus sample pairing.

Shared by :mod:`drivers.can_daq` and by a simulated DAQ node. Parsers raise only
:class:`~drivers.errors.ProtocolError` on malformed payloads (fuzzed in the tests).

Layout (all little-endian): data frames ``0x180 + node`` (``uint16 counter, int16 fx, fy, fz``) and
``0x280 + node`` (``uint16 counter, int16 ain0, ain1, ain2``); commands ``0x600 + node``
(byte0 command, ``uint16 rate_hz`` for set-rate); replies ``0x580 + node`` (byte0 = command | 0x80,
byte1 status; the status reply adds byte2 streaming flag and bytes 3-4 ``uint16 rate_hz``).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from enum import IntEnum

from drivers.errors import ProtocolError

FORCE_BASE_ID = 0x180  # force frames on 0x180 + node (CANopen's TPDO1 range; docs/protocols.md)
ANALOG_BASE_ID = 0x280  # analog frames on 0x280 + node (TPDO2 range)
COMMAND_BASE_ID = 0x600  # commands to 0x600 + node (SDO request range)
REPLY_BASE_ID = 0x580  # replies from 0x580 + node (SDO response range)
COUNTER_MODULUS = 1 << 16  # the sample counter is a uint16 in each frame and wraps
FULL_SCALE_COUNTS = 32767
"""Largest value an int16 force or analog count can carry: a reading there is saturated (the
converter's full scale; -32768 the other way), so a force's wire range is this times its scale."""
_DATA = struct.Struct("<Hhhh")


class Command(IntEnum):
    """Command codes (byte0 of a frame on ``0x600 + node``)."""

    START = 0x01
    STOP = 0x02
    TARE = 0x03
    SET_RATE = 0x04
    STATUS = 0x05


class Status(IntEnum):
    """Status codes in replies."""

    OK = 0
    UNKNOWN_COMMAND = 1
    BAD_PARAMETER = 2
    BUSY = 3


@dataclass(frozen=True)
class NodeIds:
    """Arbitration ids of one node."""

    node_id: int

    def __post_init__(self) -> None:
        if isinstance(self.node_id, bool) or not isinstance(self.node_id, int):
            raise ValueError(f"node_id must be an integer, got {self.node_id!r}")
        if not 1 <= self.node_id <= 0x7F:
            raise ValueError(f"node_id must be in 1..127, got {self.node_id}")

    @property
    def force(self) -> int:
        return FORCE_BASE_ID + self.node_id

    @property
    def analog(self) -> int:
        return ANALOG_BASE_ID + self.node_id

    @property
    def command(self) -> int:
        return COMMAND_BASE_ID + self.node_id

    @property
    def reply(self) -> int:
        return REPLY_BASE_ID + self.node_id


@dataclass(frozen=True)
class Reply:
    """A decoded reply; ``streaming`` and ``rate_hz`` only for :attr:`Command.STATUS`."""

    command: Command
    status: int
    streaming: bool | None = None
    rate_hz: int | None = None


def pack_data(counter: int, v0: int, v1: int, v2: int) -> bytes:
    """An 8-byte data frame payload (counter mod 65536; values int16)."""
    return _DATA.pack(counter % COUNTER_MODULUS, v0, v1, v2)


def unpack_data(payload: bytes | bytearray, device: str = "daq") -> tuple[int, int, int, int]:
    """(counter, v0, v1, v2) of an 8-byte data frame payload."""
    if len(payload) != _DATA.size:
        raise ProtocolError(device, f"data frame of {len(payload)} bytes, expected 8", payload)
    counter, v0, v1, v2 = _DATA.unpack(bytes(payload))
    return counter, v0, v1, v2


def pack_command(command: Command, rate_hz: int | None = None) -> bytes:
    """A command payload; ``rate_hz`` (uint16) only and always for SET_RATE."""
    if command is Command.SET_RATE:
        if rate_hz is None or not 0 <= rate_hz <= 0xFFFF:
            raise ValueError(f"set-rate needs a uint16 rate_hz, got {rate_hz!r}")
        return struct.pack("<BH", command, rate_hz)
    return bytes([command])


def unpack_command(payload: bytes | bytearray, device: str = "daq") -> tuple[int, int | None]:
    """(command code, rate_hz or None) of a command payload (for simulated nodes).

    An unknown code is returned as is (the node answers it with status 1).
    """
    if len(payload) < 1:
        raise ProtocolError(device, "empty command frame", payload)
    code = payload[0]
    if code == Command.SET_RATE:
        if len(payload) < 3:
            raise ProtocolError(device, "set-rate frame without uint16 rate", payload)
        return code, int(struct.unpack_from("<H", bytes(payload), 1)[0])
    return code, None


def pack_reply(command: int, status: int, *, streaming: bool = False, rate_hz: int = 0) -> bytes:
    """A reply payload (for simulated nodes): status replies carry streaming flag and rate."""
    if command == Command.STATUS:
        return struct.pack("<BBBH", command | 0x80, status, int(streaming), rate_hz)
    return bytes([command | 0x80, status])


def unpack_reply(payload: bytes | bytearray, device: str = "daq") -> Reply:
    """Decode a reply payload; ProtocolError if short or not a reply to a known command."""
    data = bytes(payload)
    if len(data) < 2:
        raise ProtocolError(device, f"reply of {len(data)} bytes, expected at least 2", data)
    if not data[0] & 0x80:
        raise ProtocolError(device, "reply without the 0x80 reply flag", data)
    try:
        command = Command(data[0] & 0x7F)
    except ValueError:
        raise ProtocolError(device, f"reply to unknown command 0x{data[0] & 0x7F:02x}", data) from None
    if command is Command.STATUS:
        if len(data) < 5:
            raise ProtocolError(device, "status reply shorter than 5 bytes", data)
        _, status, streaming, rate = struct.unpack_from("<BBBH", data)
        return Reply(command, status, bool(streaming), rate)
    return Reply(command, data[1])


def unwrap_counter(raw: int, reference: int) -> int:
    """The unwrapped counter nearest to ``reference`` whose value mod 65536 is ``raw``.

    Differences of up to +-32767 samples (32 s at 1024 Hz) are resolved; the counter can thus run
    forward without limit across wraps, and a slightly late frame maps just behind the reference.
    """
    delta = (raw - reference) % COUNTER_MODULUS
    if delta >= COUNTER_MODULUS // 2:
        delta -= COUNTER_MODULUS
    return reference + delta


@dataclass
class Sample:
    """One complete sample: unwrapped counter, force counts, analog counts, host arrival [ns]."""

    counter: int
    force: tuple[int, int, int]
    analog: tuple[int, int, int]
    host_ns: int


Triple = tuple[int, int, int]


@dataclass
class SamplePairer:
    """Joins the force and analog frames of each sample by counter; counts what is lost.

    A sample is emitted when both of its frames have arrived. When sample n completes, every
    earlier sample not yet emitted (missing one or both frames) is counted as dropped and its
    partial frame discarded: CAN delivers a node's frames in order, so it will not come later.
    Frames for samples already emitted or dropped, and duplicates, are discarded and counted as
    ``stale_frames``. At most ``max_pending`` half-samples are kept (a stream that lost one frame
    type entirely cannot grow memory); older ones are dropped and counted.
    """

    max_pending: int = 64
    dropped: int = 0
    stale_frames: int = 0
    origin: int | None = None
    _next: int | None = None
    _reference: int | None = None
    _force: dict[int, Triple] = field(default_factory=dict)
    _analog: dict[int, Triple] = field(default_factory=dict)

    def reset(self) -> None:
        """Forget all state except the counts (after a stop/start)."""
        self.origin = None
        self._next = None
        self._reference = None
        self._force.clear()
        self._analog.clear()

    def add(self, is_force: bool, raw_counter: int, values: Triple, host_ns: int) -> Sample | None:
        """Add one frame; returns the sample it completes, if any."""
        reference = raw_counter if self._reference is None else self._reference
        counter = unwrap_counter(raw_counter, reference)
        if self._next is not None and counter < self._next:
            self.stale_frames += 1
            return None
        self._reference = max(counter, reference)
        mine, other = (self._force, self._analog) if is_force else (self._analog, self._force)
        if counter in mine:
            self.stale_frames += 1
            return None
        partner = other.pop(counter, None)
        if partner is None:
            mine[counter] = values
            self._bound_pending()
            return None
        force, analog = (values, partner) if is_force else (partner, values)
        if self._next is None:
            self.origin = counter
        else:
            self.dropped += counter - self._next
        for half in (self._force, self._analog):
            for older in [c for c in half if c < counter]:
                del half[older]
        self._next = counter + 1
        return Sample(counter, force, analog, host_ns)

    def _bound_pending(self) -> None:
        while len(self._force) + len(self._analog) > self.max_pending:
            oldest = min(list(self._force) + list(self._analog))
            self._force.pop(oldest, None)
            self._analog.pop(oldest, None)
            if self._next is not None and oldest >= self._next:
                self.dropped += oldest - self._next + 1
                self._next = oldest + 1
