"""The force/analog DAQ node on a python-can bus, speaking docs/protocols.md ("DAQ shim over CAN").

The real :class:`drivers.can_daq.CanDaq` talks to it unchanged, over ``virtual`` (one process) or
``udp_multicast`` (across processes). While streaming, each sample n (time ``t0 + n / rate`` on the
rig's clock, ``t0`` the next rig sample at start) becomes two frames, ``0x180 + node`` (counter, Fx,
Fy, Fz) and ``0x280 + node`` (counter, ain0 = D1, ain1 = D2, ain2 spare), with the counter mod 65536.
Samples are produced as the rig's simulated time reaches them: paced by the rig's clock in real
time, as fast as the rig advances when accelerated, and only when a test advances a manual rig.
Rig samples are resampled linearly onto the DAQ's rate (rates above the rig's sample rate are
refused with status 2, since they would be invented). Values pass through the shared sensor models
(:mod:`sim_devices.sensors`): noise, tare, mounting, quantisation to the documented scales, int16
saturation.

Commands on ``0x600 + node`` are answered on ``0x580 + node``: start, stop, tare (mean of the last
32 rig samples), set rate (status 2 for 0 or above the rig rate, 3 while streaming), status, and
status 1 for an unknown command.

Faults (:mod:`sim_devices.faults`): ``silent`` (no frames, no replies), ``drop_pct`` (each data
frame lost independently: the driver sees half samples and counter gaps), ``short_pct`` (a data
frame cut to 1-7 bytes), ``corrupt_pct`` (a data frame's 8 bytes garbled, counter included: it shows
as a counter anomaly, as CAN's own CRC would have let nothing else through), ``stuck`` (the sensor
values freeze while the counter runs on).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field

import can
import numpy as np

from drivers.can_frames import (
    Command,
    NodeIds,
    Status,
    pack_data,
    pack_reply,
    unpack_command,
)
from drivers.errors import ProtocolError
from sim_devices.faults import Faults
from sim_devices.sample_ring import RigSamples, SamplesLostError
from sim_devices.sensors import ForceSensor, ForceSensorSpec, to_int16_counts
from sim_devices.service import SimService
from sim_devices.stream_cursor import StreamCursor, interp
from sim_devices.virtual_rig import VirtualRig

_log = logging.getLogger(__name__)

MAX_BATCH_SAMPLES = 512  # samples sent per stream-loop turn: 0.5 s at 1024 Hz, bounds one burst
TARE_SAMPLES = 32  # the tare averages the last 32 samples (31 ms at 1024 Hz) to average out noise


@dataclass(frozen=True)
class CanDaqSimConfig:
    """Bus and node of the simulated DAQ (defaults match :class:`drivers.can_daq.CanDaqConfig`)."""

    interface: str = "virtual"
    channel: str = "rigctl"
    node_id: int = 1
    rate_hz: int = 1024
    sensor: ForceSensorSpec = field(default_factory=ForceSensorSpec)
    seed: int = 0


class DaqSignals:
    """Turns rig samples into the DAQ's six channels of counts (shared with the in-process DAQ)."""

    def __init__(self, rig: VirtualRig, spec: ForceSensorSpec, seed: int) -> None:
        self.rig = rig
        self.spec = spec
        self.sensor = ForceSensor(spec, seed=seed)
        self._rng = np.random.default_rng(seed + 7)
        self._stuck: tuple[np.ndarray, np.ndarray] | None = None

    def counts(
        self, t_s: np.ndarray, s: RigSamples, stuck: bool, blind: bool = False
    ) -> tuple[np.ndarray, np.ndarray]:
        """(n, 3) force counts and (n, 3) analog counts at rig times ``t_s`` (within ``s``);
        ``blind``: the force sensor sees no load (its noise about zero)."""
        if blind:
            zero = np.zeros(t_s.shape[0])
            force = self.sensor.counts(zero, zero)
        else:
            force = self.sensor.counts(interp(t_s, s, s.ft_N), interp(t_s, s, s.fn_N))
        sp = self.spec
        volts = np.zeros((t_s.shape[0], 3))
        volts[:, 0] = self.rig.probes[0].analog_V(interp(t_s, s, s.d1_m), sp.probe_m_per_volt, t_s)
        volts[:, 1] = self.rig.probes[1].analog_V(interp(t_s, s, s.d2_m), sp.probe_m_per_volt, t_s)
        volts += self._rng.standard_normal(volts.shape) * sp.analog_noise_rms_V
        analog = to_int16_counts(volts, sp.volts_per_count)
        if stuck:
            if self._stuck is None:
                self._stuck = (force[0].copy(), analog[0].copy())
            force[:] = self._stuck[0]
            analog[:] = self._stuck[1]
        else:
            self._stuck = None
        return force, analog

    def tare(self) -> None:
        """Zero the forces at the mean of the most recent rig samples."""
        k = self.rig.k
        s = self.rig.samples(max(0, k - TARE_SAMPLES + 1), k + 1)
        self.sensor.tare(s.ft_N, s.fn_N)


