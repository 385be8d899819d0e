"""Small steps that procedures are built from; each can be planned (dry run) and run.

``plan`` checks the step against the rig's limits on a simulated plan state and returns the step's
estimated duration (device seconds) without touching any device; ``run`` performs it, checking for
device faults, pause and abort at least every 10 ms of host time.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

from drivers.errors import InvalidValueError, StageAlarm
from drivers.interfaces import LoadingStage
from experiments.context import TANGENTIAL, RigLimits, RunContext
from experiments.errors import PlanError, ProcedureError

POSITION_TOLERANCE_M = 1e-6
"""A move has arrived when the stage reports no motion within this distance of its target."""

RETURN_VELOCITY_M_S = 50e-6
"""Speed of returns of the tangential stage to the start (no load on the interface)."""


@dataclass
class PlanState:
    """What the dry run knows while it walks the plan."""

    x_m: float
    """Tangential stage position."""
    x_start_m: float
    fn_N: float = 0.0
    """Normal force the plan holds at this point."""


class Step:
    """Base class: a named, plannable, runnable piece of a procedure."""

    name = "step"

    def describe(self) -> str:
        return self.name

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        """Check limits, update ``state``, return the estimated duration [device s]."""
        raise NotImplementedError

    def run(self, ctx: RunContext) -> None:
        raise NotImplementedError

    def refuse(self, message: str) -> PlanError:
        return PlanError(f"step '{self.describe()}': {message}")


T = TypeVar("T")


def within_limits(step: Step, check: Callable[[], T]) -> T:
    """Run one of the drivers' own limit checks (:class:`~drivers.interfaces.StageLimits`) for the
    dry run: its refusal becomes a :class:`PlanError` naming the step, with the driver's message."""
    try:
        return check()
    except InvalidValueError as exc:
        raise step.refuse(str(exc)) from exc


def drive_to(
    ctx: RunContext,
    stage: LoadingStage,
    target_m: float,
    velocity_m_s: float,
    estimate_s: float,
    while_moving: Callable[[], None] | None = None,
) -> None:
    """Move ``stage`` to ``target_m`` and wait for it, honouring pause/abort and device faults;
    ``while_moving`` is called at every poll of the move while not paused (the probes' re-centring,
    :mod:`experiments.recentre`), never altering it.

    A pause stops the stage where it is; resuming re-issues the move to the same target. The move
    times out (ProcedureError) if it takes more than twice its estimate plus 30 s of device time,
    not counting paused time.
    """
    stage.move_absolute(target_m, velocity_m_s)
    t0 = ctx.now_s()
    paused_s = 0.0
    pause_started: float | None = None
    idle_since: float | None = None
    while True:
        ctx.checkpoint()
        if ctx.controls.paused:
            if pause_started is None:
                stage.stop()
                pause_started = ctx.acq.t_s
                ctx.acq.mark("pause", ctx.current_step)
            ctx.sleep()
            continue
        if pause_started is not None:
            paused_s += ctx.acq.t_s - pause_started
            pause_started = None
            ctx.acq.mark("resume", ctx.current_step)
            stage.move_absolute(target_m, velocity_m_s)
        if while_moving is not None:
            while_moving()
        status = stage.status()
        if status.fault:
            raise StageAlarm(stage.name, status.alarm_code)
        if not status.moving:
            if abs(stage.position_m() - target_m) <= POSITION_TOLERANCE_M:
                return
            now = time.monotonic()
            idle_since = idle_since if idle_since is not None else now
            if now - idle_since > 1.0:
                raise ProcedureError(
                    f"{ctx.current_step}: {stage.name} stopped at {stage.position_m():.7f} m, "
                    f"short of its target {target_m:.7f} m"
                )
        else:
            idle_since = None
        if ctx.acq.t_s - t0 - paused_s > 2.0 * estimate_s + 30.0:
            raise ProcedureError(
                f"{ctx.current_step}: {stage.name} did not reach {target_m:.7f} m in "
                f"{2.0 * estimate_s + 30.0:.0f} s of device time"
            )
        ctx.sleep()


def hold_device_time(ctx: RunContext, seconds: float) -> None:
    """Wait ``seconds`` of device time; a pause freezes the remaining time."""
    remaining = seconds
    last = ctx.now_s()
    while remaining > 0:
        ctx.checkpoint()
        now = ctx.now_s()
        if not ctx.controls.paused:
            remaining -= now - last
        last = now
        if remaining <= 0:
            break
        ctx.acq.wait_until(now + min(remaining, 0.5), 0.05, ctx.controls.abort_event)


class MoveTangential(Step):
    """Drive the tangential stage by ``distance_m`` at ``velocity_m_s`` (the sliding itself)."""

    name = "move_tangential"

    def __init__(self, distance_m: float, velocity_m_s: float) -> None:
        self.distance_m = float(distance_m)
        self.velocity_m_s = float(velocity_m_s)

    def describe(self) -> str:
        return (f"slide {self.distance_m * 1e6:.1f} um at {self.velocity_m_s * 1e6:.3g} um/s")

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        target = state.x_m + self.distance_m
        within_limits(self, lambda: limits.tangential.check_move(TANGENTIAL, target, self.velocity_m_s))
        state.x_m = target
        return abs(self.distance_m) / self.velocity_m_s

    def run(self, ctx: RunContext) -> None:
        stage = ctx.tangential
        target = stage.position_m() + self.distance_m
        drive_to(ctx, stage, target, self.velocity_m_s, abs(self.distance_m) / self.velocity_m_s)


class ReturnTangential(Step):
    """Bring the tangential stage back to where the protocol started (paper Sec. 2.2)."""

    name = "return_tangential"

    def __init__(self, velocity_m_s: float = RETURN_VELOCITY_M_S) -> None:
        self.velocity_m_s = float(velocity_m_s)

    def describe(self) -> str:
        return f"return the tangential stage to the start at {self.velocity_m_s * 1e6:.3g} um/s"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        within_limits(
            self, lambda: limits.tangential.check_move(TANGENTIAL, state.x_start_m, self.velocity_m_s)
        )
        duration = abs(state.x_m - state.x_start_m) / self.velocity_m_s
        state.x_m = state.x_start_m
        return duration

    def run(self, ctx: RunContext) -> None:
        if ctx.x_start_m is None:
            raise ProcedureError("return_tangential: the start position was not recorded")
        stage = ctx.tangential
        estimate = abs(stage.position_m() - ctx.x_start_m) / self.velocity_m_s
        drive_to(ctx, stage, ctx.x_start_m, self.velocity_m_s, estimate)


class Hold(Step):
    """Keep everything still for ``seconds`` of device time (holds, waits between repetitions)."""

    name = "hold"

    def __init__(self, seconds: float, label: str = "hold") -> None:
        self.seconds = float(seconds)
        self.label = label

    def describe(self) -> str:
        return f"{self.label} {self.seconds:g} s"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        if not self.seconds >= 0:
            raise self.refuse(f"duration must be >= 0 s, got {self.seconds:g}")
        return self.seconds

    def run(self, ctx: RunContext) -> None:
        hold_device_time(ctx, self.seconds)
