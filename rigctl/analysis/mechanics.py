"""The mechanical analyses of one run, gathered: passes, cycles, friction, stiffness, repeatability.

Everything here needs only the force and displacement samples, so a CSV from another rig gets all of
it. The image analyses (:mod:`rigctl.analysis.contact_run`) add to it when the run has frames.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rigctl.analysis.friction import FrictionCoefficients, friction_coefficients
from rigctl.analysis.passes import find_passes
from rigctl.analysis.repeatability import Repeated
from rigctl.analysis.stickslip import PassRecord, read_passes
from rigctl.analysis.stiffness import CycleStiffness, cycle_stiffness
from rigctl.data import MeasuredRun


@dataclass
class Mechanics:
    """Mechanical analysis of one run."""

    passes: list[PassRecord]
    friction: list[FrictionCoefficients]
    stiffness: list[list[CycleStiffness]]
    repeatability: list[Repeated]
    notes: list[str] = field(default_factory=list)

    def pass_dicts(self) -> list[dict[str, object]]:
        out: list[dict[str, object]] = []
        for rec, fc, st in zip(self.passes, self.friction, self.stiffness, strict=True):
            out.append({
                "pass": rec.pas.index + 1,
                "t_motion_s": rec.pas.t_motion_s,
                "t_end_s": rec.pas.t_end_s,
                "fn_N": rec.pas.fn_N,
                "velocity_m_s": rec.pas.velocity_m_s,
                "has_initial_stage": rec.has_initial,
                "n_cycles": rec.cycles.n,
                "n_stable_cycles": int(np.count_nonzero(rec.stable)),
                "delta_valid_fraction": float(np.mean(rec.delta_valid)),
                "friction": fc.to_dict(),
                "stiffness": [
                    {
                        "cycle": s.cycle, "stage": s.stage,
                        "K_N_per_m": s.k.k_N_per_m, "K_se_N_per_m": s.k.se_N_per_m,
                        "K_window_s": list(s.t_window_s),
                        "K_I": [{"ft_N": b.ft_mid_N, "K_N_per_m": b.k_N_per_m,
                                 "se_N_per_m": b.se_N_per_m, "n": b.n} for b in s.k_inst],
                    }
                    for s in st
                ],
                "cycles": rec.cycles.rows(),
                "notes": list(rec.notes),
            })
        return out


def analyse_mechanics(run: MeasuredRun) -> Mechanics:
    """Passes, stick/slip cycles, friction coefficients, stiffness and max-Ft repeatability."""
    notes: list[str] = []
    passes = find_passes(run)
    if not passes:
        notes.append("no tangential pass (the stage never slides under load): stick/slip, "
                     "friction and stiffness analyses not done")
    recs, pass_notes = read_passes(run, passes)
    notes += pass_notes
    for r in recs:
        notes += r.notes
    fric = [friction_coefficients(r) for r in recs]
    stiff = [cycle_stiffness(r) for r in recs]
    rep: list[Repeated] = []
    if len(recs) >= 2:
        rep.append(Repeated.of("max Ft", "N", [float(np.nanmax(r.cycles.peak_N))
                                               if r.cycles.n else float("nan") for r in recs]))
    return Mechanics(recs, fric, stiff, rep, notes)
