"""Tangential passes of a run: each stretch where the loaded specimen is dragged forward.

A TLRE file holds three passes (paper Sec. 2.2: load, slide, release, return, three times), a force
sweep one per normal force (Sec. 4.1), a simulated or imported run usually one. Each pass starts
from rest, so it has its own initial stage (paper Sec. 3.1).

The passes are read from the drive the workbench simplifies every run to
(:func:`rigctl.records.drive_profile.drive_profile`): a pass is a run of consecutive forward-sliding
phases whose normal force stays above the "apart" level (:func:`fn_apart_N`) at both ends. Creep
phases slower than ``MIN_SPEED_FRACTION`` of the run's fastest loaded slide (a stage settling while
the load is released) are not slides. A pass's samples run from up to ``REST_BEFORE_S`` before the
stage starts (the force baseline) to where it stops.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigctl.data import DataError, MeasuredRun
from rigctl.records.drive_profile import DriveProfile, drive_profile, fn_apart_N

MIN_SPEED_FRACTION = 0.02
REST_BEFORE_S = 2.0


@dataclass(frozen=True)
class Pass:
    """One forward slide under load (sample indices into the run; times in run seconds)."""

    index: int
    i0: int
    """First sample of the pass (rest before the motion included)."""
    i1: int
    """One past the last sample."""
    t_motion_s: float
    """When the stage starts to move."""
    t_end_s: float
    """When it stops."""
    fn_N: float
    """Median normal force while sliding."""
    velocity_m_s: float
    """Mean drive velocity (stage travel / time)."""

    def slice(self, run: MeasuredRun) -> MeasuredRun:
        """The pass's samples as a run of their own (absolute times kept)."""
        sl = slice(self.i0, self.i1)
        return MeasuredRun(
            run.t_s[sl], run.x_stage_m[sl], run.fn_N[sl], run.ft_N[sl], run.d1_m[sl],
            run.d2_m[sl], {k: v[sl] for k, v in run.extra.items()}, dict(run.metadata),
            run.source,
        )


def find_passes(run: MeasuredRun, drive: DriveProfile | None = None) -> list[Pass]:
    """The forward passes under load of ``run`` ([] if the stage never slides under load)."""
    try:
        prof = drive if drive is not None else drive_profile(run)
    except DataError:
        return []
    k = prof.phase_knots
    t_k = prof.t_s[k] + prof.t0_s
    v = prof.phase_velocity
    hold = prof.phase_is_hold
    fn_thr = fn_apart_N(run.fn_N)
    fn_a = prof.fn_N[k[:-1]]
    fn_b = prof.fn_N[k[1:]]
    loaded = (fn_a > fn_thr) & (fn_b > fn_thr)
    fwd = (v > 0) & ~hold & loaded
    if not fwd.any():
        return []
    v_min = MIN_SPEED_FRACTION * float(np.max(v[fwd]))
    sliding = fwd & (v >= v_min)
    passes: list[Pass] = []
    j = 0
    n_ph = sliding.shape[0]
    t = run.t_s
    while j < n_ph:
        if not sliding[j]:
            j += 1
            continue
        a = j
        while j + 1 < n_ph and sliding[j + 1]:
            j += 1
        t_a, t_b = float(t_k[a]), float(t_k[j + 1])
        i_m = int(np.searchsorted(t, t_a))
        i1 = int(np.searchsorted(t, t_b, side="right"))
        # the rest before the motion, but not before the load reached its level
        t_rest = max(t_a - REST_BEFORE_S, float(t_k[a - 1]) if a > 0 else float(t[0]))
        i0 = min(int(np.searchsorted(t, t_rest)), i_m)
        sel = slice(i_m, i1)
        fn = float(np.median(run.fn_N[sel])) if i1 > i_m else float("nan")
        span = t_b - t_a
        vel = float((prof.x_at(np.array([t_b - prof.t0_s]))[0]
                     - prof.x_at(np.array([t_a - prof.t0_s]))[0]) / span) if span > 0 else 0.0
        if i1 - i0 >= 64:
            passes.append(Pass(len(passes), i0, i1, t_a, t_b, fn, vel))
        j += 1
    return passes
