"""Re-centring the displacement probes during a slide, as the lab does, and putting them back.

A fibre-optic probe measures 74 um about its stand-off (MTI-2100 + RS2032R, Han et al. 2022,
Sec. 2.1); the probe on the driven specimen (D1) follows the slide, hundreds of micrometres per
run. Re-zeroing the electronics does not bring a target that left the range back: the probe itself
has to move. So the protocols (parameter ``recentre_probes``, 1 by default) stop the drive every
``recentre_every_m`` of stage travel, let the
specimens come to rest, move each probe's mount (:meth:`DisplacementProbe.move_mount`) so that its
reading goes to ``TARGET_FRACTION`` of the half range behind the centre (the slide then has most of
the range in front of it), and record each move as a ``probe_recentre`` event (time and the move,
:mod:`rigctl.storage.probe_events`), from which the analysis stitches delta
(:mod:`rigctl.analysis.delta_stitch`). After the stage has returned, :class:`ReturnProbeMounts`
brings the mounts back to where they started.

A re-centring that cannot be made (a manual mount, a move beyond the mount's travel, a probe already
over range) is recorded as a ``probe_not_recentred`` event with the reason and the protocol goes on:
the forces are still measured, only delta goes over range as it would have without the step.
"""

from __future__ import annotations

import math

from drivers.errors import LimitError, NotSupportedError, OverRangeError
from drivers.interfaces import DisplacementProbe
from experiments.context import RigLimits, RunContext
from experiments.errors import PlanError
from experiments.steps import Hold, MoveTangential, PlanState, ReturnTangential, Step, hold_device_time
from rigctl.storage.probe_events import NOT_RECENTRED_EVENT, RECENTRE_EVENT, recentre_message

TARGET_FRACTION = 0.8
"""Where a re-centred reading goes: this fraction of the half range behind the centre (-29.6 um of
the MTI-2100's +-37 um for a slide in +x), leaving 66.6 um of range for the slide ahead."""
RECENTRE_HOLD_S = 1.0
"""Stage at rest around a re-centring made between two pieces of a slide: half before the mount
moves (the specimens come to rest, the analysis has a reference), half after."""
MIN_MOVE_M = 1e-6
"""A probe already within this of its target is not moved."""
MIN_EVERY_M = 5e-6
"""Shortest stage travel between re-centrings accepted (0 turns them off)."""


def _probes(ctx: RunContext) -> list[tuple[str, DisplacementProbe]]:
    """The run's probes with the recorded column each one feeds."""
    found = (("d1_m", ctx.devices.d1), ("d2_m", ctx.devices.d2))
    return [(column, probe) for column, probe in found if probe is not None]


class RecentreProbes(Step):
    """Hold, move each probe's mount so its reading goes to its target, record the moves, hold."""

    name = "recentre_probes"

    def __init__(self, direction: float, hold_s: float = RECENTRE_HOLD_S) -> None:
        self.direction = 1.0 if direction >= 0 else -1.0
        self.hold_s = float(hold_s)

    def describe(self) -> str:
        held = f" (stage at rest {self.hold_s:g} s)" if self.hold_s > 0 else ""
        return f"re-centre the probes{held}"

    def plan(self, state: PlanState, limits: RigLimits) -> float:
        if not (self.hold_s >= 0 and math.isfinite(self.hold_s)):
            raise self.refuse(f"hold must be >= 0 s, got {self.hold_s:g}")
        return self.hold_s

    def run(self, ctx: RunContext) -> None:
        hold_device_time(ctx, 0.5 * self.hold_s)
        for column, probe in _probes(ctx):
            self._recentre(ctx, column, probe)
        hold_device_time(ctx, 0.5 * self.hold_s)

    def _recentre(self, ctx: RunContext, column: str, probe: DisplacementProbe) -> None:
        try:
            before = probe.read_m()
        except OverRangeError:
            ctx.acq.mark(NOT_RECENTRED_EVENT, f"{column}: over range, its reading unknown: not "
                         "moved (shorten recentre_every_m)")
            return
        target = -self.direction * TARGET_FRACTION * 0.5 * probe.range_m
        move = before - target
        if abs(move) < MIN_MOVE_M:
            return
        try:
            probe.move_mount(move)
        except (LimitError, NotSupportedError) as exc:
            ctx.acq.mark(NOT_RECENTRED_EVENT, f"{column}: {exc}")
            return
        ctx.acq.mark(RECENTRE_EVENT, recentre_message(column, move, before, before - move))


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
            move = probe.mount_m
            if move == 0.0:
                continue
            probe.move_mount(-move)
            try:
                after = probe.read_m()
            except OverRangeError:
                after = math.nan
            ctx.acq.mark(RECENTRE_EVENT, recentre_message(column, -move, math.nan, after))


def recentred(steps: list[Step], on: float, every_m: float) -> list[Step]:
    """``steps`` with the probes re-centred every ``every_m`` of each slide (``on`` 1), or
    unchanged (``on`` 0).

    Each slide (:class:`MoveTangential`) is cut into pieces of at most ``every_m``; before each
    piece the probes are re-centred: in the middle of the hold that comes before it, where there is
    one (a settle or a slide-hold-slide hold keeps its length), else in a hold of
    :data:`RECENTRE_HOLD_S`. Every return of the stage is followed by the mounts' return.
    """
    if on not in (0, 1):
        raise PlanError(f"parameter 'recentre_probes' must be 1 (on) or 0 (off), got {on:g}")
    if on == 0:
        return list(steps)
    if not (math.isfinite(every_m) and every_m >= MIN_EVERY_M):
        raise PlanError(f"parameter 'recentre_every_m' must be at least {MIN_EVERY_M * 1e6:g} um, "
                        f"got {every_m:g} m")
    out: list[Step] = []
    for step in steps:
        if isinstance(step, ReturnTangential):
            out += [step, ReturnProbeMounts()]
            continue
        if not isinstance(step, MoveTangential):
            out.append(step)
            continue
        pieces = max(1, math.ceil(abs(step.distance_m) / every_m - 1e-9))
        piece_m = step.distance_m / pieces
        for _ in range(pieces):
            before = out[-1] if out else None
            if isinstance(before, Hold) and before.seconds > 0:
                half = 0.5 * before.seconds
                out[-1] = Hold(half, before.label)
                out += [RecentreProbes(piece_m, hold_s=0.0), Hold(half, before.label)]
            else:
                out.append(RecentreProbes(piece_m))
            out.append(MoveTangential(piece_m, step.velocity_m_s))
    return out
