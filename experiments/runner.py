"""Run a protocol: dry run first, then record while the steps run; always end in a safe state.

* **Dry run** (:func:`dry_run`): every step is planned against the rig's limits (force <= the normal
  stage's limit, strokes, velocities) from the stages' current positions, and the duration is
  estimated; any violation raises :class:`~experiments.errors.PlanError` naming the step and the
  limit, before anything moves or any file is created.
* **Run** (:class:`Runner`): the run file is created (its folder, permissions and free space are
  checked first), the acquisition starts, the steps run in order with a marker per step in the run's
  event table and progress with ETA on the terminal. Pause/resume/abort come through
  :class:`~experiments.context.Controls` from any thread or signal.
* **Safe state** on abort, error or Ctrl-C (:func:`safe_state`): the tangential stage stops, the normal
  load is released (the normal stage goes back to where it was before contact; after a force-limit
  trip that retraction is the one motion allowed). The run file is closed with status ``aborted`` or
  ``failed`` and the error text; everything recorded stays.
* **Safe state after the last step** of a completed run too (:meth:`Runner._safe_end`): a protocol
  that leaves the normal load on (a protocol file without a release) has it released, recorded
  (marker ``safe_state``, before ``end``) and said; the dry run says so in the plan. A release that
  cannot be confirmed fails the run.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from drivers.safety import ForceGuard, StaleReadingGuard
from experiments.context import Controls, RigLimits, RunContext
from experiments.errors import PlanError, ProtocolAborted
from experiments.normal_load import CONTACT_N
from experiments.params import MAX_PLAN_STEPS, check_step_count, resolve
from experiments.protocols import PROTOCOLS, Protocol
from experiments.steps import POSITION_TOLERANCE_M, PlanState, Step
from rigctl.acquisition import Acquisition, AcquisitionStats, RigDevices
from rigctl.errors import InputError
from rigctl.status import RunStatus
from rigctl.storage import RunWriter
from rigctl.storage.layout import CameraLayout, DaqLayout, RunDescription
from rigctl.storage.preflight import DEFAULT_MIN_FREE_BYTES

_log = logging.getLogger(__name__)

SAFE_RETRACT_VELOCITY_M_S = 1e-3  # safe-state retraction: half the normal stage's 2 mm/s limit


@dataclass(frozen=True)
class PlannedStep:
    index: int
    description: str
    estimate_s: float


@dataclass(frozen=True)
class Plan:
    protocol: str
    parameters: dict[str, Any]
    steps: tuple[PlannedStep, ...]
    ends_loaded_N: float = 0.0
    """Normal force the last step leaves on (0: the protocol releases it); the safe state after the
    last step releases it."""

    @property
    def duration_s(self) -> float:
        return sum(s.estimate_s for s in self.steps)

    def summary(self) -> str:
        lines = [f"protocol {self.protocol}: {len(self.steps)} steps, estimated "
                 f"{self.duration_s:.0f} s of rig time"]
        lines += [f"  {s.index:3d}. {s.description:<58} ~{s.estimate_s:8.1f} s" for s in self.steps]
        if self.ends_loaded_N > 0:
            lines.append(f"  then the safe state: the last step leaves Fn {self.ends_loaded_N:g} N "
                         "on; the normal load is released after it")
        return "\n".join(lines)


def get_protocol(name: str) -> Protocol:
    try:
        return PROTOCOLS[name]
    except KeyError:
        raise InputError(
            f"unknown protocol '{name}' (known: {', '.join(PROTOCOLS)})"
        ) from None


def build_steps(protocol: Protocol, given: dict[str, Any]) -> tuple[dict[str, Any], list[Step]]:
    params = resolve(protocol.params, given, protocol.name)
    return params, protocol.steps(params)


def dry_run(
    protocol: Protocol, given: dict[str, Any], limits: RigLimits, x_start_m: float
) -> tuple[Plan, list[Step]]:
    """Plan every step against the limits from the tangential stage at ``x_start_m``."""
    params, steps = build_steps(protocol, given)
    check_force_limit(limits)
    state = PlanState(x_m=x_start_m, x_start_m=x_start_m)
    planned = []
    for i, step in enumerate(steps, 1):
        if i > MAX_PLAN_STEPS:  # a step before it that breaks a limit is named first
            check_step_count(len(steps), protocol.name)
        est = step.plan(state, limits)
        planned.append(PlannedStep(i, step.describe(), est))
    plan = Plan(protocol.name, params, tuple(planned), ends_loaded_N=state.fn_N)
    if plan.duration_s > MAX_PLAN_S:
        longest = max(planned, key=lambda p: p.estimate_s)
        raise PlanError(
            f"protocol {protocol.name}: estimated {plan.duration_s:,.0f} s of rig time "
            f"({plan.duration_s / 86400:.0f} days; at most {MAX_PLAN_S / 86400:.0f}): step "
            f"{longest.index} ({longest.description}) takes {longest.estimate_s:,.0f} s: is a "
            "unit wrong (velocities in m/s, travel in m)?")
    return plan, steps


def check_force_limit(limits: RigLimits) -> None:
    """Refuse a normal-force limit above the force sensor's range (PlanError, one line naming both):
    past the range a reading is saturated, so the force guard could not see the load reach it."""
    if limits.max_force_N > limits.force_range_N:
        raise PlanError(
            f"the normal-force limit {limits.max_force_N:g} N (normal_stage.limits.max_force_N) is "
            f"above the force sensor's range {limits.force_range_N:g} N (daq.force_range_N): a "
            "reading there is saturated, so the force guard could not see the load reach the limit"
        )


MAX_PLAN_S = 7 * 86400.0
"""Longest protocol accepted (a week of rig time): longer is a unit mistake far more often than an
experiment (a velocity of 1e-12 m/s planned 810,000,102 s)."""


def safe_state(ctx: RunContext, reason: str) -> list[str]:
    """Stop the tangential stage and release the normal load; return what could not be done."""
    problems: list[str] = []
    try:
        ctx.tangential.stop()
    except Exception as exc:
        problems.append(f"tangential stop: {exc}")
        try:
            ctx.tangential.emergency_stop()
        except Exception as exc2:
            problems.append(f"tangential emergency stop: {exc2}")
    normal = ctx.normal
    try:
        if ctx.force_guard is not None and ctx.force_guard.tripped:
            ctx.force_guard.allow_release()  # the retraction below lowers the force: allowed
        status = normal.status()
        if status.fault:
            normal.reset_alarm()
        if not status.enabled:
            normal.enable()
        z = normal.position_m()
        target = ctx.z_retract_m if ctx.z_retract_m is not None else z - 200e-6
        target = max(min(target, z), ctx.limits.normal.min_position_m)
        normal.move_absolute(target, SAFE_RETRACT_VELOCITY_M_S)
    except Exception as exc:
        problems.append(f"normal load release: {exc}")
        try:
            normal.emergency_stop()
        except Exception as exc2:
            problems.append(f"normal emergency stop: {exc2}")
    with contextlib.suppress(Exception):  # the marker is a courtesy; the state above matters
        ctx.acq.mark("safe_state", reason[:900])
    return problems


@dataclass
class RunOutcome:
    status: RunStatus
    error: str | None
    path: Path | None
    plan: Plan
    stats: AcquisitionStats | None = None
    wall_s: float = 0.0
    problems: list[str] = field(default_factory=list)


RunProgressFn = Callable[[int, int, str, float, float], None]
"""progress(step_index, n_steps, description, elapsed_device_s, eta_device_s)"""


class Runner:
    """One run of a protocol on a set of devices."""

    def __init__(
        self,
        protocol: Protocol,
        params: dict[str, Any],
        devices: RigDevices,
        limits: RigLimits,
        *,
        out: Path | None,
        daq_layout: DaqLayout | None = None,
        camera_layout: CameraLayout | None = None,
        description: RunDescription | None = None,
        controls: Controls | None = None,
        force_limit_N: float | None = None,
        progress: RunProgressFn | None = None,
        flush_interval_s: float = 0.25,
        overwrite: bool = False,
        on_acquisition: Callable[[Acquisition], None] | None = None,
        min_free_bytes: int = DEFAULT_MIN_FREE_BYTES,
    ) -> None:
        self.protocol = protocol
        self.params = params
        self.devices = devices
        self.limits = replace(limits, force_range_N=min(limits.force_range_N,
                                                         devices.daq.force_range_N))
        self.out = out
        self.daq_layout = daq_layout or DaqLayout(sample_rate_hz=devices.daq.rate_hz)
        self.camera_layout = camera_layout
        self.description = description
        self.controls = controls or Controls()
        self.force_limit_N = force_limit_N if force_limit_N is not None else limits.max_force_N
        self.progress = progress
        self.flush_interval_s = flush_interval_s
        self.overwrite = overwrite
        self.min_free_bytes = min_free_bytes
        """Free space kept beyond the run's estimated size before it starts, and half of it while it
        records (``storage.min_free_bytes``; :class:`~rigctl.storage.RunWriter`)."""
        self.on_acquisition = on_acquisition
        self.ctx: RunContext | None = None

    def plan(self) -> tuple[Plan, list[Step]]:
        x0 = self.devices.tangential_stage.position_m()
        return dry_run(self.protocol, self.params, self.limits, x0)

    def run(self) -> RunOutcome:
        """Dry run, then the run itself. Raises only for a plan or file problem (before motion)."""
        plan, steps = self.plan()
        writer = None
        if self.out is not None:
            desc = self.description or RunDescription(protocol=self.protocol.name)
            desc = RunDescription(
                protocol=self.protocol.name, parameters=_jsonable(plan.parameters),
                operator=desc.operator, notes=desc.notes, config_toml=desc.config_toml,
                calibration=desc.calibration, metadata=desc.metadata,
            )
            writer = RunWriter(
                self.out, desc, self.daq_layout, self.camera_layout,
                flush_interval_s=self.flush_interval_s, expected_duration_s=plan.duration_s,
                overwrite=self.overwrite, min_free_bytes=self.min_free_bytes,
            )
        guard = ForceGuard(self.devices.normal_stage, self.force_limit_N,
                           range_N=self.limits.force_range_N)
        stale = StaleReadingGuard((self.devices.normal_stage, self.devices.tangential_stage),
                                  device=self.devices.daq.name)
        acq = Acquisition(
            self.devices, writer, record_camera=self.camera_layout is not None, force_guard=guard,
            stale_guard=stale,
        )
        ctx = RunContext(self.devices, acq, self.limits, self.controls, guard)
        self.ctx = ctx
        t_wall = time.monotonic()
        status, error = RunStatus.COMPLETED, None
        problems: list[str] = []
        stats: AcquisitionStats | None = None
        safe_done = False
        try:
            if self.on_acquisition is not None:
                self.on_acquisition(acq)
            acq.start()
            ctx.x_start_m = self.devices.tangential_stage.position_m()
            for stage in (self.devices.tangential_stage, self.devices.normal_stage):
                if not stage.status().enabled:
                    stage.enable()
            t0 = ctx.now_s()
            acq.mark("start", f"protocol {plan.protocol}")
            remaining = plan.duration_s
            for planned, step in zip(plan.steps, steps, strict=True):
                ctx.current_step = f"step {planned.index} ({planned.description})"
                acq.mark(f"step {planned.index}", planned.description)
                if self.progress:
                    self.progress(planned.index, len(steps), planned.description,
                                  ctx.acq.t_s - t0, remaining)
                step.run(ctx)
                remaining -= planned.estimate_s
            ctx.current_step = "the safe state after the last step"
            problems = self._safe_end(ctx, stale)
            safe_done = True  # done (or found incomplete): the finally below does not redo it
            if problems:
                status = RunStatus.FAILED
                error = ("the protocol completed, but the safe state after its last step is "
                         f"incomplete: {'; '.join(problems)}")
                _log.critical("%s", error)
            else:
                acq.mark("end", "protocol completed")
        except ProtocolAborted as exc:
            status, error = RunStatus.ABORTED, str(exc) or "aborted"
        except BaseException as exc:
            status, error = RunStatus.FAILED, f"{type(exc).__name__}: {exc}"
            if isinstance(exc, KeyboardInterrupt):
                status, error = RunStatus.ABORTED, "interrupted (Ctrl-C)"
            elif self.controls.aborted:
                # the abort came first and the step then failed on its consequence (an e-stop's
                # stage alarm seen before the abort flag): the run was aborted, the failure is
                # what the abort caused
                status = RunStatus.ABORTED
                error = f"{self.controls.abort_reason or 'aborted'} (then {error})"
        finally:
            if status != RunStatus.COMPLETED and not safe_done:
                problems = safe_state(ctx, error or status)
                self._wait_released(ctx)
                problems += _unreleased(ctx, acq.device_now_s(), stale)
                if problems:
                    error = f"{error}; safe state incomplete: {'; '.join(problems)}"
                    _log.critical("safe state incomplete: %s", "; ".join(problems))
            if not acq.catch_up(RELEASE_WAIT_HOST_S):
                _log.warning("the record ends at %.3f s, before the end of the run at %.3f s of "
                             "device time (the data did not catch up)", acq.t_s,
                             acq.device_now_s())
            stats = acq.stop(status, error)
            guard_detach(self.devices.normal_stage, guard)
        return RunOutcome(status, error, self.out, plan, stats, time.monotonic() - t_wall, problems)

    def _safe_end(self, ctx: RunContext, stale: StaleReadingGuard) -> list[str]:
        """The safe state after the last step of a completed protocol; what could not be done.

        The tangential stage is stopped; a normal load the protocol left on (the measured force, or
        the normal stage still past where it was before contact) is released as on an abort and the
        release checked on the force. Recorded either way (marker ``safe_state``)."""
        with contextlib.suppress(Exception):  # it has arrived; a stop is the belt and braces
            ctx.tangential.stop()
        left_on = _load_left_on(ctx)
        if left_on is None:
            ctx.acq.mark("safe_state", "end of protocol: the normal load was already released")
            return []
        _log.warning("protocol %s ended with the normal load on (%s): the safe state releases it",
                     self.protocol.name, left_on)
        problems = safe_state(ctx, f"end of protocol: the last step left the normal load on "
                                   f"({left_on}); released")
        self._wait_released(ctx)
        return problems + _unreleased(ctx, ctx.acq.device_now_s(), stale)

    def _wait_released(self, ctx: RunContext) -> None:
        """Give the retraction RELEASE_WAIT_S of device time to finish (the acquisition keeps
        recording it), at most RELEASE_WAIT_HOST_S on the host clock (a device clock that stopped).

        Device time from the acquisition itself, not ``ctx.now_s()``: that checkpoints, and the
        safe state runs after an abort (the checkpoint would raise and skip the release check)."""
        t_dev0 = ctx.acq.device_now_s()
        deadline = time.monotonic() + RELEASE_WAIT_HOST_S
        while time.monotonic() < deadline:
            try:
                if not ctx.normal.status().moving:
                    return
            except Exception:
                return
            if ctx.acq.device_now_s() - t_dev0 > RELEASE_WAIT_S:
                return
            time.sleep(0.02)


RELEASE_WAIT_S = 5.0
"""Device time the safe state gives the normal stage's retraction to finish."""
RELEASE_WAIT_HOST_S = 20.0
"""Host-time cap of that wait and of the wait for force data after the release: on the hardware
device time is the host's (the DAQ delivers within milliseconds), but a simulated rig starved of
CPU runs slower than the host clock (a CI run of the full suite beside other jobs saw a 5 s host
wait end with the stage still retracting, Fn 2.7 N)."""
RELEASED_MAX_N = 5.0
"""|Fn| above this after the safe state's release means the load is still on the specimen."""
RELEASE_CHECK_S = 0.1
"""Device time of force data after the release that the check averages."""


