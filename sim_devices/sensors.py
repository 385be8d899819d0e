"""Physics of the rig's sensors: the 3-axis force sensor and the two fibre-optic probes.

Both the wire-level simulators and the in-process backend read the rig's true state through these
models, so the two backends quantise, saturate and add noise identically.

Force sensor (mounting, a choice documented in docs/simulated-rig.md): x along the sliding direction,
so Fx = Ft; z along the load axis with compression positive, so Fz = +Fn; Fy is the small lateral
reading a real mounting shows, modelled as a misalignment crosstalk ``crosstalk_y * Ft``. Each axis
adds Gaussian noise, subtracts its tare offset, and is quantised to ``force_N_per_count`` with int16
saturation (+-819 N at the default 0.025 N/count, the driver's default scale, as a real ADC
range saturates: the rig's sensor reads past the normal stage's rated 800 N).

Probes (MTI-2100 with RS2032R, Han et al. 2022, Section 2.1): range 74 um centred on the zero, resolution
0.019 um. The reading is the probe's gap change (the model's ideal d1 / d2 plus a mounting offset)
minus the zero set by ``ZR``, plus Gaussian noise, quantised to the resolution. Beyond +-37 um of the
zero the probe reports over-range (never a clipped number); its analog output then goes to the
rail, +-10 V (full-scale counts on the DAQ), which no in-range reading can produce.

Mount: each probe sits in a holder on a motorised micrometre drive along its axis (a choice: the
paper does not describe the holders). A fibre-optic probe's range is fixed about its stand-off, so
re-zeroing the electronics cannot bring a target that left the range back; moving the probe can.
Moving the mount by ``m`` towards the target shortens the gap by ``m``: the mount travels at its
speed (``ProbeSpec.mount_speed_m_s``, 1 mm/s, a choice), so the readings fall linearly by ``m`` over
``|m| / speed`` from the instant of the command (60 ms for 60 um) and are ``m`` lower from then on.
The moves are kept with their rig times (:meth:`ProbeHead.move_mount`), so a device reading the rig's
history late still sees each sample with the mount where it was then.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from drivers.can_daq import DEFAULT_FORCE_N_PER_COUNT

INT16_MIN = -32768  # forces and analog inputs travel as int16 counts (docs/protocols.md)
INT16_MAX = 32767

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ForceSensorSpec:
    """Scales, noise and mounting of the force sensor and the DAQ's analog front end."""

    force_N_per_count: float = DEFAULT_FORCE_N_PER_COUNT
    """The force scale, the DAQ driver's default (0.025 N/count: full scale 819.175 N)."""
    noise_rms_N: tuple[float, float, float] = (0.05, 0.05, 0.2)
    crosstalk_y: float = 0.01
    zero_offset_N: tuple[float, float, float] = (0.0, 0.0, 0.0)
    volts_per_count: float = 10.0 / 32768.0
    analog_noise_rms_V: float = 0.0005
    probe_m_per_volt: float = 7.4e-6
    amplifier_limit_N: float = math.inf
    """Where the force sensor's own amplifier saturates [N] (each axis, either sign): a true force
    beyond it reads as the limit, plus the noise, so the reading plateaus with live noise below the
    ADC's full scale. The DAQ does not know it (its :attr:`force_range_N` stays the full scale): a
    mis-set amplifier gain, which only the normal stage's position bounds can catch. inf: the ADC
    saturates first."""

    def __post_init__(self) -> None:
        if not (self.force_N_per_count > 0 and self.volts_per_count > 0):
            raise ValueError("DAQ scales must be positive")
        if not self.amplifier_limit_N > 0:
            raise ValueError(f"amplifier_limit_N must be > 0 N, got {self.amplifier_limit_N!r}")
        if self.probe_m_per_volt == 0 or not math.isfinite(self.probe_m_per_volt):
            raise ValueError("probe_m_per_volt must be finite and non-zero")

    @property
    def force_range_N(self) -> float:
        """Where a force reading saturates: the int16 full scale times the scale (819.175 N)."""
        return INT16_MAX * self.force_N_per_count


