"""The contact-image analyses of one run, gathered (Secs. 2.2, 3.2-3.3, 5.1; Figs. 7-9, 12-13).

Given a run file with timed frames (:class:`rigctl.analysis.source.RunSource`) and its mechanical
analysis (:class:`rigctl.analysis.mechanics.Mechanics`):

1. the contact region and dark level (:func:`~rigctl.records.contact_intensity.find_contact_region`);
2. one streamed pass over the frames: Isum(t), Ic(t), I(x, t) (:mod:`~rigctl.records.contact_intensity`);
3. per tangential pass: Im(i) over each K(i) window, P(x) and P(k) at chosen Ft in the initial stage
   (``INITIAL_FRACTIONS`` of the threshold Ft(1)) and in one stable stick (``STABLE_FRACTIONS`` of
   its rise from its start level to its peak), and the CSI of three frames in each of the two
   stages (``CSI_INITIAL``, ``CSI_STABLE``; only those frames are read again, one at a time).

Ft at a frame is the force record interpolated at the frame time (both on the DAQ clock).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from rigctl.analysis.contact_csi import CsiProportions, membership, proportions
from rigctl.analysis.contact_spots import WsmSettings, extract_spots
from rigctl.analysis.contact_stress import (
    MeanIntensity,
    PSnapshot,
    frame_at_force,
    im_cycles,
    p_at_forces,
)
from rigctl.analysis.mechanics import Mechanics
from rigctl.analysis.source import RunSource
from rigctl.analysis.stickslip import PassRecord
from rigctl.analysis.stiffness import CycleStiffness
from rigctl.data import DataError, FloatArray
from rigctl.records.contact_frames import DEFAULT_CHUNK_BYTES
from rigctl.records.contact_intensity import (
    ContactIntensity,
    ContactRegion,
    find_contact_region,
    stream_intensity,
)
from rigctl.records.contact_profile import p_bins
from rigctl.records.progress import SILENT, Progress
from rigctl.storage.reader import RunReader

INITIAL_FRACTIONS: tuple[float, ...] = (0.0, 0.3, 0.6, 0.9)
"""P in the initial stage at these fractions of the threshold Ft(1) (Fig. 7b: 0-30 N of ~46 N)."""
STABLE_FRACTIONS: tuple[float, ...] = (0.1, 0.5, 0.9)
"""P in a stable stick at these fractions of its rise (Fig. 7c: 33, 38, 43 N of ~31-45 N)."""
CSI_INITIAL: tuple[float, float, float] = (0.0, 0.45, 0.9)
"""CSI frames of the initial stage: fractions of Ft(1) (Fig. 9a: 0, 17, 25 N)."""
CSI_STABLE: tuple[float, float, float] = (0.1, 0.5, 0.9)
"""CSI frames of a stable stick: fractions of its rise (Fig. 9e: 32, 37, 42 N)."""


@dataclass
class Csi:
    """The colour superposition of three frames of one stick."""

    stage: str
    cycle: int
    frames: tuple[int, int, int]
    ft_N: tuple[float, float, float]
    code: NDArray[np.uint8]
    """Membership code map (see :mod:`rigctl.analysis.contact_csi`)."""
    props: CsiProportions
    spot_counts: tuple[int, int, int]

    def to_dict(self) -> dict[str, object]:
        return {"stage": self.stage, "cycle": self.cycle, "frames": list(self.frames),
                "ft_N": list(self.ft_N), "spots": list(self.spot_counts), **self.props.to_dict()}


@dataclass
class PassContact:
    """Contact analyses of one tangential pass."""

    pass_index: int
    im: list[MeanIntensity]
    p_initial: list[PSnapshot]
    p_stable: list[PSnapshot]
    stable_cycle: int | None
    csi: list[Csi] = field(default_factory=list)

    @property
    def im1(self) -> float:
        return self.im[0].im if self.im else math.nan

    def to_dict(self) -> dict[str, object]:
        return {
            "pass": self.pass_index + 1,
            "Im": [{"cycle": m.cycle, "stage": m.stage, "Im": m.im, "n_frames": m.n_frames,
                    "t_window_s": list(m.t_window_s)} for m in self.im],
            "P_initial": [s.to_dict() for s in self.p_initial],
            "P_stable": [s.to_dict() for s in self.p_stable],
            "P_stable_cycle": self.stable_cycle,
            "CSI": [c.to_dict() for c in self.csi],
        }


@dataclass
class ContactAnalysis:
    """Every contact-image analysis of one run."""

    intensity: ContactIntensity
    ft_frames_N: FloatArray
    fn_frames_N: FloatArray
    passes: list[PassContact]
    wsm: WsmSettings
    notes: list[str] = field(default_factory=list)

    def p_k(self) -> FloatArray:
        """P(k, t) of every frame, the model's 10 parts."""
        return p_bins(self.intensity.profile)

    def to_dict(self) -> dict[str, object]:
        ci = self.intensity
        r = ci.region
        return {
            "frames": ci.n_frames,
            "region": {"col0": r.col0, "col1": r.col1, "dark_level": r.dark_level,
                       "back_end_left": r.back_end_left},
            "profile_bins": ci.n_bins,
            "isum_max": float(np.nanmax(ci.isum)) if np.isfinite(ci.isum).any() else math.nan,
            "frame_quality": {
                "blank_frames": 0 if ci.blank is None else int(np.count_nonzero(ci.blank)),
                "nonfinite_frames": 0 if ci.nonfinite is None
                else int(np.count_nonzero(ci.nonfinite)),
                "saturated_frames": None if ci.saturated_px is None
                else int(np.count_nonzero(ci.saturated_px)),
            },
            "wsm": {"scales_px": list(self.wsm.scales_px), "weights": list(self.wsm.weights),
                    "edge_z": self.wsm.edge_z, "own_z": self.wsm.own_z,
                    "z": self.wsm.z, "min_spot_px": self.wsm.min_spot_px},
            "passes": [p.to_dict() for p in self.passes],
            "notes": list(self.notes),
        }


