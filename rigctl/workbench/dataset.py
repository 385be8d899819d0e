"""A measured campaign made ready for comparison: drives, read settings, measured events, scales.

:func:`prepare_dataset` checks each run (NaN, length, stage motion, slips; problems raise
:class:`rigctl.data.DataError` naming the file), simplifies its drive, fixes how it is read (slip
threshold from its own noise, post-slip settle time from its own ringing) and measures its events.
It also fixes, once for the campaign, each feature's event-to-event scatter (the unit residuals are
measured in) and the blocks of consecutive events residuals are averaged over
(:mod:`rigctl.workbench.metrics`). Everything here is small and picklable: it is what a worker needs to
score a model, without the raw samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rigctl.data import DataError, MeasuredRun
from rigctl.workbench.drive_profile import DriveProfile, drive_profile
from rigctl.workbench.events import DetectionSettings, detect_slips
from rigctl.workbench.feature_info import (
    FEATURES,
    FLOOR_FRACTION,
    INIT_FLOOR,
    PHASE_FLOOR_FRACTION,
    UNIT_FLOOR,
)
from rigctl.workbench.features import EVENT_FEATURES, EventTable, ReadSettings, extract_events
from rigctl.workbench.probe_range import probe_range
from rigctl.workbench.signals import FloatArray

BLOCK_SIZE = 6
"""Events per averaging block (the first event of each drive segment is a block of its own)."""

MIN_SAMPLES = 64


@dataclass(frozen=True)
class PreparedRun:
    name: str
    sample_rate_hz: float
    n_samples: int
    drive: DriveProfile
    read: ReadSettings
    events: EventTable
    blocks: tuple[np.ndarray, ...]
    """Measured-event indices of each block."""
    notes: tuple[str, ...] = ()
    """What reading the run found (probes over range)."""


@dataclass(frozen=True)
class Dataset:
    runs: tuple[PreparedRun, ...]
    sigma: dict[str, float]
    """Event-to-event scatter of each feature (log features: of ln value)."""
    scale: dict[str, float]
    """Typical size of each feature (for floors and wording)."""
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def n_events(self) -> int:
        return sum(r.events.n for r in self.runs)

    @property
    def names(self) -> list[str]:
        return [r.name for r in self.runs]


def _blocks(events: EventTable) -> tuple[np.ndarray, ...]:
    out: list[np.ndarray] = []
    for seg in np.unique(events.segment):
        idx = np.flatnonzero(events.segment == seg)
        out.append(idx[:1])
        rest = idx[1:]
        if rest.size:
            n_blocks = math.ceil(rest.size / BLOCK_SIZE)
            out.extend(np.array_split(rest, n_blocks))
    return tuple(out)


def _settle_time(t: FloatArray, slips_end: np.ndarray, slips_peak: np.ndarray) -> float:
    """Post-slip settle time: the median visible ringing plus 20 ms, within [30, 300] ms."""
    if slips_peak.size == 0:
        return 0.08
    ring = float(np.median(t[slips_end] - t[slips_peak]))
    return float(np.clip(ring + 0.02, 0.03, 0.3))


def check_run(run: MeasuredRun) -> None:
    """Raise DataError naming the file for data the workbench cannot use."""
    run.validate()
    if run.n_samples < MIN_SAMPLES:
        raise DataError(
            f"only {run.n_samples} samples: too short to contain a stick-slip cycle",
            path=run.source or None,
        )


def prepare_run(run: MeasuredRun, name: str) -> PreparedRun:
    check_run(run)
    prof = drive_profile(run)
    t = run.t_s - run.t_s[0]
    det = DetectionSettings.from_signal(run.ft_N)
    probes = probe_range(run)
    valid = probes.delta_valid if probes.any_over else None
    slips = detect_slips(t, run.ft_N, run.delta_m, det, valid)
    read = ReadSettings(det, _settle_time(t, slips.i_end, slips.i_peak))
    events = extract_events(
        run.t_s, run.ft_N, run.delta_m, run.fn_N, prof, read, slips, valid
    )
    return PreparedRun(
        name=name,
        sample_rate_hz=run.sample_rate_hz,
        n_samples=run.n_samples,
        drive=prof,
        read=read,
        events=events,
        blocks=_blocks(events),
        notes=tuple(probes.notes(name)),
    )


def _robust_spread(v: FloatArray) -> float:
    return 1.482602218505602 * float(np.median(np.abs(v - np.median(v))))


def _scatter(runs: list[PreparedRun], name: str, log: bool, phase_sensitive: bool) -> float:
    """Pooled event-to-event scatter of a feature in the measurement.

    Regular features: successive differences between consecutive events of the same drive segment,
    the first event of each segment (which carries the history: hold, velocity step, initial
    stage) left out, pooled over the campaign: sigma = 1.4826 MAD(d) / sqrt(2) - insensitive to
    slow trends. Phase-sensitive features: the robust spread of all of a run's values about their
    median. NaN when there are too few events.
    """

    def values(v: FloatArray) -> FloatArray:
        v = v[np.isfinite(v)]
        return np.log(v[v > 0]) if log else v

    if phase_sensitive:
        groups = [v for v in (values(r.events.features[name]) for r in runs) if v.size >= 3]
        if not groups:
            return float("nan")
        weights = [v.size for v in groups]
        var = sum(_robust_spread(v) ** 2 * w for v, w in zip(groups, weights, strict=True))
        return math.sqrt(var / sum(weights))
    diffs: list[FloatArray] = []
    for r in runs:
        ev = r.events
        first = ev.first_in_segment()
        for seg in np.unique(ev.segment):
            v = values(ev.features[name][(ev.segment == seg) & ~first])
            if v.size >= 2:
                diffs.append(np.diff(v))
    d = np.concatenate(diffs) if diffs else np.zeros(0)
    if d.size < 2:
        return float("nan")
    return 1.482602218505602 * float(np.median(np.abs(d - np.median(d)))) / math.sqrt(2.0)


def _median_finite(runs: list[PreparedRun], name: str) -> float:
    vals = np.concatenate([r.events.features[name] for r in runs]) if runs else np.zeros(0)
    vals = np.abs(vals[np.isfinite(vals)])
    return float(np.median(vals)) if vals.size else float("nan")


def feature_scales(runs: list[PreparedRun]) -> tuple[dict[str, float], dict[str, float]]:
    drop = _median_finite(runs, "drop_N")
    slip = _median_finite(runs, "slip_m")
    scale: dict[str, float] = {}
    sigma: dict[str, float] = {}
    for name in EVENT_FEATURES:
        info = FEATURES[name]
        scale[name] = _median_finite(runs, name)
        if info.floor_kind == "drop":
            floor = FLOOR_FRACTION * drop
        elif info.floor_kind == "slip":
            floor = FLOOR_FRACTION * slip
        elif info.floor_kind == "relative":
            floor = FLOOR_FRACTION
        else:
            floor = UNIT_FLOOR
        s = _scatter(runs, name, info.log, info.phase_sensitive)
        if info.phase_sensitive and np.isfinite(scale[name]):
            floor = max(floor, PHASE_FLOOR_FRACTION * scale[name])
        if not np.isfinite(floor) or floor <= 0:
            floor = 1e-12
        sigma[name] = max(s, floor) if np.isfinite(s) else 3.0 * floor
    sigma["init_k_N_per_m"] = INIT_FLOOR
    inits = np.concatenate([r.events.init_k_N_per_m for r in runs])
    inits = inits[np.isfinite(inits)]
    scale["init_k_N_per_m"] = float(np.median(inits)) if inits.size else float("nan")
    return sigma, scale


def prepare_dataset(runs: list[MeasuredRun]) -> Dataset:
    """Check and read a campaign (one or more runs)."""
    if not runs:
        raise DataError("no runs given")
    prepared: list[PreparedRun] = []
    notes: list[str] = []
    for i, run in enumerate(runs):
        name = run.source or f"run{i + 1}"
        pr = prepare_run(run, name)
        notes.extend(pr.notes)
        if pr.events.n == 0:
            notes.append(f"{name}: no slip detected (stick-slip absent or below the noise)")
        prepared.append(pr)
    if all(p.events.n == 0 for p in prepared):
        where = prepared[0].name if len(prepared) == 1 else f"all {len(prepared)} runs"
        raise DataError(
            "no slip event detected (the run is too short to contain a slip, or the tangential "
            "force never drops)",
            path=where,
        )
    sigma, scale = feature_scales(prepared)
    return Dataset(tuple(prepared), sigma, scale, tuple(notes))


def protocols_present(dataset: Dataset) -> list[str]:
    """Which protocols the campaign contains, read from its drives and events."""
    found: list[str] = []
    fns = [float(np.median(r.drive.fn_N)) for r in dataset.runs]
    if len(fns) > 1 and max(fns) > 1.1 * min(fns):
        found.append("force sweep")
    speeds = np.concatenate([np.abs(r.drive.moving_velocities) for r in dataset.runs])
    if speeds.size and speeds.max() > 1.5 * speeds.min():
        found.append("velocity steps")
    holds = False
    for r in dataset.runs:
        is_hold = r.drive.phase_is_hold
        moving = np.flatnonzero(~is_hold)
        if moving.size and np.any(is_hold[moving[0] : moving[-1] + 1]):
            holds = True
    if holds:
        found.append("slide-hold-slide")
    if any(r.events.n >= 40 for r in dataset.runs):
        found.append("long run")
    if any((r.events.stage == 0).any() for r in dataset.runs):
        found.append("loading from rest (initial stage)")
    return found
