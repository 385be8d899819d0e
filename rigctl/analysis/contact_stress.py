"""The equivalent stress distribution P(x, t) and the mean contact intensity Im(i) (Sec. 3.2, Figs. 7, 13).

P(x, t), the contact intensity I(x, t) normalised along x, and P(k, t), its shares in the model's
10 parts, are defined in :mod:`rigctl.records.contact_profile` (they read a record; the workbench
uses them too).

Sec. 3.2, Fig. 7d: "the average value Im(i) of the contact image intensity in the corresponding time
is taken to calculate the K(i)": Im(i) is the mean contact intensity Ic(t) of the frames inside the
time window of cycle i's K(i) band (:attr:`rigctl.analysis.stiffness.CycleStiffness.t_window_s`).
A window holding no frame (a slow camera) takes Ic interpolated at its middle, flagged by
``n_frames = 0``.

P at chosen tangential forces (Figs. 7b-c, 13a): the first frame of a stick whose Ft (the force
record interpolated at the frame time) reaches the target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rigctl.analysis.stiffness import CycleStiffness
from rigctl.data import FloatArray
from rigctl.records.contact_intensity import ContactIntensity
from rigctl.records.contact_profile import p_bins, p_density


@dataclass(frozen=True)
class PSnapshot:
    """P at one chosen tangential force."""

    target_N: float
    frame: int
    t_s: float
    ft_N: float
    """Ft at the frame (the target, up to one frame interval of loading)."""
    p_x: FloatArray
    """P(x) density on the profile bins."""
    p_k: FloatArray
    """P(k), the model's 10 parts."""

    def to_dict(self) -> dict[str, object]:
        return {"target_ft_N": self.target_N, "frame": self.frame, "t_s": self.t_s,
                "ft_N": self.ft_N, "P_x": self.p_x.tolist(), "P_k": self.p_k.tolist()}


def frame_at_force(t_frames_s: FloatArray, ft_frames_N: FloatArray, t_a_s: float, t_b_s: float,
                   target_N: float) -> int | None:
    """First frame in [t_a, t_b] whose Ft reaches ``target_N`` (None if none does)."""
    sel = np.flatnonzero((t_frames_s >= t_a_s) & (t_frames_s <= t_b_s))
    if sel.size == 0:
        return None
    hit = sel[ft_frames_N[sel] >= target_N]
    return int(hit[0]) if hit.size else None


def p_at_forces(ci: ContactIntensity, ft_frames_N: FloatArray, t_a_s: float, t_b_s: float,
                targets_N: Sequence[float]) -> list[PSnapshot]:
    """P(x) and P(k) at the first frame of [t_a, t_b] reaching each target force (skips misses)."""
    out: list[PSnapshot] = []
    for target in targets_N:
        j = frame_at_force(ci.t_s, ft_frames_N, t_a_s, t_b_s, float(target))
        if j is None:
            continue
        out.append(PSnapshot(float(target), j, float(ci.t_s[j]), float(ft_frames_N[j]),
                             p_density(ci.profile[j])[0], p_bins(ci.profile[j])[0]))
    return out


@dataclass(frozen=True)
class MeanIntensity:
    """Im(i) of one cycle."""

    cycle: int
    stage: str
    im: float
    n_frames: int
    """Frames averaged (0: Ic interpolated at the window's middle)."""
    t_window_s: tuple[float, float]


def im_cycles(ci: ContactIntensity, stiffness: Sequence[CycleStiffness]) -> list[MeanIntensity]:
    """Im(i): mean Ic over each cycle's K(i) window (NaN where K(i) has no window)."""
    out: list[MeanIntensity] = []
    for s in stiffness:
        a, b = s.t_window_s
        if not (math.isfinite(a) and math.isfinite(b)) or ci.n_frames == 0:
            out.append(MeanIntensity(s.cycle, s.stage, math.nan, 0, (a, b)))
            continue
        ok = np.isfinite(ci.ic)  # frames without an image (ContactIntensity.quality_notes) out
        sel = (ci.t_s >= a) & (ci.t_s <= b) & ok
        k = int(np.count_nonzero(sel))
        if k:
            im = float(np.mean(ci.ic[sel]))
        elif ok.any() and ci.t_s[ok][0] <= 0.5 * (a + b) <= ci.t_s[ok][-1]:
            im = float(np.interp(0.5 * (a + b), ci.t_s[ok], ci.ic[ok]))
        else:
            im = math.nan
        out.append(MeanIntensity(s.cycle, s.stage, im, k, (a, b)))
    return out
