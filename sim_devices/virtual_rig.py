"""ONE virtual rig: the stick-slip engine, both loading stages and the contact law on one clock.

Every simulated device (stage controllers, force sensor / DAQ, probes, camera) reads this one state,
so what the force sensor shows, what the probes measure and what the camera sees always agree.

- The tangential stage's position (relative to where the rig started) is the engine's x_stage input.
- The normal stage's position z gives Fn through :class:`~sim_devices.contact_law.NormalContactLaw`,
  the engine's fn input; if Fn would exceed the rig's maximum load the normal stage latches alarm 3
  (over-load) at the crossing instant and stops dead, so Fn never exceeds it.
- Time: a :class:`~sim_devices.clock.SimClock` (real time, accelerated, or manual). With a running
  clock, :meth:`VirtualRig.start` spawns one thread that advances the engine to the clock every
  ``tick_s`` host seconds; in manual mode tests call :meth:`VirtualRig.advance_to`.
- The engine is advanced on the sample grid (t = k / rate) with inputs that ramp linearly over
  each call: one call per sample while the normal stage moves with the specimens in contact (Fn is
  not linear in z), one per ``accel_step_samples`` while a stage accelerates, else up to
  ``max_chunk_s`` per call (cruise and rest are exactly linear).
- Thread safety: one re-entrant lock guards everything; :attr:`VirtualRig.state` returns an
  immutable snapshot (O(1)); :meth:`VirtualRig.samples` returns copies of the per-sample history.
- Devices that produce output for rig instants after the rig reached them (the camera renders
  frame j once the rig is at t_j) say which rig time they still owe (:meth:`VirtualRig.owe`); a
  pacer (``rigctl.rigs.Pacer``) holds an accelerated rig within a lag of :meth:`VirtualRig.owed_s`,
  so the camera keeps its full frame rate in rig time however fast the rig runs.
- The simulated DAQ records the rig time of its stream's sample 0
  (:attr:`VirtualRig.daq_stream_start_s`): the DAQ's device time of rig time t is t minus it, which
  places camera frames on the DAQ's clock exactly (a camera synchronised to the DAQ).
"""

from __future__ import annotations

import logging
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Self, TypeVar

import numpy as np
from numpy.typing import NDArray

from drivers.validate import check_number
from rigctl.model import MAX_NORMAL_FORCE_N, ModelSpec, SimResult, Simulator, build_model
from sim_devices.clock import SimClock
from sim_devices.contact_law import NormalContactLaw
from sim_devices.sample_ring import RigSamples, SampleRing
from sim_devices.sensors import ProbeHead, ProbeSpec
from sim_devices.service import SimService
from sim_devices.stage_axis import (
    NORMAL_STAGE,
    TANGENTIAL_STAGE,
    Alarm,
    AxisStatus,
    StageAxis,
    StageAxisParams,
)

_log = logging.getLogger(__name__)
T = TypeVar("T")

class RigFailedError(RuntimeError):
    """The virtual rig stopped because its engine raised; ``__cause__`` holds the error."""


@dataclass(frozen=True)
class VirtualRigConfig:
    """Everything about the virtual rig that is not the friction model."""

    sample_rate_hz: float = 1024.0
    tangential: StageAxisParams = TANGENTIAL_STAGE
    normal: StageAxisParams = NORMAL_STAGE
    contact: NormalContactLaw = field(default_factory=NormalContactLaw)
    max_load_N: float = MAX_NORMAL_FORCE_N
    probes: tuple[ProbeSpec, ProbeSpec] = (
        ProbeSpec(serial="SIM-D1"),
        ProbeSpec(serial="SIM-D2"),
    )
    history_s: float = 60.0
    max_chunk_s: float = 0.25
    accel_step_samples: int = 8
    contact_step_samples: int = 1
    tick_s: float = 0.005
    seed: int = 0

    def __post_init__(self) -> None:
        owner = "virtual rig"
        check_number(owner, "sample_rate_hz", self.sample_rate_hz, unit="Hz", gt=0.0)
        check_number(owner, "max_load_N", self.max_load_N, unit="N", gt=0.0, le=MAX_NORMAL_FORCE_N)
        check_number(owner, "history_s", self.history_s, unit="s", ge=64 / self.sample_rate_hz)
        check_number(owner, "max_chunk_s", self.max_chunk_s, unit="s", gt=0.0)
        check_number(owner, "tick_s", self.tick_s, unit="s", gt=0.0)
        check_number(owner, "accel_step_samples", self.accel_step_samples, ge=1)
        check_number(owner, "contact_step_samples", self.contact_step_samples, ge=1)


