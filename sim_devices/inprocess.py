"""The in-process backend: the drivers' interfaces implemented directly on the virtual rig.

No wires, no threads of their own: for fast tests and accelerated runs. Each class subclasses the
ABC of :mod:`drivers.interfaces` (so argument checks, limits, interlocks and the emergency stop are
the same code as for the real drivers) and reads the rig through the same sensor models as the
wire-level simulators, so readings agree between the backends: stage positions are quantised to the
controllers' counts, forces and analog inputs to the DAQ's counts, probe values to 0.019 um.

Faults (:mod:`sim_devices.faults`) that exist without a wire: ``silent`` (every call waits
``timeout_s`` and raises :class:`~drivers.errors.DeviceTimeout`), ``stuck``, ``drop_pct`` (DAQ
samples lost: counter gaps, counted), ``alarm_code`` (stages). Corrupt and short frames need a wire:
use the ``sim-wire`` backend for those.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import TypeVar

import numpy as np

from drivers.errors import DeviceTimeout, OverRangeError, rejected
from drivers.interfaces import (
    ChannelMap,
    Daq,
    DaqBlock,
    DisplacementProbe,
    LoadingStage,
    ProbeSamples,
    StageLimits,
    StageStatus,
)
from drivers.safety import EmergencyStop
from sim_devices.can_daq_sim import DaqSignals
from sim_devices.faults import Faults, StuckReading
from sim_devices.sample_ring import SamplesLostError
from sim_devices.sensors import ForceSensorSpec
from sim_devices.stage_axis import Alarm, AxisStatus
from sim_devices.stream_cursor import StreamCursor, interp
from sim_devices.virtual_rig import StageControl, VirtualRig

T = TypeVar("T")

DEFAULT_TIMEOUT_S = 0.3  # a silent device times out like the wire drivers' default timeout_s
STREAM_SILENCE_S = 0.5  # and a silent stream like their default stream_silence_s


class InProcessStage(LoadingStage):
    """A :class:`LoadingStage` acting directly on one of the rig's stages."""

    def __init__(
        self,
        control: StageControl,
        counts_per_m: float,
        *,
        name: str | None = None,
        limits: StageLimits | None = None,
        emergency_stop: EmergencyStop | None = None,
        faults: Faults | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        p = control.params
        super().__init__(
            name or p.name,
            limits or StageLimits(p.travel_min_m, p.travel_max_m, p.max_velocity_m_s),
            emergency_stop=emergency_stop,
        )
        self.control = control
        self.counts_per_m = float(counts_per_m)
        self.faults = faults if faults is not None else Faults()
        self.timeout_s = timeout_s
        self._stuck: StuckReading[AxisStatus] = StuckReading(self.faults)

    def _call(self, what: str, action: Callable[[], T]) -> T:
        f = self.faults
        if f.silent:
            time.sleep(self.timeout_s)
            raise DeviceTimeout(self.name, self.timeout_s, detail=what)
        code = f.take_alarm()
        if code:
            self.control.raise_alarm(Alarm(code) if code in Alarm._value2member_map_ else
                                     Alarm.DRIVER_FAULT)
        return action()

    def _axis_status(self) -> AxisStatus:
        return self._stuck.hold(self._call("status", self.control.status))

    def _counts(self, position_m: float) -> float:
        return round(position_m * self.counts_per_m) / self.counts_per_m

    def _do_enable(self) -> None:
        self._call("enable", lambda: self.control.enable(True))

    def _do_disable(self) -> None:
        self._call("disable", lambda: self.control.enable(False))

    def _do_home(self) -> None:
        self._call("home", self.control.home)

    def _do_move_absolute(self, target_m: float, velocity_m_s: float) -> None:
        self._call("move", lambda: self.control.move_to(self._counts(target_m), velocity_m_s))

    def _do_stop(self) -> None:
        self._call("stop", self.control.stop)

    def _do_emergency_stop(self) -> None:
        self._call("emergency stop", self.control.emergency_stop)

    def _do_reset_alarm(self) -> None:
        self._call("reset alarm", self.control.reset_alarm)

    def _do_position_m(self) -> float:
        return self._counts(self._axis_status().position_m)

    def _do_status(self) -> StageStatus:
        return self._axis_status().stage_status()


class InProcessDaq(Daq):
    """A :class:`Daq` sampling the rig through the shared force-sensor / analog models."""

    def __init__(
        self,
        rig: VirtualRig,
        name: str = "daq",
        *,
        rate_hz: float = 1024.0,
        sensor: ForceSensorSpec | None = None,
        channel_map: ChannelMap | None = None,
        faults: Faults | None = None,
        seed: int = 0,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        super().__init__(name, rate_hz, channel_map)
        if not rate_hz <= rig.rate_hz:
            raise rejected(name, "SET_RATE", 2)
        self.rig = rig
        self.spec = sensor or ForceSensorSpec()
        self.signals = DaqSignals(rig, self.spec, seed)
        self.faults = faults if faults is not None else Faults(seed=seed + 3)
        self.timeout_s = timeout_s
        self._cursor: StreamCursor | None = None
        self._dropped = 0
        self._rng = np.random.default_rng(seed + 5)

    @property
    def force_range_N(self) -> float:
        return self.spec.force_range_N

    @property
    def dropped_samples(self) -> int:
        return self._dropped

    @property
    def protocol_errors(self) -> int:
        return 0

    def _check_alive(self, what: str) -> None:
        if self.faults.silent:
            time.sleep(self.timeout_s)
            raise DeviceTimeout(self.name, self.timeout_s, detail=what)

    def _do_start(self) -> None:
        self._check_alive("start")
        self._cursor = StreamCursor(self.rig, self.rate_hz)
        self.rig.daq_stream_start_s = self._cursor.t0_s

    def _do_stop(self) -> None:
        self._check_alive("stop")
        self._cursor = None
        self.rig.daq_stream_start_s = None

    def _do_tare(self) -> None:
        self._check_alive("tare")
        self.signals.tare()

    def _do_set_rate(self, rate_hz: float) -> None:
        self._check_alive("set rate")
        if rate_hz != int(rate_hz) or not 0 < rate_hz <= self.rig.rate_hz:
            raise rejected(self.name, "SET_RATE", 2)

    def _do_read_block(self, max_samples: int, timeout_s: float) -> DaqBlock:
        cursor = self._cursor
        if cursor is None or self.faults.silent:
            if cursor is not None:  # streaming but nothing comes: the driver's silence timeout
                time.sleep(STREAM_SILENCE_S)
                raise DeviceTimeout(self.name, STREAM_SILENCE_S, detail="no data while streaming")
            time.sleep(timeout_s)
            return self._empty()
        if not cursor.wait_next(timeout_s):
            self.rig.check()
            return self._empty()
        n0, t = cursor.due(max_samples)
        try:
            s = cursor.window(t)
        except SamplesLostError as lost:
            self._dropped += cursor.skip_lost(lost)
            return self._empty()
        cursor.consume(t.shape[0])
        force, analog = self.signals.counts(t, s, self.faults.stuck, self.faults.blind)
        counter = n0 + np.arange(t.shape[0], dtype=np.int64)
        keep = np.ones(t.shape[0], dtype=bool)
        if self.faults.drop_pct > 0:
            keep = np.asarray(self._rng.random(t.shape[0]) * 100.0 >= self.faults.drop_pct)
            self._dropped += int(np.count_nonzero(~keep))
        return DaqBlock.from_counts(
            counter[keep],
            force[keep],
            analog[keep],
            force_N_per_count=self.spec.force_N_per_count,
            volts_per_count=self.spec.volts_per_count,
            rate_hz=self.rate_hz,
            host_monotonic_ns=self.rig.clock.host_ns_at(float(t[-1])),
            dropped_total=self._dropped,
        )

    def _empty(self) -> DaqBlock:
        return DaqBlock.empty(
            rate_hz=self.rate_hz, host_monotonic_ns=time.monotonic_ns(), dropped_total=self._dropped
        )


class InProcessProbe(DisplacementProbe):
    """A :class:`DisplacementProbe` reading one of the rig's probe heads (0 = D1, 1 = D2)."""

    def __init__(
        self,
        rig: VirtualRig,
        index: int,
        name: str | None = None,
        *,
        faults: Faults | None = None,
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        if index not in (0, 1):
            raise ValueError("probe index must be 0 (D1) or 1 (D2)")
        super().__init__(name or f"d{index + 1}")
        self.rig = rig
        self.index = index
        self.head = rig.probes[index]
        self.faults = faults if faults is not None else Faults(seed=100 + index)
        self.timeout_s = timeout_s
        self._cursor: StreamCursor | None = None
        self._stuck: StuckReading[float] = StuckReading(self.faults)

    @property
    def range_m(self) -> float:
        return self.head.spec.range_m

    @property
    def resolution_m(self) -> float:
        return self.head.spec.resolution_m

    def _check_alive(self, what: str) -> None:
        if self.faults.silent:
            time.sleep(self.timeout_s)
            raise DeviceTimeout(self.name, self.timeout_s, detail=what)

    def _stick(self, values: np.ndarray) -> np.ndarray:
        return self._stuck.hold_array(values)

    @property
    def mount_travel_m(self) -> float:
        return self.head.spec.mount_travel_m

    @property
    def mount_speed_m_s(self) -> float:
        return self.head.spec.mount_speed_m_s

    def _do_zero(self) -> None:
        self._check_alive("ZR")
        self.head.zero_at(float(self.rig.probe_ideal_m(self.index)[0]))

    def _do_move_mount(self, distance_m: float) -> None:
        self._check_alive("MV")
        self.rig.move_probe_mount(self.index, distance_m)

    def _do_read_m(self) -> float:
        self._check_alive("MS")
        value = float(self._stick(self.head.readings_m(self.rig.probe_ideal_m(self.index)))[0])
        if not np.isfinite(value):
            raise OverRangeError(self.name, 1 if value > 0 else -1, self.range_m)
        return value

    def _do_start_stream(self, rate_hz: float) -> None:
        self._check_alive("ST")
        if rate_hz != int(rate_hz) or not 1 <= rate_hz <= self.rig.rate_hz:
            raise rejected(self.name, "ST", 2)
        self._cursor = StreamCursor(self.rig, rate_hz)

    def _do_stop_stream(self) -> None:
        self._check_alive("SP")
        self._cursor = None

    def _do_read_stream(self, max_samples: int, timeout_s: float) -> ProbeSamples:
        cursor = self._cursor
        if cursor is not None and self.faults.silent:
            time.sleep(STREAM_SILENCE_S)
            raise DeviceTimeout(self.name, STREAM_SILENCE_S, detail="no stream lines")
        if cursor is None or not cursor.wait_next(timeout_s):
            return _no_samples()
        n0, t = cursor.due(max_samples)
        try:
            s = cursor.window(t)
        except SamplesLostError as lost:
            cursor.skip_lost(lost)
            return _no_samples()
        cursor.consume(t.shape[0])
        values = self._stick(self.head.readings_m(
            interp(t, s, s.d1_m if self.index == 0 else s.d2_m), t))
        host = np.array([self.rig.clock.host_ns_at(float(x)) for x in t], dtype=np.int64)
        return ProbeSamples(n0 + np.arange(t.shape[0], dtype=np.int64), values, host)


def _no_samples() -> ProbeSamples:
    return ProbeSamples(
        np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.float64), np.zeros(0, dtype=np.int64)
    )
