"""A fibre-optic displacement probe behind a pseudo-terminal, speaking docs/protocols.md's ASCII.

The simulator holds the master side of a pty pair (``os.openpty()``, slave set raw with
``tty.setraw``); the real :class:`drivers.serial_probe.SerialProbe` opens :attr:`ProbeSim.path` (the
slave) as it would open ``/dev/ttyUSB0``. Commands and replies end with CR; one command is handled at
a time, in order:

- ``ID`` -> ``ID,<model>,<serial>``; ``RG`` -> ``RG,74.0000,0.0190``;
- ``MS`` -> ``MS,+0012.3450`` (quantised to 0.019 um) or ``MS,+OVER`` / ``MS,-OVER`` beyond +-37 um
  of the zero; ``ER,MS,03`` while streaming;
- ``ZR`` -> ``ZR`` (the current gap becomes the zero; shared with the probe's analog output);
- ``MV,<um>`` -> ``MV`` (the motorised mount moves by that many micrometres towards the target at
  its speed, the readings drop by it; ``ER,MV,02`` beyond the mount's travel or for a manual mount);
- ``ST,<rate_hz>`` -> ``ST``, then ``D,<seq>,<value>`` lines for samples at ``t0 + seq / rate`` of
  the rig's clock (rate 1 .. the rig's sample rate, else ``ER,ST,02``); ``SP`` -> ``SP``;
- anything else -> ``ER,<cmd>,01``; a malformed argument -> ``ER,<cmd>,02``.

The values come from the virtual rig's probe heads (:class:`~sim_devices.sensors.ProbeHead`).
Output is written non-blocking: if the host stops reading, up to ``MAX_BACKLOG_BYTES`` wait, then
whole lines are lost (counted in ``lines_lost``) as a real UART without flow control would lose them.

Faults (:mod:`sim_devices.faults`): ``silent`` (commands ignored, stream paused), ``corrupt_pct``
(a line's bytes garbled), ``short_pct`` (a line cut short before its CR), ``stuck`` (values freeze).
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import select
import tty
from collections.abc import Callable

import numpy as np

from drivers.errors import OverRangeError, ProtocolError
from drivers.probe_lines import MAX_LINE_BYTES, TERMINATOR, format_value, parse_value_m
from sim_devices.faults import Faults, StuckReading
from sim_devices.sample_ring import SamplesLostError
from sim_devices.sensors import ProbeHead
from sim_devices.service import SimService
from sim_devices.stream_cursor import StreamCursor, interp
from sim_devices.virtual_rig import VirtualRig

_log = logging.getLogger(__name__)

CR = TERMINATOR
MAX_BACKLOG_BYTES = 1 << 16  # 64 KiB of unread output (seconds of a 1 kHz stream), then lines are lost
MAX_COMMAND_BYTES = MAX_LINE_BYTES  # the protocol's longest line; more without CR is garbage
MAX_BATCH_LINES = 256  # stream lines written per loop turn: bounds one burst


class ProbeSim(SimService):
    """One simulated probe (index 0 = D1, 1 = D2 of the rig) behind a pty (module docstring)."""

    def __init__(self, rig: VirtualRig, index: int, *, faults: Faults | None = None) -> None:
        if index not in (0, 1):
            raise ValueError("probe index must be 0 (D1) or 1 (D2)")
        super().__init__(f"probe-sim-d{index + 1}")
        self.rig = rig
        self.index = index
        self.head: ProbeHead = rig.probes[index]
        self.faults = faults if faults is not None else Faults(seed=100 + index)
        self._master = -1
        self._slave = -1
        self.path = ""
        self._in = bytearray()
        self._out = bytearray()
        self._cursor: StreamCursor | None = None
        self._stuck: StuckReading[float] = StuckReading(self.faults)
        self.lines_lost = 0
        self.commands_seen = 0

    # ---------------------------------------------------------------------------- lifecycle
    def _open(self) -> None:
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        os.set_blocking(self._master, False)
        self.path = os.ttyname(self._slave)

    def _loops(self) -> list[tuple[Callable[[], None], str]]:
        return [(self._loop, "pty")]

    def _close(self) -> None:
        for fd in (self._master, self._slave):
            if fd >= 0:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = -1

    # --------------------------------------------------------------------------------- loop
    def _loop(self) -> None:
        while self.running:
            wait_s = 0.002 if self._cursor is not None else 0.02
            writers = [self._master] if self._out else []
            try:
                readable, _, _ = select.select([self._master], writers, [], wait_s)
            except (OSError, ValueError):
                return
            if readable:
                try:
                    data = os.read(self._master, 4096)
                except BlockingIOError:
                    data = b""
                except OSError:  # the slave side went away for good
                    return
                self._in += data
                self._handle_input()
            if self._cursor is not None and not self.faults.silent:
                self._emit_stream()
            self._flush()

    def _handle_input(self) -> None:
        while (end := self._in.find(CR)) >= 0:
            line = bytes(self._in[:end]).strip(b"\n")
            del self._in[: end + 1]
            if line and not self.faults.silent:
                self.commands_seen += 1
                self._send_line(self.reply_to(line))
        if len(self._in) > MAX_COMMAND_BYTES:  # garbage without CR: forget it
            self._in.clear()

    def reply_to(self, line: bytes) -> str:
        """The reply (without CR) to one command line."""
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            return "ER,??,01"
        fields = text.split(",")
        cmd, args = fields[0], fields[1:]
        if cmd not in ("ID", "RG", "MS", "ZR", "ST", "SP", "MV"):
            return f"ER,{cmd[:8]},01"
        if cmd not in ("ST", "MV") and args:
            return f"ER,{cmd},02"
        spec = self.head.spec
        if cmd == "ID":
            return f"ID,{spec.model},{spec.serial}"
        if cmd == "RG":
            return f"RG,{spec.range_m * 1e6:.4f},{spec.resolution_m * 1e6:.4f}"
        if cmd == "SP":
            self._cursor = None
            return "SP"
        if self._cursor is not None:
            return f"ER,{cmd},03"
        if cmd == "MS":
            return "MS," + format_value(self._value_now())
        if cmd == "ZR":
            self.head.zero_at(self._ideal_now())
            return "ZR"
        if cmd == "MV":
            return self._move_mount(args)
        return self._start_stream(args)

    def _move_mount(self, args: list[str]) -> str:
        try:
            distance_m = parse_value_m(args[0]) if len(args) == 1 else math.nan
        except (ProtocolError, OverRangeError):
            return "ER,MV,02"
        try:
            self.rig.move_probe_mount(self.index, distance_m)
        except ValueError:  # not finite, beyond the travel, or a manual mount (travel 0)
            return "ER,MV,02"
        return "MV"

    def _start_stream(self, args: list[str]) -> str:
        if len(args) != 1 or not args[0].isdigit():
            return "ER,ST,02"
        rate = int(args[0])
        if not 1 <= rate <= self.rig.rate_hz:
            return "ER,ST,02"
        self._cursor = StreamCursor(self.rig, rate)
        return "ST"

    def _ideal_now(self) -> float:
        return float(self.rig.probe_ideal_m(self.index)[0])

    def _value_now(self) -> float:
        return self._apply_stuck(self.head.readings_m(np.array([self._ideal_now()])))[0]

    def _apply_stuck(self, values: np.ndarray) -> np.ndarray:
        return self._stuck.hold_array(values)

    def _emit_stream(self) -> None:
        cursor = self._cursor
        assert cursor is not None
        seq0, t = cursor.due(MAX_BATCH_LINES)
        if t.shape[0] == 0:
            return
        try:
            s = cursor.window(t)
        except SamplesLostError as lost:  # fell behind the rig's history: skip ahead, the gap shows
            cursor.skip_lost(lost)
            return
        ideal = interp(t, s, s.d1_m if self.index == 0 else s.d2_m)
        values = self._apply_stuck(self.head.readings_m(ideal, t))
        for i in range(t.shape[0]):
            self._send_line(f"D,{(seq0 + i) & 0xFFFFFFFF},{format_value(float(values[i]))}")
        cursor.consume(t.shape[0])

    # -------------------------------------------------------------------------------- output
    def _send_line(self, text: str) -> None:
        data = text.encode("ascii")
        f = self.faults
        if f.roll(f.short_pct):
            data = data[: max(1, len(data) // 2)]
        elif f.roll(f.corrupt_pct):
            garbled = bytearray(data)
            for pos in f.random_bytes(3):
                garbled[pos % len(garbled)] = 0x80 | (pos & 0x7F)  # non-ASCII: unreadable
            data = bytes(garbled)
        if len(self._out) + len(data) + 1 > MAX_BACKLOG_BYTES:
            self.lines_lost += 1
            return
        self._out += data + CR

    def _flush(self) -> None:
        if not self._out:
            return
        try:
            written = os.write(self._master, self._out)
        except BlockingIOError:
            return
        except OSError:
            self._out.clear()
            return
        del self._out[:written]