def to_int16_counts(values: FloatArray, per_count: float) -> NDArray[np.int64]:
    """Round to counts and saturate at the int16 range (an ADC's full scale)."""
    return np.clip(np.rint(np.asarray(values) / per_count), INT16_MIN, INT16_MAX).astype(np.int64)


class ForceSensor:
    """Fx, Fy, Fz counts from the true Ft and Fn (module docstring); tare-able, seeded noise."""

    def __init__(self, spec: ForceSensorSpec | None = None, seed: int = 0) -> None:
        self.spec = spec or ForceSensorSpec()
        self._rng = np.random.default_rng(seed)
        self._tare_N = np.zeros(3)
        self._lock = threading.Lock()

    def forces_N(self, ft_N: FloatArray, fn_N: FloatArray) -> NDArray[np.float64]:
        """(n, 3) sensor forces [N] before quantisation: amplifier limit, mounting, crosstalk,
        noise, tare."""
        s = self.spec
        limit = s.amplifier_limit_N
        ft = np.clip(np.asarray(ft_N, dtype=np.float64), -limit, limit)
        fn = np.clip(np.asarray(fn_N, dtype=np.float64), -limit, limit)
        f = np.empty((ft.shape[0], 3))
        f[:, 0] = ft
        f[:, 1] = s.crosstalk_y * ft
        f[:, 2] = fn
        f += np.asarray(s.zero_offset_N)
        with self._lock:
            f += self._rng.standard_normal(f.shape) * np.asarray(s.noise_rms_N)
            f -= self._tare_N
        return f

    def counts(self, ft_N: FloatArray, fn_N: FloatArray) -> NDArray[np.int64]:
        """(n, 3) int16-range counts as the DAQ sends them."""
        return to_int16_counts(self.forces_N(ft_N, fn_N), self.spec.force_N_per_count)

    def tare(self, ft_N: FloatArray, fn_N: FloatArray) -> None:
        """Zero each axis at the mean of the given recent true forces (noise averages out)."""
        with self._lock:
            current = self._tare_N.copy()
            self._tare_N[:] = 0.0
        f = self.forces_N(ft_N, fn_N).mean(axis=0) if len(ft_N) else current
        with self._lock:
            self._tare_N = f

    @property
    def tare_N(self) -> tuple[float, float, float]:
        with self._lock:
            t = self._tare_N
            return float(t[0]), float(t[1]), float(t[2])


@dataclass(frozen=True)
class ProbeSpec:
    """One fibre-optic probe (MTI-2100 + RS2032R, Han et al. 2022, Section 2.1)."""

    model: str = "MTI-2100/RS2032R-sim"
    serial: str = "SIM0001"
    range_m: float = 74e-6
    resolution_m: float = 0.019e-6
    noise_rms_m: float = 0.005e-6
    mount_offset_m: float = 0.0
    mount_travel_m: float = 25e-3
    """Travel of the probe's motorised mount, centred on where it starts (a 25 mm micrometre
    drive, a choice); 0 = a manual mount the rig cannot move."""
    mount_speed_m_s: float = 1e-3
    """Speed of the motorised mount (a DC-servo micrometre actuator at 1 mm/s, a choice): a move of
    ``m`` takes ``|m| / mount_speed_m_s``."""

    def __post_init__(self) -> None:
        if not (self.range_m > 0 and self.resolution_m > 0 and self.noise_rms_m >= 0):
            raise ValueError("probe range and resolution must be positive, noise >= 0")
        if not (self.mount_travel_m >= 0 and math.isfinite(self.mount_travel_m)):
            raise ValueError("probe mount travel must be finite and >= 0")
        if not (self.mount_speed_m_s > 0 and math.isfinite(self.mount_speed_m_s)):
            raise ValueError("probe mount speed must be finite and > 0")


