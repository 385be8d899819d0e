"""Delta stitched across the probes' re-centrings: the one reading of a re-centred probe column.

A protocol that re-centres the probes (:mod:`experiments.recentre`) moves a probe's mount while the
stage slides and records every move as a ``probe_recentre`` event (:mod:`rigctl.storage.probe_events`):
the move and the window of device time during which the mount may have been moving. The probe's
recorded column drops by the move across that window. The stitched column adds every earlier move
back, so delta = d1 - d2 is continuous across the re-centring, as the specimen's displacement is.
Every reader of a run file reads delta through here: the analysis (:mod:`rigctl.analysis.source`),
the workbench's prepared runs (:func:`rigctl.records.dataset.prepare_run`), the probes' validity
(:mod:`rigctl.records.probe_range`) and the CSV export (:mod:`rigctl.io.export`).

The recorded move is exact for a motorised mount: it is added to every sample after the window,
whatever the specimen did meanwhile (a stick phase, or even a slip, goes on during the move; a
jump measured there would take the specimen's motion for the mount's). Inside the window the
mount's position is not known sample by sample: those samples are bridged by a straight line from
the last sample before the window to the first after it (so the column has neither a jump nor a
spurious extreme). Where the specimen was steady across the move (the stitched column after the
window meets, within ``BRIDGE_STEADY_M``, the level before it or the line of the samples before it
carried over the window), the bridge is what the specimen did and its samples are read like the
others; where it was not (a slip under way, a probe back from its rail), the window's samples are
not valid for delta (:func:`unsteady_windows`, used by :func:`rigctl.records.probe_range.probe_range`).

Where an event states no move (``nan``: a re-centring of unknown size), the move is measured: the
median of ``REST_SAMPLES`` after the window minus the median before it (exact at rest only). An
event without a window (run files recorded before windows were stated, when the stage stopped for
each re-centring) is placed at the largest jump of the column within ``SEARCH_S`` before it.
Over-range samples (the rail) are never used to measure a jump.

A stitched run says so in its metadata (``STITCHED_KEY``: how many moves per probe were added
back), so that stitching it again changes nothing and an exported CSV states what its d1/d2 are.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path

import numpy as np

from rigctl.data import FloatArray, MeasuredRun
from rigctl.storage.probe_events import RECENTRE_EVENT, MountMove, parse_recentre
from rigctl.storage.reader import RunEvent

SEARCH_S = 0.45
"""How far before an event without a window its move is looked for (the old re-centring hold)."""
REST_SAMPLES = 40
"""Samples either side of a move whose medians measure it when its size is not stated, and over
which the line before a move is fitted to judge whether the specimen stayed steady."""
BRIDGE_STEADY_M = 0.5e-6
"""A move's bridge counts as measured when the stitched column after the window meets the level
before it, or the line of the samples before it carried over the window, within this much
(:func:`_steady`): the steadiness the protocol asks of a reading before it moves a mount
(``experiments.recentre.STEADY_M``), well below a slip of this rig."""
LEVEL_SAMPLES = 8
"""Samples either side of a move whose medians give the levels its steadiness is judged by."""
PROBE_COLUMNS = ("d1_m", "d2_m")
STITCHED_KEY = "delta.stitched"
"""Metadata key of a stitched run: the moves added back per probe column."""
RUN_FILE_SUFFIXES = (".h5", ".hdf5", ".nxs")
_WINDOW_SOURCE = re.compile(r"^(.*)#w\d+$")  # a window of a long record (records.long_records)


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
        if 0 < a < b < out.shape[0]:  # bridged (judged by unsteady_windows)
            out[a:b] = np.interp(t[a:b], (t[a - 1], t[b]), (out[a - 1], out[b]))
    return out


def _steady(x: FloatArray, t: FloatArray, a: int, b: int) -> bool:
    """The stitched column ``x`` after the window [a, b) meets, within BRIDGE_STEADY_M, the level
    before it (a stick, a post-slip relaxation dying out) or the line of the samples before it
    carried over the window (a steady creep or slide): medians of LEVEL_SAMPLES either side."""
    if a < LEVEL_SAMPLES or b + LEVEL_SAMPLES > x.shape[0]:
        return False
    before = slice(max(0, a - REST_SAMPLES), a)
    tb, xb = t[before], x[before]
    after_x, after_t = x[b:b + LEVEL_SAMPLES], t[b:b + LEVEL_SAMPLES]
    if not (np.all(np.isfinite(xb)) and np.all(np.isfinite(after_x))):
        return False
    level_after = float(np.median(after_x))
    change = level_after - float(np.median(x[a - LEVEL_SAMPLES:a]))
    slope, level = np.polyfit(tb - t[a - 1], xb, 1)
    carried = level_after - float(level + slope * (float(np.median(after_t)) - t[a - 1]))
    return min(abs(change), abs(carried)) <= BRIDGE_STEADY_M


def is_stitched(run: MeasuredRun) -> bool:
    """``run``'s probe columns are already stitched (:data:`STITCHED_KEY` in its metadata)."""
    return STITCHED_KEY in run.metadata


