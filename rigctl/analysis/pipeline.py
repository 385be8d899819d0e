"""Analyse runs as the paper does: one run file or CSV, or a folder (a campaign).

:func:`analyse_run` opens a run (:mod:`rigctl.analysis.source`), runs the mechanical analyses
(:mod:`rigctl.analysis.mechanics`) and, when the run has timed camera frames, the contact-image
analyses (:mod:`rigctl.analysis.contact_run`). :func:`analyse_campaign` does that for every run of
a folder and adds the force-sweep summary (:mod:`rigctl.analysis.sweep`); a single force-sweep
file gets it too.
Everything a run lacks is said in its notes; a file that cannot be read at all is a note of the
campaign (the other runs are still analysed), and a DataError for a single run.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rigctl.analysis.contact_run import ContactAnalysis, analyse_contact
from rigctl.analysis.mechanics import Mechanics, analyse_mechanics
from rigctl.analysis.repeatability import (
    Loading,
    Repeated,
    RepeatGroup,
    RunRepeat,
    image_repeatability,
    loadings,
    repeat_group,
)
from rigctl.analysis.source import RunSource, open_source
from rigctl.analysis.sweep import SweepSummary, summarise, sweep_point
from rigctl.data import DataError
from rigctl.io.load import expand_paths
from rigctl.records.drive_profile import fn_apart_N
from rigctl.records.progress import SILENT, Progress


@dataclass
class RunAnalysis:
    source: RunSource
    mechanics: Mechanics
    notes: list[str] = field(default_factory=list)
    contact: ContactAnalysis | None = None
    contact_absent: str = ""
    """Why there is no contact analysis ('' when there is one)."""
    loadings: list[Loading] = field(default_factory=list)
    """The run's loadings seen by the camera (repetitions of Sec. 2.2; [] without frames)."""

    @property
    def repeatability(self) -> list[Repeated]:
        """Max Ft over the passes, max Isum and the Isum-Fn slope over the loadings (Sec. 2.2)."""
        return list(self.mechanics.repeatability) + image_repeatability(self.loadings)

    def repeat(self) -> RunRepeat:
        """What this run contributes as one repetition across runs of its protocol."""
        peaks = [float(np.nanmax(r.cycles.peak_N)) for r in self.mechanics.passes if r.cycles.n]
        return RunRepeat.of(self.name, peaks, self.loadings)

    @property
    def name(self) -> str:
        return self.source.name

    def im1(self, pass_index: int) -> float:
        """Im(1) of a pass, NaN without frames."""
        if self.contact is None:
            return math.nan
        for pc in self.contact.passes:
            if pc.pass_index == pass_index:
                return pc.im1
        return math.nan

    def to_dict(self) -> dict[str, Any]:
        s = self.source
        run = s.run
        return {
            "file": str(s.path),
            "kind": s.kind,
            "protocol": s.protocol,
            "parameters": s.parameters,
            "status": s.status,
            "samples": run.n_samples,
            "duration_s": run.duration_s,
            "sample_rate_hz": run.sample_rate_hz,
            "frames": None if s.frames is None else {
                "n": s.frames.n_frames, "height_px": s.frames.height_px,
                "width_px": s.frames.width_px, "frame_rate_hz": s.frames.frame_rate_hz,
                "measured_rate_hz": s.frames.measured_rate_hz,
            },
            "notes": list(self.notes),
            "passes": self.mechanics.pass_dicts(),
            "repeatability": [r.to_dict() for r in self.repeatability],
            "loadings": [lo.to_dict() for lo in self.loadings],
            "contact": {"absent": self.contact_absent} if self.contact is None
            else self.contact.to_dict(),
        }


def analyse_run(path: str | Path, progress: Progress = SILENT) -> RunAnalysis:
    """All analyses of one run (DataError if the file cannot be read at all)."""
    src = open_source(path)
    mech = analyse_mechanics(src.run)
    notes = list(src.notes) + list(mech.notes)
    contact: ContactAnalysis | None = None
    absent = ""
    if src.frames is None:
        frame_notes = [n for n in src.notes if "frame" in n or "camera" in n]
        absent = frame_notes[0] if frame_notes else "the run has no usable camera frames"
    else:
        try:
            contact = analyse_contact(src, mech, progress)
        except DataError as exc:
            absent = f"contact images not analysed: {exc}"
            notes.append(absent)
        else:
            notes += contact.notes
    reps: list[Loading] = []
    if contact is not None:
        ci, run = contact.intensity, src.run
        reps = loadings(run.t_s, run.fn_N, fn_apart_N(run.fn_N), ci.t_s, contact.fn_frames_N,
                        ci.isum, ci.ic)
    return RunAnalysis(src, mech, notes, contact, absent, reps)


@dataclass
class CampaignAnalysis:
    runs: list[RunAnalysis]
    sweep: SweepSummary | None
    notes: list[str] = field(default_factory=list)
    repeat_groups: list[RepeatGroup] = field(default_factory=list)
    """Runs of one protocol with the same parameters (two or more): repeatability across runs."""

    def to_dict(self) -> dict[str, Any]:
        return {
            "runs": [r.to_dict() for r in self.runs],
            "sweep": None if self.sweep is None else self.sweep.to_dict(),
            "repeatability": [g.to_dict() for g in self.repeat_groups],
            "notes": list(self.notes),
        }


def repeat_groups(runs: Sequence[RunAnalysis]) -> list[RepeatGroup]:
    """Group the runs by protocol and parameters (run files only: a CSV names no protocol)."""
    groups: dict[str, list[RunAnalysis]] = {}
    for ra in runs:
        if ra.source.protocol:
            key = json.dumps([ra.source.protocol, ra.source.parameters], sort_keys=True,
                             default=str)
            groups.setdefault(key, []).append(ra)
    return [repeat_group(g[0].source.protocol, g[0].source.parameters, [r.repeat() for r in g])
            for g in groups.values() if len(g) >= 2]


def _sweep(runs: Sequence[RunAnalysis]) -> SweepSummary | None:
    points = []
    for ra in runs:
        m = ra.mechanics
        for rec, fc, st in zip(m.passes, m.friction, m.stiffness, strict=True):
            points.append(sweep_point(ra.name, rec, fc, st, ra.im1(rec.pas.index)))
    fns = np.round([p.fn_N for p in points]) if points else np.zeros(0)
    if np.unique(fns).size < 2:
        return None
    return summarise(points)


def analyse_campaign(paths: Sequence[str | Path], progress: Progress = SILENT) -> CampaignAnalysis:
    """Every run the paths name (a folder: its *.csv and *.h5), and the sweep across them."""
    files = expand_paths(list(paths))
    runs: list[RunAnalysis] = []
    notes: list[str] = []
    with progress.bar(len(files), "runs", "run") as bar:
        for f in files:
            try:
                runs.append(analyse_run(f, progress))
            except DataError as exc:
                if len(files) == 1:
                    raise
                notes.append(f"not analysed: {exc}")
            bar.update()
    return CampaignAnalysis(runs, _sweep(runs), notes, repeat_groups(runs))
