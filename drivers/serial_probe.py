"""A displacement probe over a serial line (docs/protocols.md), via ``serial.serial_for_url``.

Any pyserial URL works: a real port (``/dev/ttyUSB0``), a pty path, ``socket://host:port``,
``loop://``. One reader thread owns all reads: it splits the byte stream at CR, files ``D,...``
stream lines into a bounded ring (oldest dropped and counted) and every other line into the reply
queue. Commands are sent one at a time under a lock and wait ``timeout_s`` (0.3 s) for their reply,
are sent once more, then raise :class:`DeviceTimeout` (0.6 s in all). ``ER,<cmd>,<code>`` replies
raise :class:`UnknownCommand`, :class:`BadParameter` or :class:`DeviceBusy`.

Over-range: a single reading (``MS,+OVER``) raises :class:`OverRangeError`; in a stream the value
is ``+inf`` / ``-inf`` (flagged, never clipped). Malformed stream lines are counted in
``protocol_errors`` and skipped; gaps in the stream's sequence numbers count in ``dropped_samples``.
"""

from __future__ import annotations

import contextlib
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass

import numpy as np
import serial

from drivers.errors import DeviceError, DeviceTimeout, InvalidValueError, ProtocolError, SettingError
from drivers.interfaces import DisplacementProbe, ProbeSamples
from drivers.probe_lines import (
    MAX_LINE_BYTES,
    TERMINATOR,
    UINT32_MAX,
    format_command,
    format_value,
    parse_ack,
    parse_identity,
    parse_measurement,
    parse_range,
    parse_stream_line,
)
from drivers.validate import check_integer, check_number


@dataclass(frozen=True)
class ProbeConfig:
    """Port and timing of a :class:`SerialProbe`."""

    name: str = "probe"
    url: str = "loop://"
    baudrate: int = 115200
    timeout_s: float = 0.3
    retries: int = 1
    stream_silence_s: float = 0.5
    stream_buffer: int = 65536
    mount_travel_m: float = 0.0
    """Travel of a motorised mount driven through the probe's ``MV`` command (centred on where it
    starts); 0: the mount is manual and :meth:`SerialProbe.move_mount` is refused."""
    mount_speed_m_s: float = 1e-3
    """Speed of the motorised mount (its move takes ``|distance| / speed``)."""

    def __post_init__(self) -> None:
        owner = f"probe {self.name!r}"
        check_number(owner, "mount_travel_m", self.mount_travel_m, unit="m", ge=0.0, le=0.2)
        check_number(owner, "mount_speed_m_s", self.mount_speed_m_s, unit="m/s", gt=0.0, le=1.0)
        if not isinstance(self.url, str) or not self.url:
            raise SettingError(owner, "url", self.url, "must be a pyserial URL or port name")
        for key in ("timeout_s", "stream_silence_s"):
            check_number(owner, key, getattr(self, key), unit="s", gt=0.0)
        for key, low, high in (
            ("baudrate", 1, 10_000_000),
            ("retries", 0, 3),
            ("stream_buffer", 16, 1 << 22),
        ):
            check_integer(owner, key, getattr(self, key), low, high)


