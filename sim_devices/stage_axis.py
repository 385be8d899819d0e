"""Physics of one motorised linear stage with its position controller (trapezoidal profiles).

Like ophyd-async's simulated motor, a move honours the commanded velocity and a finite
acceleration, takes time, and reports moving / in-position while it runs; nothing jumps. The profile
is the textbook trapezoid (or triangle for short moves): accelerate at ``accel_m_s2`` to the cruise
velocity, cruise, decelerate to rest exactly at the target. A stop decelerates at the same rate; an
emergency stop (or a disable, or an alarm) halts immediately.

Refusals are loud: a target outside the travel raises alarm 1 (over-travel) and nothing moves, never a
clipped move; a velocity outside (0, max] or a move while disabled raises alarm 4 (driver fault). An
active alarm blocks motion until it is reset. Times are simulated seconds given by the caller (the
virtual rig), so the axis is a pure function of its command history.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

from drivers.interfaces import StageStatus


class Alarm(IntEnum):
    """Alarm codes of the register map (docs/protocols.md, register 8)."""

    NONE = 0
    OVER_TRAVEL = 1
    FOLLOWING_ERROR = 2
    OVERLOAD = 3
    DRIVER_FAULT = 4
    EMERGENCY_STOP = 5


@dataclass(frozen=True)
class StageAxisParams:
    """Mechanical limits of one stage (SI units)."""

    name: str
    travel_min_m: float
    travel_max_m: float
    max_velocity_m_s: float
    accel_m_s2: float
    home_position_m: float
    start_position_m: float
    homing_velocity_m_s: float

    def __post_init__(self) -> None:
        values = (
            self.travel_min_m,
            self.travel_max_m,
            self.max_velocity_m_s,
            self.accel_m_s2,
            self.home_position_m,
            self.start_position_m,
            self.homing_velocity_m_s,
        )
        if not all(math.isfinite(v) for v in values):
            raise ValueError(f"stage '{self.name}': every limit must be finite")
        if not self.travel_min_m < self.travel_max_m:
            raise ValueError(f"stage '{self.name}': travel_min_m must be below travel_max_m")
        for label, pos in (("home", self.home_position_m), ("start", self.start_position_m)):
            if not self.travel_min_m <= pos <= self.travel_max_m:
                raise ValueError(f"stage '{self.name}': {label} position outside the travel")
        if self.max_velocity_m_s <= 0 or self.accel_m_s2 <= 0:
            raise ValueError(f"stage '{self.name}': velocity and acceleration must be positive")
        if not 0 < self.homing_velocity_m_s <= self.max_velocity_m_s:
            raise ValueError(f"stage '{self.name}': homing velocity must be in (0, max]")


TANGENTIAL_STAGE = StageAxisParams(
    name="tangential",
    travel_min_m=0.0,
    travel_max_m=0.200,  # stroke 200 mm (Han et al. 2022, Section 2.1)
    max_velocity_m_s=5e-3,
    accel_m_s2=5e-3,
    home_position_m=0.0,
    start_position_m=0.100,
    homing_velocity_m_s=2e-3,
)
"""Tangential stage of the paper's rig (Han et al. 2022): 200 mm stroke; speed and acceleration
are choices."""

NORMAL_STAGE = StageAxisParams(
    name="normal",
    travel_min_m=0.0,
    travel_max_m=0.025,  # stroke 25 mm (Han et al. 2022, Section 2.1)
    max_velocity_m_s=2e-3,
    accel_m_s2=5e-3,
    home_position_m=0.0,
    start_position_m=0.0195,
    homing_velocity_m_s=1e-3,
)
"""Normal loading stage: 25 mm stroke; starts 0.5 mm short of the default contact point."""


@dataclass(frozen=True)
class _Segment:
    """Constant-acceleration piece of a profile: p(t) = p0 + v0 (t - t0) + a (t - t0)^2 / 2."""

    t0_s: float
    p0_m: float
    v0_m_s: float
    a_m_s2: float
    t1_s: float

    def position_m(self, t_s: float) -> float:
        dt = min(max(t_s, self.t0_s), self.t1_s) - self.t0_s
        return self.p0_m + self.v0_m_s * dt + 0.5 * self.a_m_s2 * dt * dt

    def velocity_m_s(self, t_s: float) -> float:
        dt = min(max(t_s, self.t0_s), self.t1_s) - self.t0_s
        return self.v0_m_s + self.a_m_s2 * dt


@dataclass(frozen=True)
class AxisStatus:
    """Everything a controller reports about its axis at one instant."""

    t_s: float
    position_m: float
    velocity_m_s: float
    target_m: float
    enabled: bool
    in_position: bool
    homed: bool
    moving: bool
    fault: bool
    limit: bool
    alarm: Alarm

    def stage_status(self) -> StageStatus:
        """What the controller reports through the drivers' interface (the status bits and alarm)."""
        return StageStatus(
            enabled=self.enabled,
            in_position=self.in_position,
            homed=self.homed,
            moving=self.moving,
            fault=self.fault,
            limit=self.limit,
            alarm_code=int(self.alarm),
        )


