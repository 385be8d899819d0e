"""Delta stitched across the probes' re-centrings: continuous where the mounts moved.

A protocol that re-centres the probes (:mod:`experiments.recentre`) moves a probe's mount while the
stage slides and records every move as a ``probe_recentre`` event (:mod:`rigctl.storage.probe_events`):
the move and the window of device time during which the mount may have been moving. The probe's
column drops by the move across that window. The stitched column adds every earlier move back, so
delta = d1 - d2 is continuous across the re-centring, as the specimen's displacement is.

The recorded move is exact for a motorised mount: it is added to every sample after the window,
whatever the specimen did meanwhile (mid-slide, a stick phase or even a slip goes on during the
move; a jump measured there would take the specimen's motion for the mount's). Inside the window the
mount's position is not known sample by sample: those samples are bridged by a straight line from
the last sample before the window to the first after it (so the column has neither a jump nor a
spurious extreme) and marked: :func:`rigctl.storage.probe_events.moving_masks` gives them per
column, and :func:`rigctl.records.probe_range.probe_range` leaves delta out there.

Where an event states no move (``nan``: a re-centring of unknown size), the move is measured: the
median of ``REST_SAMPLES`` after the window minus the median before it (exact at rest only). An
event without a window (run files recorded before windows were stated, when the stage stopped for
each re-centring) is placed at the largest jump of the column within ``SEARCH_S`` before it.
Over-range samples (the rail) are never used to measure a jump.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from rigctl.data import FloatArray, MeasuredRun
from rigctl.storage.probe_events import RECENTRE_EVENT, MountMove, parse_recentre
from rigctl.storage.reader import RunEvent

SEARCH_S = 0.45
"""How far before an event without a window its move is looked for (the old re-centring hold)."""
REST_SAMPLES = 40
"""Samples either side of a move whose medians measure it when its size is not stated."""
PROBE_COLUMNS = ("d1_m", "d2_m")


def mount_moves(events: Iterable[RunEvent]) -> dict[str, list[tuple[float, MountMove]]]:
    """(event time, the move) per probe column, in time order."""
    out: dict[str, list[tuple[float, MountMove]]] = {}
    for ev in sorted(events, key=lambda e: e.t_s):
        if ev.name != RECENTRE_EVENT:
            continue
        move = parse_recentre(ev.message)
        if move is not None and move.column in PROBE_COLUMNS:
            out.setdefault(move.column, []).append((ev.t_s, move))
    return out


def _jump_index(x: FloatArray, t: FloatArray, t_event_s: float) -> int | None:
    """Index of the first sample after the largest in-range step within SEARCH_S before the event."""
    near = np.flatnonzero((t > t_event_s - SEARCH_S) & (t <= t_event_s + 0.02))
    if near.size < 2:
        return None
    steps = np.abs(np.diff(x[near]))
    steps[~np.isfinite(steps)] = -1.0
    return int(near[int(np.argmax(steps))] + 1)


def _measured(x: FloatArray, a: int, b: int) -> float:
    """The drop of ``x`` from the samples before index ``a`` to those from ``b`` on (NaN if none in
    range)."""
    before, after = x[max(0, a - REST_SAMPLES):a], x[b:b + REST_SAMPLES]
    before, after = before[np.isfinite(before)], after[np.isfinite(after)]
    if before.size == 0 or after.size == 0:
        return math.nan
    return float(np.median(before) - np.median(after))


def _span(t: FloatArray, t_event_s: float, move: MountMove, x: FloatArray) -> tuple[int, int] | None:
    """[a, b): the samples during which the mount moved (a == b: a step between two samples)."""
    if move.has_window:
        a = int(np.searchsorted(t, move.t_start_s, side="right"))
        b = int(np.searchsorted(t, move.t_start_s + move.duration_s, side="right"))
        return a, b
    k = _jump_index(x, t, t_event_s)
    return None if k is None else (k, k)


def stitched(x: FloatArray, t: FloatArray, moves: list[tuple[float, MountMove]]) -> FloatArray:
    """Probe column ``x`` with every earlier mount move added back (see the module docstring)."""
    out = np.array(x, dtype=np.float64, copy=True)
    for t_ev, move in moves:
        span = _span(t, t_ev, move, x)
        if span is None:
            continue
        a, b = span
        moved = move.moved_m if math.isfinite(move.moved_m) else _measured(x, a, b)
        if not math.isfinite(moved):
            continue
        out[b:] += moved
        if 0 < a < b < out.shape[0]:  # bridged (those samples are marked: moving_masks)
            out[a:b] = np.interp(t[a:b], (t[a - 1], t[b]), (out[a - 1], out[b]))
    return out


def stitch_run(run: MeasuredRun, events: Iterable[RunEvent]) -> MeasuredRun:
    """``run`` with its probe columns stitched across the recorded re-centrings (the same object
    when there are none)."""
    moves = mount_moves(events)
    if not moves:
        return run
    cols = {c: stitched(getattr(run, c), run.t_s, moves[c]) if c in moves else getattr(run, c)
            for c in PROBE_COLUMNS}
    return MeasuredRun(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, cols["d1_m"], cols["d2_m"],
                       dict(run.extra), dict(run.metadata), run.source)