def _stable_cycle(rec: PassRecord) -> int | None:
    st = np.flatnonzero(rec.stable)
    return int(st[min(1, st.size - 1)]) if st.size else None


def _csi(reader: RunReader, ci: ContactIntensity, ft: FloatArray, window: tuple[float, float],
         targets: Sequence[float], stage: str, cycle: int, wsm: WsmSettings) -> Csi | None:
    idx: list[int] = []
    for target in targets:
        j = frame_at_force(ci.t_s, ft, window[0], window[1], target)
        if j is None:
            return None
        idx.append(j)
    if len(set(idx)) < 3:
        return None
    masks = []
    counts = []
    for j in idx:
        frame = reader.frames(j, j + 1)[0][0]
        sp = extract_spots(frame, ci.region.dark_level, wsm)
        masks.append(sp.mask)
        counts.append(sp.n_spots)
    code = membership(masks[0], masks[1], masks[2])
    r = ci.region
    code = code[:, r.col0:r.col1] if r.back_end_left else code[:, r.col0:r.col1][:, ::-1]
    return Csi(stage, cycle, (idx[0], idx[1], idx[2]),
               (float(ft[idx[0]]), float(ft[idx[1]]), float(ft[idx[2]])), code,
               proportions(code), (counts[0], counts[1], counts[2]))


def _pass_contact(reader: RunReader, ci: ContactIntensity, ft: FloatArray, rec: PassRecord,
                  stiff: Sequence[CycleStiffness], wsm: WsmSettings) -> PassContact:
    c = rec.cycles
    im = im_cycles(ci, stiff)
    p_ini: list[PSnapshot] = []
    p_st: list[PSnapshot] = []
    csis: list[Csi] = []
    if rec.has_initial and c.n:
        win = (float(c.t_start_s[0]), float(c.t_peak_s[0]))
        peak = float(c.peak_N[0])
        p_ini = p_at_forces(ci, ft, *win, [f * peak for f in INITIAL_FRACTIONS])
        got = _csi(reader, ci, ft, win, [f * peak for f in CSI_INITIAL], "initial", 1, wsm)
        if got is not None:
            csis.append(got)
    j = _stable_cycle(rec)
    if j is not None:
        win = (float(c.t_start_s[j]), float(c.t_peak_s[j]))
        f0, fp = stiff[j].f_start_N, stiff[j].f_peak_N
        if math.isfinite(f0) and math.isfinite(fp) and fp > f0:
            p_st = p_at_forces(ci, ft, *win, [f0 + f * (fp - f0) for f in STABLE_FRACTIONS])
            got = _csi(reader, ci, ft, win, [f0 + f * (fp - f0) for f in CSI_STABLE], "stable",
                       j + 1, wsm)
            if got is not None:
                csis.append(got)
    return PassContact(rec.pas.index, im, p_ini, p_st, None if j is None else j + 1, csis)


def analyse_contact(source: RunSource, mech: Mechanics, progress: Progress = SILENT,
                    wsm: WsmSettings | None = None, region: ContactRegion | None = None,
                    max_bytes: int = DEFAULT_CHUNK_BYTES) -> ContactAnalysis:
    """All contact analyses of a run with frames (DataError if it has none or no contact is seen)."""
    wsm = wsm or WsmSettings()
    info = source.frames
    if info is None:
        raise DataError("the run has no timed camera frames", path=source.path)
    run = source.run
    notes: list[str] = []
    with RunReader(source.path) as reader:
        reg = region or find_contact_region(reader, info.n_frames)
        ci = stream_intensity(reader, reg, info.n_frames, max_bytes=max_bytes, progress=progress)
        ft = np.interp(ci.t_s, run.t_s, run.ft_N)
        fn = np.interp(ci.t_s, run.t_s, run.fn_N)
        notes += ci.quality_notes()
        out = [_pass_contact(reader, ci, ft, rec, st, wsm)
               for rec, st in zip(mech.passes, mech.stiffness, strict=True)]
    for p in out:
        name = f"pass {p.pass_index + 1}"
        if not any(c.stage == "initial" for c in p.csi) and any(
                r.has_initial for r in mech.passes if r.pas.index == p.pass_index):
            notes.append(f"{name}: too few frames in the initial stick for its CSI")
        if p.stable_cycle is not None and not any(c.stage == "stable" for c in p.csi):
            notes.append(f"{name}: too few frames in stable cycle {p.stable_cycle} for its CSI")
        if p.im and all(m.n_frames == 0 for m in p.im):
            notes.append(f"{name}: no frame inside any K(i) window; Im(i) interpolated")
    return ContactAnalysis(ci, ft, fn, out, wsm, notes)