class ProbeHead:
    """A probe's physical state: where its zero is and where its mount has been moved (each move a
    ramp in rig time at the mount's speed). Shared by its serial and analog outputs."""

    def __init__(self, spec: ProbeSpec | None = None, seed: int = 0) -> None:
        self.spec = spec or ProbeSpec()
        self._zero_m = 0.0
        self._rng = np.random.default_rng(seed)
        self._lock = threading.Lock()
        self._knot_t_s: list[float] = []
        """Rig times at which the mount starts or ends a move (the mount is linear in between)."""
        self._knot_m: list[float] = []
        """Where the mount is at each knot [m]."""
        self._mount_m = 0.0

    @property
    def half_range_m(self) -> float:
        return 0.5 * self.spec.range_m

    @property
    def zero_m(self) -> float:
        return self._zero_m

    @property
    def mount_m(self) -> float:
        """Where the mount is going, from where it started [m] (positive: towards the target): the
        end of the last move commanded."""
        with self._lock:
            return self._mount_m

    def move_mount(self, distance_m: float, after_t_s: float) -> float:
        """Move the mount by ``distance_m`` (positive: towards the target, the readings drop by it),
        starting at rig time ``after_t_s`` (or where the previous move ends, if later) at the mount's
        speed; returns the rig time the move ends. A move beyond the mount's travel raises ValueError
        and nothing moves (never clipped)."""
        d = float(distance_m)
        t = float(after_t_s)
        if not (math.isfinite(d) and math.isfinite(t)):
            raise ValueError(f"mount move must be finite, got {distance_m!r} at {after_t_s!r}")
        half = 0.5 * self.spec.mount_travel_m
        with self._lock:
            target = self._mount_m + d
            if abs(target) > half:
                raise ValueError(f"mount move to {target * 1e6:+.1f} um is beyond its travel "
                                 f"of +-{half * 1e6:.0f} um")
            if d == 0.0:
                return t
            start = max(t, self._knot_t_s[-1]) if self._knot_t_s else t
            end = start + abs(d) / self.spec.mount_speed_m_s
            self._knot_t_s += [start, end]
            self._knot_m += [self._mount_m, target]
            self._mount_m = target
            return end

    def _mount_at(self, t_s: FloatArray | None, shape: tuple[int, ...]) -> FloatArray:
        with self._lock:
            if t_s is None or not self._knot_t_s:
                return np.full(shape, self._mount_m)
            times = np.asarray(self._knot_t_s)
            mounts = np.asarray(self._knot_m)
        return np.interp(np.asarray(t_s, dtype=np.float64), times, mounts)

    def zero_at(self, ideal_m: float) -> None:
        """``ZR``: the current gap becomes the zero."""
        self._zero_m = float(ideal_m) + self.spec.mount_offset_m - self.mount_m

    def readings_m(self, ideal_m: FloatArray, t_s: FloatArray | None = None) -> FloatArray:
        """Quantised readings relative to the zero at rig times ``t_s`` (None: now, the mount at the
        end of its last move); +inf / -inf where over range."""
        ideal = np.asarray(ideal_m, dtype=np.float64)
        mount = self._mount_at(t_s, ideal.shape)
        with self._lock:
            noise = self._rng.standard_normal(ideal.shape) * self.spec.noise_rms_m
        rel = ideal + self.spec.mount_offset_m - mount - self._zero_m + noise
        res = self.spec.resolution_m
        q = np.rint(rel / res) * res + 0.0  # + 0.0: no negative zero
        over = np.abs(rel) > self.half_range_m
        return np.where(over, np.copysign(np.inf, rel), q)

    def analog_V(
        self, ideal_m: FloatArray, m_per_volt: float, t_s: FloatArray | None = None
    ) -> FloatArray:
        """Analog output [V] at rig times ``t_s`` (None: now); over range it sits at the +-10 V
        rail."""
        r = self.readings_m(ideal_m, t_s)
        return np.where(np.isfinite(r), r / m_per_volt, np.copysign(10.0, r))


def format_probe_um(value_m: float) -> str:
    """``+0012.3450`` / ``+OVER`` / ``-OVER``: micrometres, 4 decimals, sign always printed."""
    if math.isinf(value_m):
        return "+OVER" if value_m > 0 else "-OVER"
    return f"{value_m * 1e6:+010.4f}"