def stitch_run(run: MeasuredRun, events: Iterable[RunEvent]) -> MeasuredRun:
    """``run`` with its probe columns stitched across the recorded re-centrings (the same object
    when there are none, or when it is stitched already)."""
    if is_stitched(run):
        return run
    moves = mount_moves(events)
    if not moves:
        return run
    cols = {c: stitched(getattr(run, c), run.t_s, moves[c]) if c in moves else getattr(run, c)
            for c in PROBE_COLUMNS}
    said = "; ".join(f"{c}: {len(m)} mount move(s) added back" for c, m in moves.items())
    return replace(run, d1_m=cols["d1_m"], d2_m=cols["d2_m"], extra=dict(run.extra),
                   metadata={**run.metadata, STITCHED_KEY: said})


def unsteady_windows(run: MeasuredRun, events: Iterable[RunEvent]) -> dict[str, np.ndarray]:
    """Per probe column, the samples of the move windows across which the specimen was not steady
    (module docstring): no delta is read there. ``run`` stitched or not; {} without windows."""
    moves = mount_moves(events)
    t = run.t_s
    out: dict[str, np.ndarray] = {}
    for column, col_moves in moves.items():
        x = getattr(run, column) if is_stitched(run) else stitched(getattr(run, column), t,
                                                                   col_moves)
        for _t_ev, move in col_moves:
            if not move.has_window:
                continue
            a, b = _span(t, _t_ev, move, x) or (0, 0)
            if a < b and not _steady(x, t, a, b):
                out.setdefault(column, np.zeros(t.shape[0], dtype=bool))[a:b] = True
    return out


def record_file(run: MeasuredRun) -> Path | None:
    """The run file ``run`` was read from (a window of a long record: its record's), or None (a
    CSV, a simulation)."""
    src = run.source
    m = _WINDOW_SOURCE.match(src) if src else None
    path = Path(m.group(1) if m else src) if src else None
    if path is None or path.suffix.lower() not in RUN_FILE_SUFFIXES or not path.is_file():
        return None
    return path


def record_events(run: MeasuredRun) -> list[RunEvent]:
    """The events of the run file ``run`` was read from ([] for CSV, no events, or a file that
    cannot be read)."""
    path = record_file(run)
    if path is None:
        return []
    from rigctl.storage.reader import RunReader

    try:
        with RunReader(path) as reader:
            return reader.events()
    except (OSError, KeyError, ValueError):
        return []


def stitch_record(run: MeasuredRun) -> MeasuredRun:
    """``run`` stitched across the re-centrings its run file records (:func:`stitch_run` with
    :func:`record_events`)."""
    if is_stitched(run):
        return run
    return stitch_run(run, record_events(run))
