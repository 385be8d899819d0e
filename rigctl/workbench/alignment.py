"""Which simulated slip each measured slip is compared with.

Slip timing is sensitive: a model whose recurrence differs by 2 % is a whole cycle off after 50
cycles, so events are never paired by index over a run, and time series are never compared point by
point over many cycles (shared/spec/model.md). Pairing is local, within each drive segment (a stretch
of constant stage velocity and load):

* the first slip of a segment (the end of an initial stage, the first peak after a hold or a velocity
  step) is paired with the model's first slip of the same segment - these are the events where
  history effects show;
* every later measured slip is paired with the model slip nearest in time among the model's later
  slips of that segment, so features are compared at the same point of the protocol even when the
  two records have drifted out of phase.

A measured slip in a segment where the model has none is unpaired (-1); model slips in segments where
the measurement has none are *spurious* and counted separately.
"""

from __future__ import annotations

import numpy as np

from rigctl.workbench.features import EventTable


def match_events(measured: EventTable, model: EventTable) -> np.ndarray:
    """Index of the paired model event for every measured event (-1 when there is none)."""
    out = np.full(measured.n, -1, dtype=np.intp)
    if measured.n == 0 or model.n == 0:
        return out
    for seg in np.unique(measured.segment):
        mi = np.flatnonzero(measured.segment == seg)
        si = np.flatnonzero(model.segment == seg)
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


def spurious_counts(measured: EventTable, model: EventTable, n_segments: int) -> np.ndarray:
    """Model events in each segment where the measurement has no event (0 elsewhere)."""
    meas_counts = np.bincount(measured.segment, minlength=n_segments)[:n_segments]
    model_counts = np.bincount(model.segment, minlength=n_segments)[:n_segments]
    out: np.ndarray = np.where(meas_counts == 0, model_counts, 0)
    return out
