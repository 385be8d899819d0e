"""The force/analog DAQ shim over CAN with python-can (docs/protocols.md), for any interface.

Receiving: a :class:`can.Notifier` calls :class:`_FrameListener` in its reader thread; the callback
is O(1) - it copies the 8 payload bytes and the host arrival time into a bounded ring
(``rx_queue_size`` frames; when full the oldest frame goes and ``overflowed_frames`` counts it) and
sets an event. Decoding, counter unwrapping and force/analog pairing happen in ``read_block`` on the
caller's thread, and only as far as needed, so a slow reader loses data only in the bounded ring,
where the loss shows as a counter gap and is counted.

Loss is counted, never invented: a counter jump, a sample missing one of its two frames, a ring
overflow all add to ``dropped_samples``. Malformed data frames (wrong length, remote frames) are
counted in ``protocol_errors`` and skipped, so one bad frame cannot stop a 1024 Hz stream; the last
one is kept in ``last_protocol_error`` with its bytes. Command replies that are malformed raise.

Timing: a command unanswered for ``command_timeout_s`` (0.3 s) is sent once more, then
:class:`DeviceTimeout` (0.6 s in all). While streaming, ``read_block`` raises :class:`DeviceTimeout`
once no data frame has arrived for ``stream_silence_s`` (0.5 s).
"""

from __future__ import annotations

import contextlib
import math
import queue
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import can
import numpy as np

from drivers.can_frames import (
    FULL_SCALE_COUNTS,
    Command,
    NodeIds,
    Reply,
    Sample,
    SamplePairer,
    pack_command,
    unpack_data,
    unpack_reply,
)
from drivers.errors import (
    DeviceError,
    DeviceTimeout,
    InvalidValueError,
    LimitError,
    ProtocolError,
    rejected,
)
from drivers.interfaces import ChannelMap, Daq, DaqBlock
from drivers.validate import check_integer, check_number, refused

MAX_RATE_HZ = 0xFFFF
"""The set-rate command carries a uint16."""

DEFAULT_FORCE_N_PER_COUNT = 0.025
"""Default force scale [N/count]: the wire's full scale, 32767 counts, is then 819.175 N, above the
normal stage's rated 800 N (``drivers.ratings.RATED_NORMAL_FORCE_N``), as a lab fits a force sensor
whose range covers the stage's rated load."""


@dataclass(frozen=True)
class CanDaqConfig:
    """Bus, node, scales and timing of a :class:`CanDaq`; defaults follow docs/protocols.md."""

    name: str = "daq"
    interface: str = "virtual"
    channel: str = "rigctl"
    bitrate: int | None = None
    node_id: int = 1
    rate_hz: float = 1024.0
    force_N_per_count: float = DEFAULT_FORCE_N_PER_COUNT
    force_range_N: float = math.inf
    """The force sensor's rated range [N]; the driver's :attr:`CanDaq.force_range_N` is the lower of
    it and the wire's full scale (``FULL_SCALE_COUNTS * force_N_per_count``)."""
    volts_per_count: float = 10.0 / 32768.0
    command_timeout_s: float = 0.3
    command_retries: int = 1
    stream_silence_s: float = 0.5
    rx_queue_size: int = 8192
    channel_map: ChannelMap = field(default_factory=ChannelMap)

    @property
    def saturation_N(self) -> float:
        """Where a force reading saturates: the lower of :attr:`force_range_N` and the wire's full
        scale (``FULL_SCALE_COUNTS * force_N_per_count``, 819.175 N at 0.025 N/count)."""
        return min(self.force_range_N, FULL_SCALE_COUNTS * self.force_N_per_count)

    def __post_init__(self) -> None:
        owner = f"daq {self.name!r}"

        NodeIds(self.node_id)  # validates the node id
        for key, unit in (
            ("rate_hz", "Hz"),
            ("force_N_per_count", "N/count"),
            ("volts_per_count", "V/count"),
            ("command_timeout_s", "s"),
            ("stream_silence_s", "s"),
        ):
            check_number(owner, key, getattr(self, key), unit=unit, gt=0.0)
        if self.force_range_N != math.inf:
            check_number(owner, "force_range_N", self.force_range_N, unit="N", gt=0.0)
        if self.rate_hz != int(self.rate_hz) or self.rate_hz > MAX_RATE_HZ:
            raise refused(owner, self, "rate_hz", f"must be a whole number of Hz up to {MAX_RATE_HZ}")
        for key, low, high in (("command_retries", 0, 3), ("rx_queue_size", 16, 1 << 22)):
            check_integer(owner, key, getattr(self, key), low, high)
        if self.bitrate is not None and (
            isinstance(self.bitrate, bool) or not isinstance(self.bitrate, int) or self.bitrate <= 0
        ):
            raise refused(owner, self, "bitrate", "must be a positive integer or None")
        if not isinstance(self.interface, str) or not self.interface:
            raise refused(owner, self, "interface", "must name a python-can interface")
        if not isinstance(self.channel_map, ChannelMap):
            raise refused(owner, self, "channel_map", "must be a ChannelMap")


