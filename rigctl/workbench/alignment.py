"""Which simulated slip each measured slip is compared with.

Slip timing is sensitive: a model whose recurrence differs by 2 % is a whole cycle off after 50
cycles, so events are never paired by index over a run, and time series are never compared point by
point over many cycles (docs/model.md). Pairing is local, within each drive segment (a stretch
of constant stage velocity and load):

* the first slip of a segment (the end of an initial stage, the first peak after a hold or a velocity
  step) is paired with the model's first slip of the same segment - these are the events where
  history effects show;
* every later measured slip is paired with the model slip nearest in time among the model's later
  slips of that segment, so features are compared at the same point of the protocol even when the
  two records have drifted out of phase.

A measured slip in a segment where the model has none is unpaired (-1); model slips in segments where
the measurement has none are *spurious* and counted separately. Where the model has only its first
slip in a segment, the measurement's later slips are compared with that one slip, which then *stands
in* for the later slips the model does not make (:func:`stand_in_pairs`): the error charges such a
pair at most what a missing slip costs (:mod:`rigctl.workbench.metrics`), because a first slip (the
end of an initial stage, a peak after a hold) can differ from a stable one by far more than any
model's stable slip would.

**A slip at a stop is a tie.** When the stage stops with the interface a hair below its threshold,
whether the slip comes at the stop or when the stage restarts, a whole hold later, is decided by
sub-micrometre differences (the stop's corner is located to a few samples in the measured stage
position). Both are the same stick cycle: the same peak and drop, the same stage travel. So for
pairing, a slip within ``HOLD_TIE_S`` of the start of a hold is counted as the first slip of the
phase after the hold, in the measurement and in the model alike (:func:`pairing_segments`).
Without this, one stick cycle that slipped at the stop in one record and at the restart in the
other is charged as a missing slip in the hold and paired with the wrong cycle after it, even for
the generating model, and an effect that shifts slips in time is credited with the tie
(docs/validation.md; the case: docs/decisions.md).
"""

from __future__ import annotations

import numpy as np

from rigctl.records.drive_profile import DriveProfile
from rigctl.records.features import EventTable

HOLD_TIE_S = 0.02
"""A slip this close after the start of a hold (the stop) is a tie with a slip at its end (the
restart): 20 samples at 1024 Hz, well above the few samples to which the stop is located."""


def pairing_segments(events: EventTable, drive: DriveProfile | None) -> np.ndarray:
    """Each event's drive segment for pairing: a slip within HOLD_TIE_S of a hold's start counts
    in the phase after the hold (see the module docstring); other slips keep their segment."""
    seg = np.array(events.segment, dtype=np.intp, copy=True)
    if drive is None or events.n == 0:
        return seg
    hold = drive.phase_is_hold
    starts = drive.t_s[drive.phase_knots[:-1]]
    for k in np.flatnonzero(hold[:-1]):
        tie = (seg == k) & (events.t_drop_s - starts[k] <= HOLD_TIE_S)
        seg[tie] = k + 1
    return seg


Segments = tuple[np.ndarray, np.ndarray]
"""The pairing segments (:func:`pairing_segments`) of the measured events and of the model's."""


def segments_of(measured: EventTable, model: EventTable, drive: DriveProfile | None) -> Segments:
    """:func:`pairing_segments` of both event tables: what the functions below share (a caller
    that runs several of them on one pair of tables passes them once)."""
    return pairing_segments(measured, drive), pairing_segments(model, drive)


def match_events(measured: EventTable, model: EventTable,
                 drive: DriveProfile | None = None, segments: Segments | None = None,
                 ) -> np.ndarray:
    """Index of the paired model event for every measured event (-1 when there is none).

    With the run's ``drive``, slips at a stop pair with slips at the restart (pairing_segments;
    ``segments``: :func:`segments_of` these tables and drive, made already)."""
    out = np.full(measured.n, -1, dtype=np.intp)
    if measured.n == 0 or model.n == 0:
        return out
    seg_meas, seg_model = segments or segments_of(measured, model, drive)
    for seg in np.unique(seg_meas):
        mi = np.flatnonzero(seg_meas == seg)
        si = np.flatnonzero(seg_model == seg)
        if si.size == 0:
            continue
        out[mi[0]] = si[0]
        rest = si[1:] if si.size > 1 else si
        if mi.size > 1:
            t_model = model.t_drop_s[rest]
            pos = np.searchsorted(t_model, measured.t_drop_s[mi[1:]])
            lo = np.clip(pos - 1, 0, rest.size - 1)
            hi = np.clip(pos, 0, rest.size - 1)
            d_lo = np.abs(t_model[lo] - measured.t_drop_s[mi[1:]])
            d_hi = np.abs(t_model[hi] - measured.t_drop_s[mi[1:]])
            out[mi[1:]] = rest[np.where(d_hi < d_lo, hi, lo)]
    return out


def stand_in_pairs(measured: EventTable, model: EventTable, match: np.ndarray,
                   drive: DriveProfile | None = None, segments: Segments | None = None,
                   ) -> np.ndarray:
    """Per measured event: paired (by :func:`match_events`) with the model's first slip of its
    segment although it is not the measurement's first slip there - the model has no later slip to
    compare it with (see the module docstring)."""
    out = np.zeros(measured.n, dtype=bool)
    if measured.n == 0 or model.n == 0:
        return out
    seg_meas, seg_model = segments or segments_of(measured, model, drive)
    first_meas = np.r_[True, seg_meas[1:] != seg_meas[:-1]]
    first_model = np.r_[True, seg_model[1:] != seg_model[:-1]]
    paired = match >= 0
    out[paired] = first_model[match[paired]] & ~first_meas[paired]
    return out


def spurious_counts(measured: EventTable, model: EventTable, n_segments: int,
                    drive: DriveProfile | None = None, segments: Segments | None = None,
                    ) -> np.ndarray:
    """Model events in each segment where the measurement has no event (0 elsewhere); with the
    run's ``drive``, segments as for pairing (a slip at a stop counts after the hold)."""
    seg_meas, seg_model = segments or segments_of(measured, model, drive)
    meas_counts = np.bincount(seg_meas, minlength=n_segments)[:n_segments]
    model_counts = np.bincount(seg_model, minlength=n_segments)[:n_segments]
    out: np.ndarray = np.where(meas_counts == 0, model_counts, 0)
    return out