def _trapezoid(
    t0_s: float, p0_m: float, p1_m: float, v_max: float, accel: float
) -> list[_Segment]:
    """Rest-to-rest profile from p0 to p1: accelerate, cruise at v_max, decelerate (or a triangle)."""
    distance = p1_m - p0_m
    if distance == 0.0:
        return []
    sign = 1.0 if distance > 0 else -1.0
    d = abs(distance)
    t_acc = v_max / accel
    d_acc = 0.5 * accel * t_acc * t_acc
    if 2.0 * d_acc >= d:  # triangle: never reaches v_max
        t_acc = math.sqrt(d / accel)
        t_cruise = 0.0
    else:
        t_cruise = (d - 2.0 * d_acc) / v_max
    segs = []
    t, p, v = t0_s, p0_m, 0.0
    for a, dur in ((sign * accel, t_acc), (0.0, t_cruise), (-sign * accel, t_acc)):
        if dur <= 0.0:
            continue
        seg = _Segment(t, p, v, a, t + dur)
        segs.append(seg)
        p, v, t = seg.position_m(seg.t1_s), seg.velocity_m_s(seg.t1_s), seg.t1_s
    return segs


class StageAxis:
    """One stage; every method takes the simulated time ``t_s`` at which it happens."""

    # Position tolerance of "in position" and of the limit switches: well below one count (0.32 um).
    _TOL_M = 1e-9

    def __init__(self, params: StageAxisParams, t_s: float = 0.0) -> None:
        self.params = params
        self._rest_m = params.start_position_m
        self._target_m = params.start_position_m
        self._segments: list[_Segment] = []
        self._enabled = False
        self._homed = False
        self._homing_end_s: float | None = None
        self._alarm = Alarm.NONE
        self._last_t_s = t_s

    # ----------------------------------------------------------------------------- queries
    def _segment_at(self, t_s: float) -> _Segment | None:
        for seg in self._segments:
            if t_s < seg.t1_s:
                return seg if t_s >= seg.t0_s else None
        return None

    def position_m(self, t_s: float) -> float:
        if not self._segments:
            return self._rest_m
        if t_s >= self._segments[-1].t1_s:
            return self._target_m
        seg = self._segment_at(t_s)
        return self._segments[0].p0_m if seg is None else seg.position_m(t_s)

    def velocity_m_s(self, t_s: float) -> float:
        seg = self._segment_at(t_s)
        return 0.0 if seg is None else seg.velocity_m_s(t_s)

    def moving(self, t_s: float) -> bool:
        return bool(self._segments) and t_s < self._segments[-1].t1_s

    def accelerating(self, t_s: float) -> bool:
        """True while the position is not linear in time (needs fine sub-steps downstream)."""
        seg = self._segment_at(t_s)
        return seg is not None and seg.a_m_s2 != 0.0

    def next_breakpoint_s(self, t_s: float) -> float | None:
        """End of the profile piece running at ``t_s`` (None if at rest)."""
        for seg in self._segments:
            if t_s < seg.t1_s:
                return seg.t1_s
        return None

    @property
    def alarm(self) -> Alarm:
        return self._alarm

    def status(self, t_s: float) -> AxisStatus:
        pos = self.position_m(t_s)
        moving = self.moving(t_s)
        homed = self._homed or (self._homing_end_s is not None and t_s >= self._homing_end_s)
        p = self.params
        limit = pos <= p.travel_min_m + self._TOL_M or pos >= p.travel_max_m - self._TOL_M
        return AxisStatus(
            t_s=t_s,
            position_m=pos,
            velocity_m_s=self.velocity_m_s(t_s),
            target_m=self._target_m,
            enabled=self._enabled,
            in_position=(not moving)
            and self._alarm == Alarm.NONE
            and abs(pos - self._target_m) <= self._TOL_M,
            homed=homed,
            moving=moving,
            fault=self._alarm != Alarm.NONE,
            limit=limit,
            alarm=self._alarm,
        )

    # ---------------------------------------------------------------------------- commands
    def _settle(self, t_s: float) -> None:
        """Fold a finished profile into the rest position (keeps the segment list short)."""
        if self._segments and t_s >= self._segments[-1].t1_s:
            self._rest_m = self._target_m
            self._segments = []
        if self._homing_end_s is not None and t_s >= self._homing_end_s:
            self._homed = True
            self._homing_end_s = None
        self._last_t_s = t_s

    def _halt(self, t_s: float) -> None:
        """Stop dead at the current position (infinite deceleration)."""
        self._rest_m = self.position_m(t_s)
        self._target_m = self._rest_m
        self._segments = []
        self._homing_end_s = None

    def enable(self, t_s: float, on: bool = True) -> None:
        self._settle(t_s)
        if not on and self.moving(t_s):
            self._halt(t_s)
        self._enabled = on

    def move_to(self, t_s: float, target_m: float, velocity_m_s: float) -> Alarm:
        """Start a move; returns the alarm raised (NONE if the move was accepted)."""
        self._settle(t_s)
        if self._alarm != Alarm.NONE:
            return self._alarm
        p = self.params
        if not self._enabled or not (
            math.isfinite(velocity_m_s) and 0.0 < velocity_m_s <= p.max_velocity_m_s
        ):
            return self.raise_alarm(t_s, Alarm.DRIVER_FAULT)
        if not (math.isfinite(target_m) and p.travel_min_m <= target_m <= p.travel_max_m):
            return self.raise_alarm(t_s, Alarm.OVER_TRAVEL)
        self._plan(t_s, target_m, velocity_m_s)
        self._homing_end_s = None
        return Alarm.NONE

    def _plan(self, t_s: float, target_m: float, velocity_m_s: float) -> None:
        p = self.params
        pos, vel = self.position_m(t_s), self.velocity_m_s(t_s)
        segs: list[_Segment] = []
        t_go = t_s
        if vel != 0.0:  # come to rest first, then go
            a = -math.copysign(p.accel_m_s2, vel)
            stop = _Segment(t_s, pos, vel, a, t_s + abs(vel) / p.accel_m_s2)
            segs.append(stop)
            t_go, pos = stop.t1_s, stop.position_m(stop.t1_s)
            if not p.travel_min_m <= pos <= p.travel_max_m:  # braking would overshoot the travel
                self.raise_alarm(t_s, Alarm.OVER_TRAVEL)
                return
        segs.extend(_trapezoid(t_go, pos, target_m, velocity_m_s, p.accel_m_s2))
        self._rest_m = segs[0].p0_m if segs else pos
        self._segments = segs
        self._target_m = target_m

    def home(self, t_s: float) -> Alarm:
        """Drive to the home switch at the homing velocity; ``homed`` is set on arrival."""
        self._settle(t_s)
        if self._alarm != Alarm.NONE:
            return self._alarm
        if not self._enabled:
            return self.raise_alarm(t_s, Alarm.DRIVER_FAULT)
        self._plan(t_s, self.params.home_position_m, self.params.homing_velocity_m_s)
        self._homed = False
        self._homing_end_s = self._segments[-1].t1_s if self._segments else t_s
        self._settle(t_s)
        return Alarm.NONE

    def stop(self, t_s: float) -> None:
        """Decelerate to rest at the configured acceleration; the target becomes the rest point."""
        self._settle(t_s)
        if not self.moving(t_s):
            return
        pos, vel = self.position_m(t_s), self.velocity_m_s(t_s)
        self._homing_end_s = None
        if vel == 0.0:
            self._halt(t_s)
            return
        accel = self.params.accel_m_s2
        seg = _Segment(t_s, pos, vel, -math.copysign(accel, vel), t_s + abs(vel) / accel)
        self._segments = [seg]
        self._target_m = seg.position_m(seg.t1_s)

    def emergency_stop(self, t_s: float) -> None:
        """Halt immediately and latch alarm 5 (needs a reset)."""
        self.raise_alarm(t_s, Alarm.EMERGENCY_STOP)

    def raise_alarm(self, t_s: float, code: Alarm) -> Alarm:
        """Latch an alarm and halt at once (over-load, injected faults, refused commands)."""
        self._settle(t_s)
        self._halt(t_s)
        self._alarm = Alarm(code)
        return self._alarm

    def reset_alarm(self, t_s: float) -> None:
        self._settle(t_s)
        self._alarm = Alarm.NONE