@dataclass(frozen=True)
class DaqDeviceStatus:
    """The node's answer to the status command."""

    streaming: bool
    rate_hz: int


class _FrameListener(can.Listener):
    """Runs in the notifier thread: O(1) per frame, no decoding."""

    def __init__(self, ids: NodeIds, ring_size: int) -> None:
        self._force_id = ids.force
        self._analog_id = ids.analog
        self._reply_id = ids.reply
        self.ring: deque[tuple[bool, bytes, int, bool]] = deque(maxlen=ring_size)
        self.replies: queue.Queue[bytes] = queue.Queue(maxsize=16)
        self.data_event = threading.Event()
        self.overflowed = 0
        self.last_frame_ns = 0
        self.error: Exception | None = None

    def on_message_received(self, msg: can.Message) -> None:
        arbitration_id = msg.arbitration_id
        if msg.is_error_frame or msg.is_extended_id:
            return
        if arbitration_id == self._force_id or arbitration_id == self._analog_id:
            now = time.monotonic_ns()
            if len(self.ring) == self.ring.maxlen:
                self.overflowed += 1
            self.ring.append((arbitration_id == self._force_id, bytes(msg.data), now, msg.is_remote_frame))
            self.last_frame_ns = now
            self.data_event.set()
        elif arbitration_id == self._reply_id:
            # replies nobody waits for are dropped; the command path clears the queue first
            with contextlib.suppress(queue.Full):
                self.replies.put_nowait(bytes(msg.data))

    def on_error(self, exc: Exception) -> None:
        self.error = exc
        self.data_event.set()


def open_bus(config: CanDaqConfig) -> can.BusABC:
    """A python-can bus filtered to the node's ids; bounded receive queue where supported."""
    ids = NodeIds(config.node_id)
    kwargs: dict[str, Any] = {
        "interface": config.interface,
        "channel": config.channel,
        "receive_own_messages": False,
        "can_filters": [
            {"can_id": can_id, "can_mask": 0x7FF, "extended": False}
            for can_id in (ids.force, ids.analog, ids.reply)
        ],
    }
    if config.bitrate is not None:
        kwargs["bitrate"] = config.bitrate
    if config.interface == "virtual":
        kwargs["rx_queue_size"] = config.rx_queue_size
    try:
        return can.Bus(**kwargs)
    except (can.CanError, ValueError, OSError, ImportError) as exc:
        raise DeviceError(
            config.name, f"cannot open CAN interface {config.interface!r} {config.channel!r}: {exc}"
        ) from exc


