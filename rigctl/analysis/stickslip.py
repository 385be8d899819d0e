"""Stages and stick/slip cycles of one tangential pass (paper Sec. 3.1, Fig. 5).

Slips are found by the project's one slip detector, the workbench's
(:func:`rigctl.records.dataset.prepare_run`: :mod:`rigctl.records.events` for the drops and
:mod:`rigctl.records.features` for their levels), so the analysis and ``rigctl model compare``
read the same events. Every slip ends a stick; cycle i is the stick that ends in slip i and the slip
itself:

* **initial stage**: from the start of the motion to the first slip, when the pass starts from rest
  (Ft near zero): Ft rises from 0 with a bending Ft-delta curve to the threshold of Coulomb friction
  (paper: "When the tangential force reaches the threshold ... it decreases rapidly");
* **stable stage**: every later cycle ("the tangential force fluctuates stably in a certain range").

Per cycle (the workbench's definitions, levels from line fits either side of the drop, never single
samples, so neither noise nor the aliased 1 kHz ringing after a slip moves them):

==================  ==========================================================================
``t_start_s``       stick start: end of the previous slip (its drop time + the settle time) or
                    the start of the motion for the first cycle
``t_peak_s``        slip start: the drop time (Ft falls through half its drop)
``t_end_s``         slip end: drop time + settle time (the ringing has died)
``peak_N``          Ft at the drop, from the pre-drop loading line
``trough_N``        settled post-slip Ft, the next stick's line extrapolated back to the drop
``drop_N``          peak - trough
``stick_s``         stick duration (stage travel since the previous drop / drive velocity)
``slip_m``          jump of delta across the slip (NaN where a probe was over range)
``fn_N``            normal force at the drop
==================  ==========================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigctl.analysis.passes import Pass
from rigctl.data import DataError, FloatArray, MeasuredRun
from rigctl.records.dataset import PreparedRun, prepare_run
from rigctl.records.probe_range import probe_range

STAGE_INITIAL = "initial"
STAGE_STABLE = "stable"


@dataclass
class CycleTable:
    """Stick/slip cycles of one pass (equal-length arrays; times in run seconds)."""

    stage: list[str]
    t_start_s: FloatArray
    t_peak_s: FloatArray
    t_end_s: FloatArray
    peak_N: FloatArray
    trough_N: FloatArray
    drop_N: FloatArray
    stick_s: FloatArray
    slip_m: FloatArray
    fn_N: FloatArray

    @property
    def n(self) -> int:
        return len(self.stage)

    def rows(self) -> list[dict[str, float | str | int]]:
        """One dict per cycle (JSON-ready; NaN stays NaN)."""
        out: list[dict[str, float | str | int]] = []
        for j in range(self.n):
            out.append({
                "cycle": j + 1, "stage": self.stage[j],
                **{name: float(getattr(self, name)[j]) for name in CYCLE_COLUMNS},
            })
        return out


CYCLE_COLUMNS: tuple[str, ...] = (
    "t_start_s", "t_peak_s", "t_end_s", "peak_N", "trough_N", "drop_N", "stick_s", "slip_m", "fn_N",
)


@dataclass
class PassRecord:
    """A pass with its samples, slips and cycles."""

    pas: Pass
    run: MeasuredRun
    """The pass's samples (absolute times)."""
    prepared: PreparedRun
    cycles: CycleTable
    delta_valid: np.ndarray
    """Per sample of ``run``: True where both probes were in range."""
    has_initial: bool
    """The pass starts from rest, so its first cycle is the initial stage."""
    notes: list[str]

    @property
    def stable(self) -> np.ndarray:
        """Mask of the stable-stage cycles."""
        return np.array([s == STAGE_STABLE for s in self.cycles.stage], dtype=bool)


def read_pass(run: MeasuredRun, pas: Pass) -> PassRecord:
    """Detect the slips of one pass and build its cycle table (DataError if it cannot be read)."""
    sub = pas.slice(run)
    name = f"pass {pas.index + 1}"
    prepared = prepare_run(sub, name)
    ev = prepared.events
    settle = prepared.read.settle_s
    t0 = float(sub.t_s[0])
    t_drop = ev.t_drop_s + t0
    n = ev.n
    has_initial = bool(n and ev.stage[0] == 0)
    stage = [STAGE_INITIAL if (j == 0 and has_initial) else STAGE_STABLE for j in range(n)]
    t_start = np.empty(n)
    if n:
        t_start[0] = pas.t_motion_s
        t_start[1:] = t_drop[:-1] + settle
    f = ev.features
    cycles = CycleTable(
        stage, t_start, t_drop.copy(), t_drop + settle, f["peak_N"].copy(), f["trough_N"].copy(),
        f["drop_N"].copy(), f["stick_s"].copy(), f["slip_m"].copy(), ev.covariates["fn_N"].copy(),
    )
    probes = probe_range(sub)
    notes = list(prepared.notes)
    if n == 0:
        notes.append(f"{name}: no slip detected (no stick-slip at Fn = {pas.fn_N:.0f} N, or the "
                     "slide ended before the threshold)")
    elif not has_initial:
        notes.append(f"{name}: the pass does not start from rest (Ft not near 0 at the motion "
                     "start): no initial stage, mu_s,max not measured")
    return PassRecord(pas, sub, prepared, cycles, probes.delta_valid, has_initial, notes)


def read_passes(run: MeasuredRun, passes: list[Pass]) -> tuple[list[PassRecord], list[str]]:
    """Every pass that can be read, and a note for each that cannot."""
    out: list[PassRecord] = []
    notes: list[str] = []
    for p in passes:
        try:
            out.append(read_pass(run, p))
        except DataError as exc:
            notes.append(f"pass {p.index + 1} not analysed: {exc}")
    return out, notes
