"""Normal loading steps: reach a normal force by closed-loop moves of the (position-controlled) normal
stage on the Fn reading, with the paper's pre-load, and release the load.

Reaching a force (no contact law is assumed; only readings are used):

1. **Contact search.** While Fn is below ``contact_N`` the stage advances in ``coarse_step_m``
   increments (each a complete move, then a reading), so an unexpected contact overshoots by at
   most one increment.
2. **Secant iterations.** From two readings the local stiffness dFn/dz is estimated and the next
   position is ``z + (F_target - Fn) / slope``, limited to ``max_step_m`` per move; each move ends,
   the force settles for ``settle_s`` and is averaged over ``average_s`` of device time. Stops when
   |Fn - F_target| <= ``tolerance_N``. The first move after contact is a small probe step.

Pre-load (paper Sec. 2.1, after Rubinstein): load to ``preload_factor * F`` first, hold
``preload_hold_s``, then unload to F; this reduces the influence of aging on the run.
"""

from __future__ import annotations

import math

from drivers.errors import InvalidValueError
from experiments.context import NORMAL, RigLimits, RunContext
from experiments.errors import ProcedureError
from experiments.steps import PlanState, Step, drive_to, hold_device_time, within_limits

CONTACT_N = 2.0
"""A reading above this means the specimens touch (80 force counts of 0.025 N)."""


class LoadNormal(Step):
    """Bring the normal force to ``target_N`` (with an optional pre-load overshoot)."""

    name = "load_normal"

    def __init__(
        self,
        target_N: float,
        preload_factor: float = 1.0,
        preload_hold_s: float = 5.0,
        tolerance_N: float = 3.0,
        coarse_step_m: float = 20e-6,
        max_step_m: float = 10e-6,
        approach_velocity_m_s: float = 200e-6,
        load_velocity_m_s: float = 20e-6,
        settle_s: float = 0.05,
        average_s: float = 0.05,
        max_iterations: int = 40,
    ) -> None:
        self.target_N = float(target_N)
        self.preload_factor = float(preload_factor)
        self.preload_hold_s = float(preload_hold_s)
        self.tolerance_N = float(tolerance_N)
        self.coarse_step_m = float(coarse_step_m)
        self.max_step_m = float(max_step_m)
        self.approach_velocity_m_s = float(approach_velocity_m_s)
        self.load_velocity_m_s = float(load_velocity_m_s)
        self.settle_s = float(settle_s)
        self.average_s = float(average_s)
        self.max_iterations = int(max_iterations)

    def describe(self) -> str:
        pre = (f" (pre-load {self.preload_factor * self.target_N:.0f} N)"
               if self.preload_factor > 1 else "")
        return f"load Fn to {self.target_N:g} N{pre}"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        peak = self.target_N * max(self.preload_factor, 1.0)
        if not (math.isfinite(self.target_N) and self.target_N > 0):
            raise self.refuse(f"target force must be > 0 N, got {self.target_N:g}")
        if not self.preload_factor >= 1.0:
            raise self.refuse(f"pre-load factor must be >= 1, got {self.preload_factor:g}")
        if peak > limits.max_force_N:
            raise self.refuse(
                f"peak normal force {peak:g} N exceeds the limit {limits.max_force_N:g} N"
            )
        if peak > limits.force_range_N:
            raise self.refuse(
                f"peak normal force {peak:g} N is above the force sensor's range "
                f"{limits.force_range_N:g} N (daq.force_range_N): a reading there is saturated, "
                "so the force guard could not see the load past it"
            )
        if not 0 < self.tolerance_N < self.target_N:
            raise self.refuse(f"tolerance {self.tolerance_N:g} N must be in (0, target)")
        normal = limits.normal
        within_limits(
            self, lambda: normal.check_velocity(NORMAL, self.approach_velocity_m_s, "approach_velocity_m_s")
        )
        within_limits(
            self, lambda: normal.check_velocity(NORMAL, self.load_velocity_m_s, "load_velocity_m_s")
        )
        state.fn_N = self.target_N
        # a contact search from up to 0.5 mm away, plus ~10 secant moves per force level
        search_s = 25 * (self.coarse_step_m / self.approach_velocity_m_s + self.settle_s
                         + self.average_s)
        levels = 2 if self.preload_factor > 1 else 1
        secant_s = levels * 10 * (self.max_step_m / self.load_velocity_m_s + self.settle_s
                                  + self.average_s)
        return search_s + secant_s + (self.preload_hold_s if levels == 2 else 0.0)

    def run(self, ctx: RunContext) -> None:
        if self.preload_factor > 1.0:
            self._reach(ctx, self.target_N * self.preload_factor)
            ctx.acq.mark("preload", f"Fn {ctx.fn_N(self.average_s):.2f} N")
            hold_device_time(ctx, self.preload_hold_s)
        self._reach(ctx, self.target_N)
        ctx.acq.mark("loaded", f"Fn {ctx.fn_N(self.average_s):.2f} N")

    def _measure(self, ctx: RunContext) -> float:
        t = ctx.now_s()
        ctx.wait_device_time(t + self.settle_s + self.average_s, host_timeout_s=30.0)
        return ctx.fn_N(self.average_s)

    def _move(self, ctx: RunContext, z: float, velocity: float) -> float:
        stage = ctx.normal
        limits = ctx.limits
        if ctx.z_contact_m is not None and z > ctx.z_contact_m + limits.max_approach_m:
            raise ProcedureError(
                f"{self.describe()}: refused: the normal stage would press "
                f"{(z - ctx.z_contact_m) * 1e6:.0f} um past where it first read a contact "
                f"(z = {ctx.z_contact_m * 1e3:.4f} mm; max_approach_m = "
                f"{limits.max_approach_m * 1e6:.0f} um) while Fn reads {ctx.fn_N(self.average_s):.1f} N: "
                "the force reading may be blind, or the load path is softer than configured")
        if ctx.z_contact_m is None and z > limits.contact_search_end_m:
            raise ProcedureError(
                f"{self.describe()}: no contact read up to z = {stage.position_m() * 1e3:.4f} mm, the "
                f"end of the contact search (contact_search_end_m = "
                f"{limits.contact_search_end_m * 1e3:.4f} mm) while Fn reads "
                f"{ctx.fn_N(self.average_s):.2f} N: the force reading may be blind, or the specimen "
                "is not where the configuration expects it")
        try:
            ctx.limits.normal.check_target(stage.name, z)
        except InvalidValueError as exc:
            raise ProcedureError(
                f"{self.describe()}: the normal stage would leave its stroke: {exc}"
            ) from exc
        drive_to(ctx, stage, z, velocity, abs(z - stage.position_m()) / velocity)
        return self._measure(ctx)

    def _reach(self, ctx: RunContext, force_N: float) -> None:
        stage = ctx.normal
        z = stage.position_m()
        fn = self._measure(ctx)
        if ctx.z_retract_m is None and fn < CONTACT_N:
            ctx.z_retract_m = z
        steps = 0
        while fn < CONTACT_N:
            steps += 1
            if steps > 2000:
                raise ProcedureError(f"{self.describe()}: no contact found")
            z += self.coarse_step_m
            fn = self._move(ctx, z, self.approach_velocity_m_s)
        if ctx.z_contact_m is None:
            ctx.z_contact_m = z
        slope: float | None = None
        best = (abs(fn - force_N), z)
        for _ in range(self.max_iterations):
            err = force_N - fn
            if abs(err) <= self.tolerance_N:
                return
            if slope is None:
                dz = math.copysign(min(2e-6, self.max_step_m), err)
            else:
                dz = max(-self.max_step_m, min(self.max_step_m, err / slope))
                if abs(dz) < 0.5e-6:  # below about one count of the stage: cannot improve
                    dz = math.copysign(0.6e-6, err)
            z_new = z + dz
            fn_new = self._move(ctx, z_new, self.load_velocity_m_s)
            if fn_new > CONTACT_N and abs(z_new - z) > 0:
                s = (fn_new - fn) / (z_new - z)
                if s > 0:
                    slope = s
            z, fn = z_new, fn_new
            best = min(best, (abs(fn - force_N), z))
        raise ProcedureError(
            f"{self.describe()}: Fn did not settle within {self.tolerance_N:g} N of {force_N:g} N "
            f"(closest {best[0]:.2f} N off, at z = {best[1]:.7f} m)"
        )


