"""Force-sweep summary (paper Sec. 4.1, Figs. 10-11): the passes of a campaign against Fn.

A sweep is any set of passes at different normal forces: one force-sweep file (one pass per force)
or a folder of runs. Per pass: Fn, mu_s,max, mu_s, mu_k (with spread), K(1), K(i) of every cycle,
Im(1) when the run has frames (Fig. 11c-d: Im(1) against Fn, K(1) against Im(1); the sweep's notes
say "no camera frames" when no run has them), and how strongly it sticks and slips:

* ``relative_drop`` = median over the stable cycles of drop / peak (0 when the pass has no stable
  slip): the size of the stick-slip oscillation against the force level.

Where stick-slip fades (paper: "the stick-slip motion decreases gradually at 200 N ... with the
continuing decrease of normal force, stick-slip motion disappears finally"), read from the passes
sorted by Fn:

* ``vanishes_below_N``: the lowest Fn with stable stick-slip, when every lower Fn has none (NaN when
  stick-slip is present at the lowest force, or absent everywhere);
* ``fades_below_N``: the lowest Fn whose relative drop is at least ``FADE_FRACTION`` of the sweep's
  largest, when some lower Fn falls under that fraction (NaN if none does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rigctl.analysis.friction import FrictionCoefficients
from rigctl.analysis.stickslip import PassRecord
from rigctl.analysis.stiffness import CycleStiffness

FADE_FRACTION = 0.5


@dataclass(frozen=True)
class SweepPoint:
    """One pass of a sweep."""

    run: str
    pass_index: int
    fn_N: float
    friction: FrictionCoefficients
    k1_N_per_m: float
    k_N_per_m: tuple[float, ...]
    """K(i) of every cycle."""
    n_stable: int
    relative_drop: float
    im1: float = math.nan
    """Im(1), the mean contact intensity over the K(1) window (NaN without frames)."""

    def to_dict(self) -> dict[str, object]:
        return {
            "run": self.run, "pass": self.pass_index + 1, "fn_N": self.fn_N,
            "friction": self.friction.to_dict(), "K1_N_per_m": self.k1_N_per_m,
            "K_N_per_m": list(self.k_N_per_m), "n_stable_cycles": self.n_stable,
            "relative_drop": self.relative_drop, "Im1": self.im1,
        }


def sweep_point(run: str, rec: PassRecord, fc: FrictionCoefficients,
                stiff: list[CycleStiffness], im1: float = math.nan) -> SweepPoint:
    st = rec.stable
    c = rec.cycles
    rel = c.drop_N[st] / c.peak_N[st] if st.any() else np.zeros(0)
    rel = rel[np.isfinite(rel)]
    k = tuple(float(s.k.k_N_per_m) for s in stiff)
    return SweepPoint(run, rec.pas.index, rec.pas.fn_N, fc, k[0] if k else math.nan, k,
                      int(np.count_nonzero(st)), float(np.median(rel)) if rel.size else 0.0, im1)


@dataclass
class SweepSummary:
    points: list[SweepPoint]
    vanishes_below_N: float
    fades_below_N: float
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, object]:
        return {
            "points": [p.to_dict() for p in self.points],
            "stick_slip_vanishes_below_N": self.vanishes_below_N,
            "stick_slip_fades_below_N": self.fades_below_N,
            "notes": list(self.notes),
        }


def summarise(points: list[SweepPoint]) -> SweepSummary:
    """Sort by Fn and find where stick-slip fades (module docstring)."""
    pts = sorted(points, key=lambda p: p.fn_N)
    notes: list[str] = []
    fns = np.array([p.fn_N for p in pts])
    if np.unique(np.round(fns)).size < 2:
        notes.append("fewer than two normal forces: no force dependence to show")
    im1 = np.array([p.im1 for p in pts], dtype=np.float64)
    if pts and not np.isfinite(im1).any():
        notes.append("no camera frames: Im(1) against Fn and K(1) against Im(1) (Fig. 11c-d) "
                     "not measured")
    elif not np.isfinite(im1).all():
        missing = sorted({p.run for p, m in zip(pts, im1, strict=True) if not math.isfinite(m)})
        notes.append("no camera frames (or no Im(1)) in " + ", ".join(missing)
                     + ": left out of Fig. 11c-d")
    present = np.array([p.n_stable > 0 and p.relative_drop > 0 for p in pts], dtype=bool)
    vanish = math.nan
    if present.any() and not present.all():
        first = int(np.flatnonzero(present)[0])
        if first > 0 and not present[:first].any() and present[first:].all():
            vanish = float(fns[first])
    fade = math.nan
    rel = np.array([p.relative_drop for p in pts])
    if rel.size and float(np.max(rel)) > 0:
        strong = rel >= FADE_FRACTION * float(np.max(rel))
        first = int(np.flatnonzero(strong)[0])
        if first > 0:
            fade = float(fns[first])
    return SweepSummary(pts, vanish, fade, notes)