def _load_left_on(ctx: RunContext) -> str | None:
    """What says the normal load is still on after the last step (None: released): the force
    measured after the step ended above the contact threshold, or the normal stage past where it was
    before contact."""
    t_end_s = ctx.acq.device_now_s()
    if math.isfinite(t_end_s):
        ctx.acq.wait_until(t_end_s + RELEASE_CHECK_S, RELEASE_WAIT_HOST_S)
    fn = ctx.acq.mean("fn_N", RELEASE_CHECK_S)
    if not math.isfinite(fn) or fn > CONTACT_N:
        return f"Fn {fn:.1f} N" if math.isfinite(fn) else "no force reading"
    try:
        z = ctx.normal.position_m()
    except Exception as exc:
        return f"the normal stage's position unknown: {exc}"
    if ctx.z_retract_m is not None and z > ctx.z_retract_m + POSITION_TOLERANCE_M:
        return (f"the normal stage {(z - ctx.z_retract_m) * 1e6:.0f} um past where it was before "
                f"contact, Fn {fn:.1f} N")
    return None


def _unreleased(ctx: RunContext, t_release_s: float,
                stale: StaleReadingGuard | None = None) -> list[str]:
    """The release checked on the measured force recorded after the release finished (device time
    ``t_release_s``), not on the stage's word for it nor on data from before it."""
    if stale is not None and stale.trip is not None:
        return ["the release could not be confirmed from the force: its reading is frozen (the "
                "normal stage retracted to where it was before contact; check the rig)"]
    if not math.isfinite(t_release_s):
        return ["the release could not be confirmed: no force data"]
    ctx.acq.wait_until(t_release_s + RELEASE_CHECK_S, RELEASE_WAIT_HOST_S)
    t_now = ctx.acq.t_s
    if not (math.isfinite(t_now) and t_now >= t_release_s + RELEASE_CHECK_S):
        return ["the release could not be confirmed: no force data since the release"]
    fn = ctx.acq.mean("fn_N", min(RELEASE_CHECK_S, t_now - t_release_s))
    if math.isfinite(fn) and abs(fn) > RELEASED_MAX_N:
        return [f"the normal load is still on: Fn = {fn:.1f} N after the release (check the rig)"]
    return []


def guard_detach(stage: Any, guard: ForceGuard) -> None:
    with contextlib.suppress(Exception):  # the stage may be closed already
        stage.remove_interlock(guard)


def _jsonable(params: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in params.items():
        out[k] = list(v) if isinstance(v, tuple) else v
        if isinstance(v, float) and not math.isfinite(v):
            out[k] = str(v)
    return out
