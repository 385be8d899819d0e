"""Re-centring the displacement probes while the stage slides, as a lab does, and putting them back.

A fibre-optic probe measures 74 um about its stand-off (MTI-2100 + RS2032R, Han et al. 2022,
Sec. 2.1); the probe on the driven specimen (D1) follows the slide, hundreds of micrometres per
run. Re-zeroing the electronics does not bring a target that left the range back: the probe itself
has to move. Its mount is independent of the tangential drive, so the drive is never stopped or
altered for it (a stop would be a hold, and a hold changes the friction being measured).

During every slide (:class:`RecentredSlide`, parameter ``recentre_probes``, on by default) each
probe's reading, as recorded, is watched at every poll of the move. When less than
``headroom_m`` of the probe's range is left ahead of it in the slide's direction (40 um by default:
an initial-stage slip of the simulated TLRE at 300 N carries D1 by 40 um), its mount
(:meth:`DisplacementProbe.move_mount`) moves so that the reading goes to ``TARGET_FRACTION`` of the
half range behind the centre (-29.6 um of the MTI-2100's +-37 um), while the stage keeps going;
never in the middle of a slip (the reading must be steady, ``STEADY_M`` over ``STEADY_S``). A
probe found over range on the slide's side (a slip carried it beyond) is moved back by half its
range, which is known to bring it back in, and re-centred from there.

Each move is recorded as a ``probe_recentre`` event (:mod:`rigctl.storage.probe_events`) once the
mount has arrived: the column, the move, the readings before and after, and the window of device
time during which the mount may have been moving: from just before the command to its return plus
the move's duration at :attr:`DisplacementProbe.mount_speed_m_s` plus ``MOUNT_SETTLE_S``. The samples
in that window are kept as read; every reader adds the move back after it and bridges the window
(:mod:`rigctl.records.delta_stitch`). After the stage has returned, :class:`ReturnProbeMounts`
brings the mounts back to where they started.

A re-centring that cannot be made (a manual mount, a move beyond the mount's travel, a headroom the
probe's range cannot give) is recorded once per slide as a ``probe_not_recentred`` event with the
reason, and the slide goes on: the forces are still measured, only delta goes over range as it
would have without re-centring.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from drivers.errors import LimitError, NotSupportedError, OverRangeError
from drivers.interfaces import DisplacementProbe
from experiments.context import RigLimits, RunContext
from experiments.errors import PlanError
from experiments.steps import MoveTangential, PlanState, ReturnTangential, Step, drive_to
from rigctl.storage.probe_events import NOT_RECENTRED_EVENT, RECENTRE_EVENT, recentre_message

TARGET_FRACTION = 0.8
"""Where a re-centred reading goes: this fraction of the half range behind the centre (-29.6 um of
the MTI-2100's +-37 um for a slide in +x), leaving 66.6 um of range ahead of it."""
MOUNT_SETTLE_S = 0.05
"""Device time added to a move's end in its recorded window: the mount's settling and the DAQ's block
latency (the newest recorded sample, the device time a real rig reports, is behind the present)."""
STEADY_S = 0.03
"""A mount moves only while its probe's reading is steady: within ``STEADY_M`` of its mean over the
last ``STEADY_S`` (not in a slip: a slip that carries the reading past the headroom is let end
first, so the move's window does not hide it)."""
STEADY_M = 0.5e-6
MIN_MOVE_M = 1e-6
"""A re-centring moves the mount by at least this much, or not at all."""
MIN_HEADROOM_M = 1e-6
"""Smallest headroom accepted (``recentre_probes=0`` turns re-centring off)."""
WAIT_HOST_S = 30.0
"""Host seconds a slide's end waits for the recorded data to reach the end of a move."""


def _probes(ctx: RunContext) -> list[tuple[str, DisplacementProbe]]:
    """The run's probes with the recorded column each one feeds."""
    found = (("d1_m", ctx.devices.d1), ("d2_m", ctx.devices.d2))
    return [(column, probe) for column, probe in found if probe is not None]


@dataclass
class _Move:
    """A mount move made, waiting for the recorded data to pass its end before it is recorded."""

    moved_m: float
    before_m: float
    t_start_s: float
    t_end_s: float


class _Watched:
    """One probe watched during a slide."""

    def __init__(self, column: str, probe: DisplacementProbe) -> None:
        self.column = column
        self.probe = probe
        self.half_m = 0.5 * probe.range_m
        self.pending: _Move | None = None
        self.given_up = False


class Recentring:
    """The probes' re-centring during one slide of the stage in ``direction`` (module docstring):
    :meth:`poll` at every poll of the move, :meth:`finish` after it."""

    def __init__(self, ctx: RunContext, direction: float, headroom_m: float) -> None:
        self.ctx = ctx
        self.direction = 1.0 if direction >= 0 else -1.0
        self.headroom_m = float(headroom_m)
        self.watched = [_Watched(c, p) for c, p in _probes(ctx)]
        for w in self.watched:
            reachable = w.half_m * (1.0 + TARGET_FRACTION) - MIN_MOVE_M
            if self.headroom_m > reachable:
                self._give_up(w, f"a re-centring leaves at most {reachable * 1e6:.1f} um of its "
                              f"range ahead, less than recentre_headroom_m "
                              f"({self.headroom_m * 1e6:.1f} um)")

    def _give_up(self, w: _Watched, why: str) -> None:
        self.ctx.acq.mark(NOT_RECENTRED_EVENT, f"{w.column}: {why}; not re-centred in this slide")
        w.given_up = True

    def poll(self) -> None:
        """Record the moves that have ended; move the mount of a probe near its range's edge."""
        latest = self.ctx.acq.latest()
        t_data = self.ctx.acq.t_s
        for w in self.watched:
            if w.pending is not None:
                if t_data >= w.pending.t_end_s:
                    self._record(w, latest.get(w.column, math.nan))
                continue
            if not w.given_up:
                self._check(w, latest.get(w.column, math.nan))

    def _check(self, w: _Watched, reading_m: float) -> None:
        if not math.isfinite(reading_m):
            return
        ahead = w.half_m - self.direction * reading_m
        if ahead >= self.headroom_m:
            return
        if abs(reading_m) > w.half_m:  # over range, at the rail: the reading says only which side
            if self.direction * reading_m < 0:
                return  # behind the slide: not the slide's doing
            before, move = math.nan, self.direction * w.half_m
        else:
            before = reading_m
            move = reading_m + self.direction * TARGET_FRACTION * w.half_m
        if abs(move) < MIN_MOVE_M:
            return
        if abs(reading_m - self.ctx.acq.mean(w.column, STEADY_S)) > STEADY_M:
            return  # sliding: wait for the slip to end
        t0 = self.ctx.now_s()
        try:
            w.probe.move_mount(move)
        except (LimitError, NotSupportedError) as exc:
            self._give_up(w, str(exc))
            return
        t1 = self.ctx.now_s()
        end = t1 + abs(move) / w.probe.mount_speed_m_s + MOUNT_SETTLE_S
        w.pending = _Move(move, before, t0, end)

    def _record(self, w: _Watched, after_m: float) -> None:
        move = w.pending
        if move is None:
            return
        if not (math.isfinite(after_m) and abs(after_m) <= w.half_m):
            after_m = math.nan
        self.ctx.acq.mark(RECENTRE_EVENT, recentre_message(
            w.column, move.moved_m, move.before_m, after_m, move.t_start_s,
            move.t_end_s - move.t_start_s))
        w.pending = None

    def finish(self) -> None:
        """After the slide: wait for the moves still under way to end, and record them."""
        for w in self.watched:
            if w.pending is not None:
                self.ctx.wait_device_time(w.pending.t_end_s, WAIT_HOST_S)
                self._record(w, self.ctx.acq.latest().get(w.column, math.nan))

    def flush(self) -> None:
        """Record the moves still under way without waiting (a slide ended by an abort or a fault):
        every move made is in the record, its reading after unknown."""
        for w in self.watched:
            self._record(w, math.nan)


class RecentredSlide(MoveTangential):
    """A slide (:class:`MoveTangential`, unchanged drive) during which the probes are re-centred
    (:class:`Recentring`)."""

    name = "move_tangential"

    def __init__(self, distance_m: float, velocity_m_s: float, headroom_m: float) -> None:
        super().__init__(distance_m, velocity_m_s)
        self.headroom_m = float(headroom_m)

    def describe(self) -> str:
        return f"{super().describe()}, probes re-centred while sliding"

    def refuse(self, message: str) -> PlanError:
        """A refusal names the slide as a plain slide's would: the drive is what is refused."""
        return PlanError(f"step '{MoveTangential.describe(self)}': {message}")

    def run(self, ctx: RunContext) -> None:
        stage = ctx.tangential
        target = stage.position_m() + self.distance_m
        watch = Recentring(ctx, self.distance_m, self.headroom_m)
        try:
            drive_to(ctx, stage, target, self.velocity_m_s,
                     abs(self.distance_m) / self.velocity_m_s, while_moving=watch.poll)
            watch.finish()
        finally:
            watch.flush()


class ReturnProbeMounts(Step):
    """Move every probe's mount back to where it started (after the stage has returned)."""

    name = "return_probe_mounts"

    def describe(self) -> str:
        return "return the probe mounts to their start"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        return 0.0

    def run(self, ctx: RunContext) -> None:
        ctx.checkpoint()
        for column, probe in _probes(ctx):
            move = -probe.mount_m
            if move == 0.0:
                continue
            t0 = ctx.now_s()
            probe.move_mount(move)
            end = ctx.now_s() + abs(move) / probe.mount_speed_m_s + MOUNT_SETTLE_S
            ctx.wait_device_time(end, WAIT_HOST_S)
            try:
                after = probe.read_m()
            except OverRangeError:
                after = math.nan
            ctx.acq.mark(RECENTRE_EVENT,
                         recentre_message(column, move, math.nan, after, t0, end - t0))


def recentred(steps: list[Step], on: float, headroom_m: float) -> list[Step]:
    """``steps`` with the probes re-centred during every slide (``on`` 1), or unchanged (``on`` 0).

    Each :class:`MoveTangential` becomes a :class:`RecentredSlide` (the same drive: one piece, no
    stop); every return of the stage is followed by the mounts' return.
    """
    if on not in (0, 1):
        raise PlanError(f"parameter 'recentre_probes' must be 1 (on) or 0 (off), got {on:g}")
    if on == 0:
        return list(steps)
    if not (math.isfinite(headroom_m) and headroom_m >= MIN_HEADROOM_M):
        raise PlanError(f"parameter 'recentre_headroom_m' must be at least "
                        f"{MIN_HEADROOM_M * 1e6:g} um, got {headroom_m:g} m")
    out: list[Step] = []
    for step in steps:
        if isinstance(step, ReturnTangential):
            out += [step, ReturnProbeMounts()]
        elif isinstance(step, MoveTangential):
            out.append(RecentredSlide(step.distance_m, step.velocity_m_s, headroom_m))
        else:
            out.append(step)
    return out
