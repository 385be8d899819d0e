"""Delta stitched across the probes' re-centrings: continuous where the mounts moved.

A protocol that re-centres the probes (:mod:`experiments.recentre`) records every mount move as a
``probe_recentre`` event (:mod:`rigctl.storage.probe_events`): the move, and a time just after it
(the specimens at rest around it). Each probe column then drops by the move at one sample. The
stitched column adds every earlier move back, so delta = d1 - d2 is continuous across the
re-centring, as the specimen's displacement is.

The move is applied at the largest jump of the column within ``SEARCH_S`` before the event (the
event is written just after the move, a paced rig up to 0.25 s later); where the event states no
move (an operator's re-centring of unknown size, ``nan``), the jump measured there, the median of
``REST_SAMPLES`` after it minus the median before, is used instead. Over-range samples (the rail)
are never used to measure a jump.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from rigctl.data import FloatArray, MeasuredRun
from rigctl.storage.probe_events import RECENTRE_EVENT, parse_recentre
from rigctl.storage.reader import RunEvent

SEARCH_S = 0.45
"""How far before its event a move is looked for (the re-centring hold is 0.5 s either side)."""
REST_SAMPLES = 40
"""Samples either side of a jump whose medians measure it (39 ms at 1024 Hz)."""


def mount_moves(events: Iterable[RunEvent]) -> dict[str, list[tuple[float, float]]]:
    """(event time, move [m]; NaN if unknown) per probe column, in time order."""
    out: dict[str, list[tuple[float, float]]] = {}
    for ev in sorted(events, key=lambda e: e.t_s):
        if ev.name != RECENTRE_EVENT:
            continue
        parsed = parse_recentre(ev.message)
        if parsed is not None:
            out.setdefault(parsed[0], []).append((ev.t_s, parsed[1]))
    return out


def _jump_index(x: FloatArray, t: FloatArray, t_event_s: float) -> int | None:
    """Index of the first sample after the largest in-range step within SEARCH_S before the event."""
    near = np.flatnonzero((t > t_event_s - SEARCH_S) & (t <= t_event_s + 0.02))
    if near.size < 2:
        return None
    steps = np.abs(np.diff(x[near]))
    steps[~np.isfinite(steps)] = -1.0
    return int(near[int(np.argmax(steps))] + 1)


def stitched(x: FloatArray, t: FloatArray, moves: list[tuple[float, float]]) -> FloatArray:
    """Probe column ``x`` with every earlier mount move added back (see the module docstring)."""
    out = np.array(x, dtype=np.float64, copy=True)
    for t_ev, moved in moves:
        k = _jump_index(x, t, t_ev)
        if k is None:
            continue
        if not math.isfinite(moved):
            a, b = x[max(0, k - REST_SAMPLES):k], x[k:k + REST_SAMPLES]
            a, b = a[np.isfinite(a)], b[np.isfinite(b)]
            if a.size == 0 or b.size == 0:
                continue
            moved = float(np.median(a) - np.median(b))
        out[k:] += moved
    return out


def stitch_run(run: MeasuredRun, events: Iterable[RunEvent]) -> MeasuredRun:
    """``run`` with its probe columns stitched across the recorded re-centrings (the same object
    when there are none)."""
    moves = mount_moves(events)
    if not moves:
        return run
    cols = {c: stitched(getattr(run, c), run.t_s, moves[c]) if c in moves else getattr(run, c)
            for c in ("d1_m", "d2_m")}
    return MeasuredRun(run.t_s, run.x_stage_m, run.fn_N, run.ft_N, cols["d1_m"], cols["d2_m"],
                       dict(run.extra), dict(run.metadata), run.source)