class CanDaqSim(SimService):
    """The simulated DAQ node (module docstring). Start it, then connect a CanDaq to the channel."""

    def __init__(
        self,
        rig: VirtualRig,
        config: CanDaqSimConfig | None = None,
        *,
        faults: Faults | None = None,
        bus: can.BusABC | None = None,
    ) -> None:
        super().__init__("can-daq-sim")
        self.rig = rig
        self.config = cfg = config or CanDaqSimConfig()
        self.faults = faults if faults is not None else Faults(seed=cfg.seed + 3)
        self.ids = NodeIds(cfg.node_id)
        self.signals = DaqSignals(rig, cfg.sensor, cfg.seed)
        self._bus_given = bus
        self._bus: can.BusABC | None = None
        self._lock = threading.Lock()
        self._wake_stream = threading.Event()
        self._rate_hz = int(cfg.rate_hz)
        self._cursor: StreamCursor | None = None
        self.frames_sent = 0
        self.frames_dropped = 0
        if not 0 < self._rate_hz <= rig.rate_hz:
            raise ValueError(f"DAQ rate must be in (0, {rig.rate_hz:g}] Hz")

    @property
    def streaming(self) -> bool:
        return self._cursor is not None

    @property
    def rate_hz(self) -> int:
        return self._rate_hz

    @property
    def stream_start_s(self) -> float | None:
        """Rig time of the stream's sample 0 (None while stopped): sample n is at this + n / rate."""
        cursor = self._cursor
        return None if cursor is None else cursor.t0_s

    # ---------------------------------------------------------------------------- lifecycle
    def _open(self) -> None:
        cfg = self.config
        self._bus = self._bus_given or can.Bus(
            interface=cfg.interface,
            channel=cfg.channel,
            receive_own_messages=False,
            can_filters=[{"can_id": self.ids.command, "can_mask": 0x7FF, "extended": False}],
        )

    def _loops(self) -> list[tuple[Callable[[], None], str]]:
        return [(self._command_loop, "cmd"), (self._stream_loop, "stream")]

    def _wake(self) -> None:
        self._wake_stream.set()

    def _close(self) -> None:
        if self._bus is not None and self._bus_given is None:
            self._bus.shutdown()
        self._bus = None

    # ----------------------------------------------------------------------------- commands
    def _command_loop(self) -> None:
        assert self._bus is not None
        while self.running:
            try:
                msg = self._bus.recv(timeout=0.05)
            except can.CanError as exc:  # a broken bus ends the node; the driver times out
                _log.error("simulated DAQ: CAN receive failed: %s", exc)
                return
            if msg is None or msg.arbitration_id != self.ids.command or msg.is_remote_frame:
                continue
            if self.faults.silent:
                continue
            reply = self.handle_command(bytes(msg.data))
            if reply is not None:
                self._send(self.ids.reply, reply)

    def handle_command(self, payload: bytes) -> bytes | None:
        """The reply payload for one command payload (None for an empty frame)."""
        try:
            code, rate = unpack_command(payload)
        except ProtocolError:
            if payload and payload[0] == Command.SET_RATE:
                return pack_reply(Command.SET_RATE, Status.BAD_PARAMETER)
            return None
        with self._lock:
            if code == Command.START:
                if self._cursor is None:
                    self._cursor = StreamCursor(self.rig, self._rate_hz)
                    self.rig.daq_stream_start_s = self._cursor.t0_s
                    self._wake_stream.set()
                return pack_reply(code, Status.OK)
            if code == Command.STOP:
                self._cursor = None
                self.rig.daq_stream_start_s = None
                return pack_reply(code, Status.OK)
            if code == Command.TARE:
                self.signals.tare()
                return pack_reply(code, Status.OK)
            if code == Command.SET_RATE:
                assert rate is not None
                if self._cursor is not None:
                    return pack_reply(code, Status.BUSY)
                if not 0 < rate <= self.rig.rate_hz:
                    return pack_reply(code, Status.BAD_PARAMETER)
                self._rate_hz = rate
                return pack_reply(code, Status.OK)
            if code == Command.STATUS:
                return pack_reply(
                    code, Status.OK, streaming=self._cursor is not None, rate_hz=self._rate_hz
                )
        return bytes([code | 0x80, Status.UNKNOWN_COMMAND])

    # ---------------------------------------------------------------------------- streaming
    def _stream_loop(self) -> None:
        while self.running:
            cursor = self._cursor
            if cursor is None or self.faults.silent:
                self._wake_stream.wait(0.02)
                self._wake_stream.clear()
                continue
            if not cursor.wait_next(0.02):
                continue
            n0, t = cursor.due(MAX_BATCH_SAMPLES)
            if t.shape[0] == 0:
                continue
            try:
                force, analog = self.signals.counts(t, cursor.window(t), self.faults.stuck,
                                                   self.faults.blind)
            except SamplesLostError as lost:  # fell behind the rig's history: skip, the gap shows
                with self._lock:
                    cursor.skip_lost(lost)
                continue
            with self._lock:
                if self._cursor is not cursor or cursor.n_next != n0:
                    continue  # stopped or restarted meanwhile
                cursor.consume(t.shape[0])
            self._send_samples(n0, force, analog)

    def _send_samples(self, n0: int, force: np.ndarray, analog: np.ndarray) -> None:
        f = self.faults
        for i in range(force.shape[0]):
            counter = n0 + i
            for arb, values in ((self.ids.force, force[i]), (self.ids.analog, analog[i])):
                if f.roll(f.drop_pct):
                    self.frames_dropped += 1
                    continue
                data = pack_data(counter, int(values[0]), int(values[1]), int(values[2]))
                if f.roll(f.short_pct):
                    data = data[: 1 + int(f.random_bytes(1)[0]) % 7]
                elif f.roll(f.corrupt_pct):
                    data = f.random_bytes(8)
                self._send(arb, data)

    def _send(self, arbitration_id: int, data: bytes) -> None:
        bus = self._bus
        if bus is None:
            return
        msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False)
        try:
            bus.send(msg)
            self.frames_sent += 1
        except can.CanError as exc:
            _log.warning("simulated DAQ: CAN send failed: %s", exc)