@dataclass(frozen=True)
class RigState:
    """Snapshot of the whole rig at simulated time ``t_s`` (the newest sample, index ``k``)."""

    t_s: float
    k: int
    x_stage_m: float
    """Absolute tangential stage position."""
    z_normal_m: float
    fn_N: float
    ft_N: float
    f_interface_N: float
    delta_m: float
    d1_m: float
    d2_m: float
    stage: int
    p_elements: NDArray[np.float64]
    sliding_elements: NDArray[np.bool_]
    n_slips: int
    tangential: AxisStatus
    normal: AxisStatus


class StageControl:
    """Commands to one of the rig's stages, applied at the rig's current simulated time."""

    def __init__(self, rig: VirtualRig, axis: StageAxis) -> None:
        self._rig = rig
        self.axis = axis

    @property
    def name(self) -> str:
        return self.axis.params.name

    @property
    def params(self) -> StageAxisParams:
        return self.axis.params

    def _do(self, action: Callable[[StageAxis, float], T]) -> T:
        return self._rig._command(self.axis, action)

    def enable(self, on: bool = True) -> None:
        self._do(lambda a, t: a.enable(t, on))

    def move_to(self, target_m: float, velocity_m_s: float) -> Alarm:
        return self._do(lambda a, t: a.move_to(t, target_m, velocity_m_s))

    def home(self) -> Alarm:
        return self._do(lambda a, t: a.home(t))

    def stop(self) -> None:
        self._do(lambda a, t: a.stop(t))

    def emergency_stop(self) -> None:
        self._do(lambda a, t: a.emergency_stop(t))

    def reset_alarm(self) -> None:
        self._do(lambda a, t: a.reset_alarm(t))

    def raise_alarm(self, code: Alarm) -> Alarm:
        return self._do(lambda a, t: a.raise_alarm(t, code))

    def status(self) -> AxisStatus:
        """Status at the rig's current time (O(1))."""
        st = self._rig.state
        return st.tangential if self.axis is self._rig._tan else st.normal