class SerialProbe(DisplacementProbe):
    """A :class:`DisplacementProbe` speaking the CR-terminated ASCII protocol."""

    def __init__(self, config: ProbeConfig | None = None, *, port: serial.SerialBase | None = None) -> None:
        cfg = config if config is not None else ProbeConfig()
        super().__init__(cfg.name)
        self._config = cfg
        if port is None:
            try:
                port = serial.serial_for_url(cfg.url, baudrate=cfg.baudrate, timeout=0.02)
            except (serial.SerialException, ValueError, OSError) as exc:
                raise DeviceError(cfg.name, f"cannot open serial port {cfg.url!r}: {exc}") from exc
        self._port = port
        self._command_lock = threading.Lock()
        self._replies: queue.Queue[bytes] = queue.Queue(maxsize=64)
        self._stream: deque[tuple[int, float, int]] = deque(maxlen=cfg.stream_buffer)
        self._stream_event = threading.Event()
        self._stats_lock = threading.Lock()
        self._protocol_errors = 0
        self._last_protocol_error: ProtocolError | None = None
        self._dropped = 0
        self._overflowed = 0
        self._last_seq: int | None = None
        self._last_line_ns = 0
        self._stream_started_ns = 0
        self._io_error: Exception | None = None
        self._range: tuple[float, float] | None = None
        self._running = True
        self._reader = threading.Thread(target=self._read_loop, name=f"{cfg.name}-reader", daemon=True)
        self._reader.start()

    @property
    def config(self) -> ProbeConfig:
        """The configuration this probe was built from."""
        return self._config

    @property
    def range_m(self) -> float:
        """Full measuring range [m] (asked of the probe once with ``RG``)."""
        return self._query_range()[0]

    @property
    def resolution_m(self) -> float:
        """Resolution [m] (asked of the probe once with ``RG``)."""
        return self._query_range()[1]

    @property
    def protocol_errors(self) -> int:
        """Malformed stream lines received and skipped so far."""
        return self._protocol_errors

    @property
    def last_protocol_error(self) -> ProtocolError | None:
        """The most recent malformed stream line (with its bytes), if any."""
        return self._last_protocol_error

    @property
    def dropped_samples(self) -> int:
        """Stream samples lost so far (sequence gaps and buffer overflow)."""
        return self._dropped + self._overflowed

    def identify(self) -> tuple[str, str]:
        """(model, serial number) from ``ID``."""
        self._check_idle("identify")
        return parse_identity(self._transact("ID"), self.name)

    @property
    def mount_travel_m(self) -> float:
        """Travel of the motorised mount (``ProbeConfig.mount_travel_m``; 0: manual)."""
        return self._config.mount_travel_m

    @property
    def mount_speed_m_s(self) -> float:
        """Speed of the motorised mount (``ProbeConfig.mount_speed_m_s``)."""
        return self._config.mount_speed_m_s

    # hooks --------------------------------------------------------------------------------------
    def _do_zero(self) -> None:
        parse_ack(self._transact("ZR"), "ZR", self.name)

    def _do_move_mount(self, distance_m: float) -> None:
        parse_ack(self._transact("MV", format_value(distance_m), retries=0), "MV", self.name)

    def _do_read_m(self) -> float:
        return parse_measurement(self._transact("MS"), self.name)

    def _do_start_stream(self, rate_hz: float) -> None:
        if rate_hz != int(rate_hz):
            raise InvalidValueError(self.name, "rate_hz", rate_hz, "must be a whole number of Hz")
        with self._stats_lock:
            self._stream.clear()
            self._last_seq = None
        self._stream_started_ns = time.monotonic_ns()
        parse_ack(self._transact("ST", str(int(rate_hz))), "ST", self.name)

    def _do_stop_stream(self) -> None:
        parse_ack(self._transact("SP"), "SP", self.name)

    def _do_read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples:
        deadline = time.monotonic() + timeout_s
        while True:
            self._stream_event.clear()
            if self._stream:
                break
            self._raise_on_io_error()
            now_ns = time.monotonic_ns()
            if self.streaming:
                silent_since = max(self._last_line_ns, self._stream_started_ns)
                if now_ns - silent_since > self._config.stream_silence_s * 1e9:
                    raise DeviceTimeout(self.name, self._config.stream_silence_s, detail="no stream lines")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                break
            self._stream_event.wait(min(remaining, self._config.stream_silence_s))
        taken: list[tuple[int, float, int]] = []
        with self._stats_lock:
            while self._stream and len(taken) < max_samples:
                taken.append(self._stream.popleft())
        return ProbeSamples(
            seq=np.array([s[0] for s in taken], dtype=np.int64),
            values_m=np.array([s[1] for s in taken], dtype=np.float64),
            host_ns=np.array([s[2] for s in taken], dtype=np.int64),
        )

    def _do_close(self) -> None:
        self._running = False
        self._reader.join(timeout=1.0)
        with contextlib.suppress(serial.SerialException, OSError):
            self._port.close()

    # commands -----------------------------------------------------------------------------------
    def _query_range(self) -> tuple[float, float]:
        if self._range is None:
            self._check_idle("RG")
            self._range = parse_range(self._transact("RG"), self.name)
        return self._range

    def _transact(self, command: str, *args: str, retries: int | None = None) -> bytes:
        """Send one command (one in flight), return its reply line; ``retries`` (default: the
        configuration's) more tries on silence. A move is never retried: it may have been made."""
        line = format_command(command, *args)
        cfg = self._config
        tries = 1 + (cfg.retries if retries is None else retries)
        with self._command_lock:
            for _attempt in range(tries):
                self._clear_replies()
                self._write(line)
                reply = self._await_reply(cfg.timeout_s)
                if reply is not None:
                    return reply
        raise DeviceTimeout(self.name, cfg.timeout_s * tries, detail=command)

    def _write(self, data: bytes) -> None:
        self._raise_on_io_error()
        try:
            self._port.write(data)
            self._port.flush()
        except (serial.SerialException, OSError) as exc:
            raise DeviceError(self.name, f"serial write failed: {exc}") from exc

    def _await_reply(self, timeout_s: float) -> bytes | None:
        try:
            return self._replies.get(timeout=timeout_s)
        except queue.Empty:
            self._raise_on_io_error()
            return None

    def _clear_replies(self) -> None:
        while True:
            try:
                self._replies.get_nowait()
            except queue.Empty:
                return

    def _raise_on_io_error(self) -> None:
        if self._io_error is not None:
            raise DeviceError(self.name, f"serial read failed: {self._io_error}")

    # reader thread ------------------------------------------------------------------------------
    def _read_loop(self) -> None:
        buffer = bytearray()
        while self._running:
            try:
                chunk = self._port.read(max(1, self._port.in_waiting))
            except (serial.SerialException, OSError, TypeError) as exc:
                if self._running:
                    self._io_error = exc
                return
            if not chunk:
                continue
            buffer += chunk
            while (end := buffer.find(TERMINATOR)) >= 0:
                line = bytes(buffer[:end]).lstrip(b"\n")
                del buffer[: end + 1]
                self._dispatch(line, time.monotonic_ns())
            if len(buffer) > MAX_LINE_BYTES:
                self._dispatch(bytes(buffer), time.monotonic_ns())
                buffer.clear()

    def _dispatch(self, line: bytes, host_ns: int) -> None:
        if not line.startswith(b"D,"):
            with contextlib.suppress(queue.Full):
                self._replies.put_nowait(line)
            return
        self._last_line_ns = host_ns
        try:
            seq, value_m = parse_stream_line(line, self.name)
        except ProtocolError as exc:
            self._protocol_errors += 1
            self._last_protocol_error = exc
            return
        with self._stats_lock:
            if self._last_seq is not None:
                gap = (seq - self._last_seq - 1) % (UINT32_MAX + 1)
                if gap < 2**31:
                    self._dropped += gap
            self._last_seq = seq
            if len(self._stream) == self._stream.maxlen:
                self._overflowed += 1
            self._stream.append((seq, value_m, host_ns))
        self._stream_event.set()