class CanDaq(Daq):
    """A :class:`Daq` spoken to over CAN (docs/protocols.md, "DAQ shim over CAN")."""

    def __init__(self, config: CanDaqConfig | None = None, *, bus: can.BusABC | None = None) -> None:
        cfg = config if config is not None else CanDaqConfig()
        super().__init__(cfg.name, cfg.rate_hz, cfg.channel_map)
        self._config = cfg
        self._ids = NodeIds(cfg.node_id)
        self._owns_bus = bus is None
        self._bus = bus if bus is not None else open_bus(cfg)
        self._listener = _FrameListener(self._ids, cfg.rx_queue_size)
        self._notifier = can.Notifier(self._bus, [self._listener], timeout=0.05)
        self._pairer = SamplePairer()
        self._ready: deque[Sample] = deque()
        self._command_lock = threading.Lock()
        self._read_lock = threading.Lock()
        self._protocol_errors = 0
        self._last_protocol_error: ProtocolError | None = None
        self._stream_started_ns = 0

    @property
    def config(self) -> CanDaqConfig:
        """The configuration this DAQ was built from."""
        return self._config

    @property
    def force_range_N(self) -> float:
        """The configured sensor range, at most the wire's full scale (:attr:`CanDaqConfig.saturation_N`)."""
        return self._config.saturation_N

    @property
    def dropped_samples(self) -> int:
        """Samples lost so far: counter gaps, half samples, ring overflow (never invented)."""
        return self._pairer.dropped

    @property
    def protocol_errors(self) -> int:
        """Malformed data frames received and skipped so far."""
        return self._protocol_errors

    @property
    def last_protocol_error(self) -> ProtocolError | None:
        """The most recent malformed data frame (with its bytes), if any."""
        return self._last_protocol_error

    @property
    def overflowed_frames(self) -> int:
        """Frames pushed out of the full receive ring (their samples count as dropped)."""
        return self._listener.overflowed

    @property
    def stale_frames(self) -> int:
        """Duplicate or late frames discarded by the pairing."""
        return self._pairer.stale_frames

    def device_status(self) -> DaqDeviceStatus:
        """Ask the node whether it streams and at which rate (command 0x05)."""
        self._check_open()
        reply = self._command(Command.STATUS)
        return DaqDeviceStatus(bool(reply.streaming), int(reply.rate_hz or 0))

    # hooks --------------------------------------------------------------------------------------
    def _do_start(self) -> None:
        with self._read_lock:
            self._listener.ring.clear()
            self._ready.clear()
            self._pairer.reset()
        self._stream_started_ns = time.monotonic_ns()
        self._command(Command.START)

    def _do_stop(self) -> None:
        self._command(Command.STOP)

    def _do_tare(self) -> None:
        self._command(Command.TARE)

    def _do_set_rate(self, rate_hz: float) -> None:
        if rate_hz != int(rate_hz):
            raise InvalidValueError(self.name, "rate_hz", rate_hz, "must be a whole number of Hz")
        if rate_hz > MAX_RATE_HZ:
            raise LimitError(self.name, "rate_hz", rate_hz, MAX_RATE_HZ, "Hz")
        self._command(Command.SET_RATE, int(rate_hz))

    def _do_read_block(self, max_samples: int, timeout_s: float) -> DaqBlock:
        deadline_ns = time.monotonic_ns() + int(timeout_s * 1e9)
        with self._read_lock:
            while True:
                self._listener.data_event.clear()
                self._drain(max_samples)
                if self._ready:
                    return self._take(max_samples)
                self._raise_on_bus_error()
                now = time.monotonic_ns()
                if self.streaming:
                    silent_since = max(self._listener.last_frame_ns, self._stream_started_ns)
                    if now - silent_since > self._config.stream_silence_s * 1e9:
                        raise DeviceTimeout(
                            self.name,
                            self._config.stream_silence_s,
                            detail="no data frames while streaming",
                        )
                remaining_s = (deadline_ns - now) * 1e-9
                if remaining_s <= 0:
                    return DaqBlock.empty(
                        rate_hz=self.rate_hz,
                        host_monotonic_ns=now,
                        dropped_total=self.dropped_samples,
                    )
                self._listener.data_event.wait(min(remaining_s, self._config.stream_silence_s))

    def _do_close(self) -> None:
        self._notifier.stop(timeout=1.0)
        if self._owns_bus:
            self._bus.shutdown()

    # receiving ----------------------------------------------------------------------------------
    def _drain(self, wanted: int) -> None:
        """Decode and pair raw frames until ``wanted`` samples are ready or the ring is empty."""
        ring, pairer, ready = self._listener.ring, self._pairer, self._ready
        while len(ready) < wanted:
            try:
                is_force, payload, host_ns, remote = ring.popleft()
            except IndexError:
                return
            try:
                if remote:
                    raise ProtocolError(self.name, "remote frame on a data id", payload)
                counter, v0, v1, v2 = unpack_data(payload, self.name)
            except ProtocolError as exc:
                self._protocol_errors += 1
                self._last_protocol_error = exc
                continue
            sample = pairer.add(is_force, counter, (v0, v1, v2), host_ns)
            if sample is not None:
                ready.append(sample)

    def _take(self, max_samples: int) -> DaqBlock:
        count = min(max_samples, len(self._ready))
        samples = [self._ready.popleft() for _ in range(count)]
        cfg = self._config
        return DaqBlock.from_counts(
            np.fromiter((s.counter for s in samples), dtype=np.int64, count=count),
            np.array([s.force for s in samples], dtype=np.int64).reshape(count, 3),
            np.array([s.analog for s in samples], dtype=np.int64).reshape(count, 3),
            force_N_per_count=cfg.force_N_per_count,
            volts_per_count=cfg.volts_per_count,
            rate_hz=self.rate_hz,
            host_monotonic_ns=samples[-1].host_ns,
            dropped_total=self._pairer.dropped,
            counter_origin=self._pairer.origin or 0,
        )

    def _raise_on_bus_error(self) -> None:
        error = self._listener.error
        if error is not None:
            self._listener.error = None
            raise DeviceError(self.name, f"CAN receive failed: {error}") from error

    # commands -----------------------------------------------------------------------------------
    def _command(self, command: Command, rate_hz: int | None = None) -> Reply:
        """Send a command, wait for its reply; one retry; named errors for every failure."""
        payload = pack_command(command, rate_hz)
        cfg = self._config
        with self._command_lock:
            reply = None
            for _attempt in range(1 + cfg.command_retries):
                self._clear_replies()
                self._send(payload)
                reply = self._await_reply(command, cfg.command_timeout_s)
                if reply is not None:
                    break
            if reply is None:
                total_s = cfg.command_timeout_s * (1 + cfg.command_retries)
                raise DeviceTimeout(self.name, total_s, detail=f"command {command.name}")
        if reply.status != 0:
            raise rejected(self.name, command.name, reply.status)
        return reply

    def _send(self, payload: bytes) -> None:
        message = can.Message(arbitration_id=self._ids.command, data=payload, is_extended_id=False)
        try:
            self._bus.send(message, timeout=self._config.command_timeout_s)
        except can.CanError as exc:
            raise DeviceError(self.name, f"CAN send failed: {exc}") from exc

    def _await_reply(self, command: Command, timeout_s: float) -> Reply | None:
        deadline = time.monotonic() + timeout_s
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                data = self._listener.replies.get(timeout=remaining)
            except queue.Empty:
                return None
            reply = unpack_reply(data, self.name)
            if reply.command is command:
                return reply
        return None

    def _clear_replies(self) -> None:
        while True:
            try:
                self._listener.replies.get_nowait()
            except queue.Empty:
                return