class VirtualRig(SimService):
    """The one simulated rig (module docstring). Use as a context manager or call :meth:`close`."""

    def __init__(
        self,
        model: ModelSpec | None = None,
        *,
        speed: float | None = None,
        config: VirtualRigConfig | None = None,
    ) -> None:
        super().__init__("virtual-rig")
        self.config = cfg = config or VirtualRigConfig()
        self.model = model if model is not None else build_model()
        self.clock = SimClock(speed)
        self._sim = Simulator(self.model, sample_rate_hz=cfg.sample_rate_hz)
        self._tan = StageAxis(cfg.tangential)
        self._nor = StageAxis(cfg.normal)
        self.tangential = StageControl(self, self._tan)
        self.normal = StageControl(self, self._nor)
        self.x_ref_m = cfg.tangential.start_position_m
        self.probes = tuple(
            ProbeHead(spec, seed=cfg.seed + 11 + i) for i, spec in enumerate(cfg.probes)
        )
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        fn0 = cfg.contact.fn_N(self._nor.position_m(0.0))
        if fn0 > cfg.max_load_N:
            raise ValueError("the normal stage starts beyond the maximum load")
        self._stepper = self._sim.stepper(x_stage_m=0.0, fn_N=fn0)
        # The history starts with samples 0 and 1 at rest (the engine needs t_end > t_now).
        first = self._stepper.advance(1.0 / cfg.sample_rate_hz, 0.0, fn0)
        self.p_tables: NDArray[np.float64] = np.asarray(first.p_tables, dtype=np.float64)
        n_el = self.p_tables.shape[1]
        self._ring = SampleRing(max(64, int(cfg.history_s * cfg.sample_rate_hz)), n_el)
        self._k_done = -1
        z_start = self._nor.position_m(0.0)
        self._store(first, 0.0, 1.0 / cfg.sample_rate_hz, z_start, z_start)
        self._state = self._snapshot()
        self.error: BaseException | None = None
        self._closed = False
        self.daq_stream_start_s: float | None = None
        """Rig time of the DAQ stream's sample 0 while it streams (set by the simulated DAQ)."""
        self._owed: dict[int, float] = {}

    # --------------------------------------------------------------------------- properties
    @property
    def rate_hz(self) -> float:
        return self.config.sample_rate_hz

    @property
    def t_s(self) -> float:
        """Simulated time of the newest sample."""
        return self._k_done / self.config.sample_rate_hz

    def daq_time_now_s(self) -> float:
        """The DAQ's device time of the rig's newest sample (NaN while the DAQ does not stream):
        the present instant on the recorded time axis, which a paced rig runs ahead of the data
        the recorder has read."""
        t0 = self.daq_stream_start_s
        return math.nan if t0 is None else self.t_s - t0

    @property
    def k(self) -> int:
        """Index of the newest sample (t = k / rate)."""
        return self._k_done

    @property
    def state(self) -> RigState:
        """The newest snapshot (immutable; O(1))."""
        return self._state

    @property
    def n_elements(self) -> int:
        return int(self.p_tables.shape[1])

    # ---------------------------------------------------------------------------- lifecycle
    def start(self) -> Self:
        """Start the clock thread (real-time or accelerated); a no-op in manual mode."""
        if self.clock.manual or self._closed:
            return self
        return super().start()

    def _loops(self) -> list[tuple[Callable[[], None], str]]:
        return [(self._run, "clock")]

    def close(self) -> None:
        """Stop the clock thread for good; wakes every waiter."""
        self._closed = True
        self.stop()
        with self._cond:
            self._cond.notify_all()

    def check(self) -> None:
        """Raise :class:`RigFailedError` if the engine has failed."""
        if self.error is not None:
            raise RigFailedError(f"virtual rig stopped: {self.error}") from self.error

    def _run(self) -> None:
        while self.running:
            try:
                self.advance_to(self.clock.now_s())
            except Exception as exc:  # keep the reason; waiters see it through check()
                _log.exception("virtual rig clock thread stopped")
                self.error = exc
                with self._cond:
                    self._cond.notify_all()
                return
            self._stop_event.wait(self.config.tick_s)

    # ------------------------------------------------------------------------------ advance
    def advance_to(self, t_s: float) -> None:
        """Advance the simulation to the last sample at or before ``t_s`` (never backwards)."""
        if not math.isfinite(t_s):
            raise ValueError(f"time must be finite, got {t_s!r}")
        rate = self.config.sample_rate_hz
        k_target = math.floor(t_s * rate + 1e-9)
        while True:
            with self._cond:
                if self._k_done >= k_target or self._closed:
                    return
                self._advance_chunk_locked(k_target)
                self._state = self._snapshot()
                self._cond.notify_all()

    def advance_by(self, dt_s: float) -> None:
        self.advance_to(self.t_s + dt_s)

    def _sync_locked(self) -> None:
        """Catch up with a running clock before a command is applied."""
        if not self.clock.manual and self.error is None and not self._closed:
            k_target = math.floor(self.clock.now_s() * self.config.sample_rate_hz + 1e-9)
            while self._k_done < k_target:
                self._advance_chunk_locked(k_target)

    def _next_k(self, k0: int, k_target: int) -> int:
        """End of the next engine call: inputs must be linear in time over (k0, k1]."""
        cfg = self.config
        rate = cfg.sample_rate_hz
        t0 = k0 / rate
        k1 = min(k_target, k0 + max(1, int(cfg.max_chunk_s * rate)))
        for axis in (self._tan, self._nor):
            bp = axis.next_breakpoint_s(t0)
            if bp is not None:
                k1 = min(k1, max(k0 + 1, math.ceil(bp * rate - 1e-9)))
        if self._tan.accelerating(t0) or self._nor.accelerating(t0):
            # x(t) is quadratic: chords of 8 samples are within a t^2 / 8 (~10 nm) of it
            k1 = min(k1, k0 + cfg.accel_step_samples)
        if self._nor.moving(t0):
            zc = cfg.contact.z_contact_m
            if max(self._nor.position_m(t0), self._nor.position_m(k1 / rate)) > zc:
                k1 = min(k1, k0 + cfg.contact_step_samples)  # Fn(z) is not linear
        return k1

    def _advance_chunk_locked(self, k_target: int) -> None:
        cfg = self.config
        rate = cfg.sample_rate_hz
        k0 = self._k_done
        k1 = self._next_k(k0, k_target)
        t0, t1 = k0 / rate, k1 / rate
        z0 = self._nor.position_m(t0)
        z1 = self._nor.position_m(t1)
        fn1 = cfg.contact.fn_N(z1)
        if fn1 > cfg.max_load_N:
            t_trip = self._overload_time(t0, t1)
            self._nor.raise_alarm(t_trip, Alarm.OVERLOAD)
            z1 = self._nor.position_m(t1)
            fn1 = min(cfg.contact.fn_N(z1), cfg.max_load_N)
        x1 = self._tan.position_m(t1) - self.x_ref_m
        chunk = self._stepper.advance(t1, x1, fn1)
        self._store(chunk, t0, t1, z0, z1)

    def _overload_time(self, t0: float, t1: float) -> float:
        """Instant in [t0, t1] at which Fn reaches the maximum load (bisection on z(t))."""
        cfg = self.config
        lo, hi = t0, t1
        for _ in range(40):
            mid = 0.5 * (lo + hi)
            if cfg.contact.fn_N(self._nor.position_m(mid)) > cfg.max_load_N:
                hi = mid
            else:
                lo = mid
        return lo

    def _store(self, chunk: SimResult, t0: float, t1: float, z0: float, z1: float) -> None:
        """Append an engine chunk (samples k_done + 1 ..) with the normal stage positions."""
        n = chunk.n_samples
        if n == 0:
            return
        t = chunk.t_s
        z = np.full(n, z1) if t1 == t0 else z0 + (z1 - z0) * (t - t0) / (t1 - t0)
        ft = chunk.ft_N
        if not np.all(np.isfinite(ft)):
            raise RigFailedError(f"engine returned non-finite forces near t = {t1:.6f} s")
        self._ring.append(
            self._k_done + 1,
            {
                "t_s": t,
                "x_stage_m": chunk.x_stage_m + self.x_ref_m,
                "z_normal_m": z,
                "fn_N": chunk.fn_N,
                "ft_N": ft,
                "d1_m": chunk.d1_m,
                "d2_m": chunk.d2_m,
            },
            chunk.stage,
            chunk.slipping,
            chunk.sliding_elements,
        )
        self._k_done = self._ring.next_k - 1

    def _snapshot(self) -> RigState:
        """The newest sample as every device sees it (effects' output hooks included)."""
        st = self._stepper.state
        last = self._ring.read(self._k_done, self._k_done + 1)
        t = self.t_s
        return RigState(
            t_s=t,
            k=self._k_done,
            x_stage_m=float(last.x_stage_m[0]),
            z_normal_m=float(last.z_normal_m[0]),
            fn_N=float(last.fn_N[0]),
            ft_N=float(last.ft_N[0]),
            f_interface_N=st.f_interface_N,
            delta_m=st.delta_m,
            d1_m=float(last.d1_m[0]),
            d2_m=float(last.d2_m[0]),
            stage=int(last.stage[0]),
            p_elements=self.p_tables[int(last.stage[0])].copy(),
            sliding_elements=last.sliding_elements[0].copy(),
            n_slips=int(st.n_slips),
            tangential=self._tan.status(t),
            normal=self._nor.status(t),
        )

    def _command(self, axis: StageAxis, action: Callable[[StageAxis, float], T]) -> T:
        with self._cond:
            self._sync_locked()
            result = action(axis, self.t_s)
            self._state = self._snapshot()
            self._cond.notify_all()
            return result

    # -------------------------------------------------------------------------------- reads
    def samples(self, k0: int, k1: int) -> RigSamples:
        """Copies of samples k0 <= k < k1 that exist (SamplesLostError if k0 was overwritten)."""
        with self._lock:
            return self._ring.read(k0, k1)

    def owe(self, owner: object, t_s: float | None) -> None:
        """``owner`` still owes its output for rig time ``t_s`` onwards (None: owes nothing)."""
        with self._lock:
            if t_s is None:
                self._owed.pop(id(owner), None)
            else:
                self._owed[id(owner)] = float(t_s)

    def owed_s(self) -> float:
        """The earliest rig time a device still owes output for (inf: none)."""
        with self._lock:
            return min(self._owed.values(), default=math.inf)

    def wait_for_sample(self, k: int, timeout_s: float) -> bool:
        """Block until sample ``k`` exists (True) or ``timeout_s`` passes / the rig stops (False)."""
        with self._cond:
            return self._cond.wait_for(
                lambda: self._k_done >= k or self._closed or self.error is not None,
                timeout=max(0.0, timeout_s),
            ) and self._k_done >= k

    def wait_until(self, t_s: float, timeout_s: float) -> bool:
        """Block until simulated time ``t_s`` is reached."""
        return self.wait_for_sample(math.ceil(t_s * self.config.sample_rate_hz - 1e-9), timeout_s)

    def move_probe_mount(self, index: int, distance_m: float) -> float:
        """Move probe ``index``'s mount by ``distance_m`` (positive: towards its target, the readings
        drop by it) from the rig's current time, after catching up with the clock (as a stage command
        is applied), at the mount's speed (:class:`~sim_devices.sensors.ProbeSpec`); returns that
        rig time. ValueError beyond the mount's travel (nothing moves)."""
        with self._cond:
            self._sync_locked()
            t = self.t_s
            self.probes[index].move_mount(distance_m, after_t_s=t)
            return t

    def probe_ideal_m(self, index: int, samples: RigSamples | None = None) -> NDArray[np.float64]:
        """The model's ideal reading of probe ``index`` (0 = D1, 1 = D2) for samples / now."""
        if samples is None:
            st = self._state
            return np.array([st.d1_m if index == 0 else st.d2_m])
        return samples.d1_m if index == 0 else samples.d2_m
