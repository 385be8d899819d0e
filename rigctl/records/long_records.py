"""Long records compared on windows: bounded time whatever the record's length.

Every evaluation of a model simulates each run over its whole drive, so a record of hours (tens of
thousands of slips) would make each of a fit's hundreds of evaluations take minutes. A record with
more than :data:`MAX_SLIPS` slips is therefore compared on :data:`N_WINDOWS` windows of
``MAX_SLIPS / N_WINDOWS`` consecutive slips, spread evenly over it by slip index (start, middle
and end of the record are all seen: wear or drift shows as a difference between windows). Each
window is cut from just after a slip's end and is read like any record that starts loaded: the
model runs a lead-in first (:func:`rigctl.records.dataset.lead_in`). The windows are copies, so
the record's full arrays can be freed once cut; the comparison then costs the same for one hour
as for ten.

The slips are counted with the workbench's own detector (:func:`~rigctl.records.events.detect_slips`)
on the full record: one vectorised pass, about 0.1 s per million samples.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.records.drive_profile import drive_profile
from rigctl.records.events import DetectionSettings, detect_slips

MAX_SLIPS = 480
"""Slips of one record compared in full; above this the record is windowed. A cost bound: several
times the slips of one protocol run (tens to a hundred), so protocol runs are compared in full and
only records of long sliding are windowed. The value is a choice, not derived
(docs/decisions.md)."""
N_WINDOWS = 8
"""Windows a long record is compared on (their slips: MAX_SLIPS / N_WINDOWS each)."""
WINDOW_KEY = "rigctl_windows"
"""Metadata key the first window of a record carries: the note saying how it was windowed."""


def window_long_runs(runs: list[MeasuredRun], max_slips: int = MAX_SLIPS,
                     n_windows: int = N_WINDOWS) -> list[MeasuredRun]:
    """``runs`` with every record of more than ``max_slips`` slips replaced by ``n_windows``
    windows of ``max_slips // n_windows`` slips (see the module docstring); shorter ones as given."""
    out: list[MeasuredRun] = []
    for i, run in enumerate(runs):
        out.extend(_windows(run, run.source or f"run{i + 1}", max_slips, n_windows))
    return out


def _windows(run: MeasuredRun, name: str, max_slips: int, n_windows: int) -> list[MeasuredRun]:
    if run.n_samples < 64:
        return [run]
    t = run.t_s - run.t_s[0]
    prof = drive_profile(run)
    det = DetectionSettings.from_signal(run.ft_N)
    slips = detect_slips(t, run.ft_N, run.delta_m, det, v_drive_m_s=prof.sliding_velocity_at(t),
                         fn_N=run.fn_N)
    n = slips.n
    if n <= max_slips:
        return [run]
    per = max(2, max_slips // n_windows)
    firsts = np.linspace(0, n - per - 1, n_windows).round().astype(int)
    cuts = []
    for j0 in firsts:
        # from just after the end of the slip before the window's first to the end of its last
        j_last = min(int(j0) + per, n - 1)
        cuts.append((int(slips.i_end[j0]) + 1, min(int(slips.i_end[j_last]) + 1, run.n_samples)))
    spans = ", ".join(f"{run.t_s[a] - run.t_s[0]:.0f}-{run.t_s[b - 1] - run.t_s[0]:.0f}"
                      for a, b in cuts)
    note = (f"{name}: a long record ({n:,} slips over {run.duration_s:,.0f} s) is compared on "
            f"{n_windows} windows of {per} slips spread over it (t = {spans} s)")
    out: list[MeasuredRun] = []
    for k, (i0, i1) in enumerate(cuts):
        out.append(replace(
            run,
            t_s=run.t_s[i0:i1].copy(), x_stage_m=run.x_stage_m[i0:i1].copy(),
            fn_N=run.fn_N[i0:i1].copy(), ft_N=run.ft_N[i0:i1].copy(),
            d1_m=run.d1_m[i0:i1].copy(), d2_m=run.d2_m[i0:i1].copy(),
            extra={c: a[i0:i1].copy() for c, a in run.extra.items()},
            metadata={**run.metadata, **({WINDOW_KEY: note} if k == 0 else {})},
            source=f"{name}#w{k + 1}",
        ))
    return out