class ReleaseNormal(Step):
    """Release the normal load: the normal stage goes back to where it was before contact."""

    name = "release_normal"

    def __init__(self, velocity_m_s: float = 500e-6, retract_m: float = 200e-6) -> None:
        self.velocity_m_s = float(velocity_m_s)
        self.retract_m = float(retract_m)

    def describe(self) -> str:
        return "release the normal load"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        within_limits(self, lambda: limits.normal.check_velocity(NORMAL, self.velocity_m_s))
        state.fn_N = 0.0
        return 0.5e-3 / self.velocity_m_s + 0.5

    def run(self, ctx: RunContext) -> None:
        stage = ctx.normal
        z = stage.position_m()
        target = ctx.z_retract_m if ctx.z_retract_m is not None else z - self.retract_m
        target = max(target, ctx.limits.normal.min_position_m)
        drive_to(ctx, stage, target, self.velocity_m_s, abs(z - target) / self.velocity_m_s)
        t = ctx.now_s()
        ctx.wait_device_time(t + 0.1, host_timeout_s=30.0)
        fn = ctx.fn_N(0.05)
        if fn > CONTACT_N:
            raise ProcedureError(f"{self.describe()}: Fn still {fn:.2f} N after retracting")
        ctx.z_contact_m = None  # the next load step finds the contact anew
        ctx.acq.mark("released", f"Fn {fn:.2f} N")
