"""The displacement probes' ASCII lines (docs/protocols.md) as pure functions.

Shared by :mod:`drivers.serial_probe` and by a simulated probe. Parsers take one line without its
terminating CR and raise only :class:`~drivers.errors.ProtocolError` (malformed line, bytes kept),
a :class:`~drivers.errors.DeviceRejected` subclass (an ``ER,<cmd>,<code>`` reply) or
:class:`~drivers.errors.OverRangeError` (``MS,+OVER``). Values on the wire are micrometres with
four decimals and an explicit sign (``+0012.3450``); here they are metres.
"""

from __future__ import annotations

import math
import re

from drivers.errors import OverRangeError, ProtocolError, rejected

TERMINATOR = b"\r"  # every line ends with CR (docs/protocols.md)
MAX_LINE_BYTES = 80
"""A line longer than this without CR is garbage, not a reply."""

UINT32_MAX = 2**32 - 1  # stream sequence numbers are uint32 and wrap
_VALUE = re.compile(r"[+-][0-9]{1,6}\.[0-9]{4}")
_NUMBER = re.compile(r"[0-9]{1,6}(\.[0-9]{1,6})?")
_SEQ = re.compile(r"[0-9]{1,10}")
_CODE = re.compile(r"[0-9]{2}")
COMMANDS = ("ID", "RG", "MS", "ZR", "ST", "SP", "MV")  # the probe protocol's commands (docs/protocols.md)


def format_command(command: str, *args: str) -> bytes:
    """A command line: ``CMD[,arg...]\\r``."""
    if command not in COMMANDS:
        raise ValueError(f"unknown probe command {command!r}")
    return ",".join((command, *args)).encode("ascii") + TERMINATOR


def decode_line(line: bytes, device: str = "probe") -> list[str]:
    """The comma-separated fields of a line (CR removed), checked to be printable ASCII."""
    if len(line) > MAX_LINE_BYTES:
        raise ProtocolError(device, f"line longer than {MAX_LINE_BYTES} bytes", line[:120])
    try:
        text = line.decode("ascii")
    except UnicodeDecodeError:
        raise ProtocolError(device, "non-ASCII bytes in line", line) from None
    if not text or not text.isprintable():
        raise ProtocolError(device, "empty line or control characters", line)
    return text.split(",")


def check_reply(line: bytes, command: str, device: str = "probe") -> list[str]:
    """The fields after the echo of ``command``; ER replies raise the matching named error."""
    fields = decode_line(line, device)
    if fields[0] == "ER":
        if len(fields) != 3 or not _CODE.fullmatch(fields[2]):
            raise ProtocolError(device, "malformed error reply", line)
        raise rejected(device, fields[1], int(fields[2]))
    if fields[0] != command:
        raise ProtocolError(device, f"reply to {command} expected", line)
    return fields[1:]


def parse_value_m(text: str, device: str = "probe", line: bytes = b"") -> float:
    """A signed micrometre value with four decimals, in metres; ``+OVER``/``-OVER`` raise."""
    if text in ("+OVER", "-OVER"):
        raise OverRangeError(device, 1 if text[0] == "+" else -1)
    if not _VALUE.fullmatch(text):
        raise ProtocolError(device, f"bad value {text!r}", line or text.encode("ascii", "replace"))
    return float(text) * 1e-6


def parse_measurement(line: bytes, device: str = "probe") -> float:
    """The displacement [m] in an ``MS,<value>`` reply; OverRangeError for ``MS,+-OVER``."""
    fields = check_reply(line, "MS", device)
    if len(fields) != 1:
        raise ProtocolError(device, "MS reply needs exactly one value", line)
    return parse_value_m(fields[0], device, line)


def parse_range(line: bytes, device: str = "probe") -> tuple[float, float]:
    """(range_m, resolution_m) of an ``RG,<range_um>,<resolution_um>`` reply."""
    fields = check_reply(line, "RG", device)
    if len(fields) != 2 or not all(_NUMBER.fullmatch(f) for f in fields):
        raise ProtocolError(device, "RG reply needs two positive numbers", line)
    range_m, resolution_m = float(fields[0]) * 1e-6, float(fields[1]) * 1e-6
    if not (range_m > 0 and 0 < resolution_m <= range_m):
        raise ProtocolError(device, "RG reply: need 0 < resolution <= range", line)
    return range_m, resolution_m


def parse_identity(line: bytes, device: str = "probe") -> tuple[str, str]:
    """(model, serial) of an ``ID,<model>,<serial>`` reply."""
    fields = check_reply(line, "ID", device)
    if len(fields) != 2 or not all(fields):
        raise ProtocolError(device, "ID reply needs model and serial", line)
    return fields[0], fields[1]


def parse_ack(line: bytes, command: str, device: str = "probe") -> None:
    """Check a bare acknowledgement (``ZR``, ``ST``, ``SP``)."""
    if check_reply(line, command, device):
        raise ProtocolError(device, f"{command} acknowledgement with extra fields", line)


def parse_stream_line(line: bytes, device: str = "probe") -> tuple[int, float]:
    """(seq, value_m) of a ``D,<seq>,<value>`` line; over-range is ``+inf`` / ``-inf``."""
    fields = decode_line(line, device)
    if len(fields) != 3 or fields[0] != "D" or not _SEQ.fullmatch(fields[1]):
        raise ProtocolError(device, "malformed stream line", line)
    seq = int(fields[1])
    if seq > UINT32_MAX:
        raise ProtocolError(device, "stream sequence number beyond uint32", line)
    try:
        return seq, parse_value_m(fields[2], device, line)
    except OverRangeError as over:
        return seq, math.copysign(math.inf, over.direction)


def format_value(value_m: float) -> str:
    """The wire form of a displacement (for simulated probes): ``+0012.3450`` um, or +-OVER."""
    if math.isnan(value_m):
        raise ValueError("a probe value cannot be NaN")
    if math.isinf(value_m):
        return "+OVER" if value_m > 0 else "-OVER"
    return f"{value_m * 1e6:+010.4f}"
