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
from dataclasses import dataclass, field, replace

import numpy as np

from rigctl.data import DataError, MeasuredRun
from rigctl.records.delta_stitch import stitch_record
from rigctl.records.drive_profile import DriveProfile, drive_profile
from rigctl.records.events import DetectionSettings, detect_slips
from rigctl.records.feature_info import (
    FEATURES,
    FLOOR_FRACTION,
    INIT_FLOOR,
    PHASE_FLOOR_FRACTION,
    SAMPLE_FLOOR,
    UNIT_FLOOR,
)
from rigctl.records.features import EVENT_FEATURES, EventTable, ReadSettings, extract_events
from rigctl.records.fn_coupling import campaign_coupling
from rigctl.records.image_features import ImageFeatures, read_image_features
from rigctl.records.long_records import WINDOW_KEY
from rigctl.records.probe_range import probe_range
from rigctl.records.rig_description import RigDescription, campaign_description
from rigctl.records.ringing import RingFit, Ringing, campaign_ringing, run_ring_fits
from rigctl.records.signals import FloatArray, noise_sigma
from rigctl.records.unit_checks import unit_notes

BLOCK_SIZE = 6
"""Events per averaging block (the first event of each drive segment is a block of its own)."""

MAX_LISTED = 4  # runs named in a note before "and N more"

MIN_SAMPLES = 64  # fewer samples cannot hold one stick and slip with its fitted lines


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
    irregular: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Per protocol phase: irregular stick-slip, compared by its mean (one block)."""
    block_irregular: tuple[bool, ...] = ()
    """Per block: the later slips of an irregular phase (empty: no block is)."""
    delta_measured: bool = True
    """False when the record has no displacement probes (:mod:`rigctl.records.probe_range`)."""
    lead_in_s: float = 0.0
    """Drive time the model runs before the record's first sample (:func:`lead_in`)."""
    image: ImageFeatures | None = None
    """What the run's camera frames say (:mod:`rigctl.records.image_features`); None without."""
    image_absent: str = ""
    """Why the run has no image feature ('' when it has one, or when images were not asked for)."""
    ring_fits: tuple[RingFit, ...] = ()
    """The post-slip ringing after its slips (:mod:`rigctl.records.ringing`)."""


@dataclass(frozen=True)
class Dataset:
    runs: tuple[PreparedRun, ...]
    sigma: dict[str, float]
    """Event-to-event scatter of each feature (log features: of ln value)."""
    scale: dict[str, float]
    """Typical size of each feature (for floors and wording)."""
    notes: tuple[str, ...] = field(default_factory=tuple)
    event_sigmas: tuple[dict[str, FloatArray], ...] = field(default_factory=tuple)
    """Per run and feature: the scatter each event is measured in (:func:`event_scatter`; fixed
    once for the campaign, read by every evaluation)."""
    rig: RigDescription = field(default_factory=RigDescription)
    """What the data say about their rig (:mod:`rigctl.records.rig_description`)."""

    def event_sigma(self, i_run: int, name: str) -> FloatArray:
        """The scatter each event of run ``i_run`` is measured in (``sigma`` where the dataset was
        built without :func:`prepare_dataset`)."""
        if i_run < len(self.event_sigmas) and name in self.event_sigmas[i_run]:
            return self.event_sigmas[i_run][name]
        return np.full(self.runs[i_run].events.n, self.sigma[name])

    @property
    def n_events(self) -> int:
        return sum(r.events.n for r in self.runs)

    @property
    def ringing(self) -> Ringing:
        """The campaign's post-slip ringing (:func:`rigctl.records.ringing.campaign_ringing`)."""
        return campaign_ringing(f for r in self.runs for f in r.ring_fits)

    @property
    def mass_from_ringing(self) -> bool:
        """The mass follows the drive and interface stiffnesses at the measured ringing frequency
        (:func:`rigctl.records.ringing.ringing_mass`): the ringing is resolved and the rig
        description does not state the mass."""
        return "m_kg" not in self.rig.fixed and self.ringing.resolved

    @property
    def names(self) -> list[str]:
        return [r.name for r in self.runs]


def _block_flags(
    events: EventTable, blocks: tuple[np.ndarray, ...], irregular: np.ndarray
) -> tuple[bool, ...]:
    """Per block of :func:`_blocks`: True for the later slips of an irregular phase."""
    first = events.first_in_segment()
    return tuple(
        bool(b.size) and int(events.segment[b[0]]) < irregular.shape[0]
        and bool(irregular[events.segment[b[0]]]) and not bool(first[b[0]])
        for b in blocks
    )


def _blocks(events: EventTable, irregular: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    out: list[np.ndarray] = []
    for seg in np.unique(events.segment):
        idx = np.flatnonzero(events.segment == seg)
        out.append(idx[:1])
        if irregular is not None and seg < irregular.shape[0] and irregular[seg]:
            if idx.size > 1:
                out.append(idx[1:])
            continue
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


LOADED_START_FRACTION = 0.3
"""A record whose first samples carry more than this fraction of its typical peak |Ft| starts
loaded: it was cut from a running slide (no initial stage from rest in it)."""
LEAD_IN_STICKS = 5.0
"""Stick cycles the model runs before such a record starts, to reach its own stick-slip cycle."""


def lead_in(ft_N: FloatArray, prof: DriveProfile, events: EventTable, rate_hz: float) -> float:
    """Seconds of drive to run the model before t = 0: 0 for a record that starts from rest (the
    model starts unloaded, as the specimen did); for one that starts loaded, LEAD_IN_STICKS
    median stick times at the first segment's velocity, so that the model enters the record in
    its own stick-slip cycle instead of loading from rest where the data show a running slide."""
    if events.n == 0 or prof.velocity_m_per_s.shape[0] == 0 or prof.velocity_m_per_s[0] == 0.0:
        return 0.0
    peaks = np.abs(events.features["peak_N"])
    peaks = peaks[np.isfinite(peaks)]
    f0 = float(np.median(np.abs(ft_N[: max(3, min(10, ft_N.shape[0]))])))
    if peaks.size == 0 or f0 <= LOADED_START_FRACTION * float(np.median(peaks)):
        return 0.0
    stick = events.features["stick_s"]
    stick = stick[np.isfinite(stick) & (stick > 0)]
    t_first = float(events.t_drop_s[0]) if events.n else 0.0
    typical = float(np.median(stick)) if stick.size else max(t_first, 1.0 / rate_hz)
    n = math.ceil(LEAD_IN_STICKS * typical * rate_hz)
    return max(n, 10) / rate_hz


def check_run(run: MeasuredRun) -> None:
    """Raise DataError naming the file for data the workbench cannot use."""
    run.validate()
    if run.n_samples < MIN_SAMPLES:
        raise DataError(
            f"only {run.n_samples} samples: too short to contain a stick-slip cycle",
            path=run.source or None,
        )


def prepare_run(run: MeasuredRun, name: str, delta_measured: bool | None = None,
                images: bool = False, ringing: bool = False,
                coupling: tuple[float, float] | None = None) -> PreparedRun:
    """Read one run; ``delta_measured=False`` (a rig description) treats it as having no probes.

    ``images``: also read the run file's camera frames once, streamed, into the image features
    (:func:`rigctl.records.image_features.read_image_features`). ``ringing``: also fit the
    post-slip ringing (:func:`rigctl.records.ringing.run_ring_fits`; a model's starting mass
    and damping, not needed to analyse a run). ``coupling``: the campaign's dFn/dFt
    (:func:`rigctl.records.drive_profile.drive_profile`). A run file's delta is read stitched
    across the probes' re-centrings (:func:`rigctl.records.delta_stitch.stitch_record`)."""
    check_run(run)
    run = stitch_record(run)
    prof = drive_profile(run, coupling=coupling)
    t = run.t_s - run.t_s[0]
    probes = probe_range(run, delta_measured)
    valid = probes.delta_valid if probes.any_over else None
    det = DetectionSettings.from_signal(run.ft_N, delta_m=run.delta_m, delta_valid=valid)
    slips = detect_slips(t, run.ft_N, run.delta_m, det, valid, v_drive_m_s=prof.sliding_velocity_at(t),
                         fn_N=run.fn_N)
    read = ReadSettings(det, _settle_time(t, slips.i_end, slips.i_peak))
    events = extract_events(
        run.t_s, run.ft_N, run.delta_m, run.fn_N, prof, read, slips, valid
    )
    image: ImageFeatures | None = None
    absent = ""
    if images and WINDOW_KEY in run.metadata:
        absent = "a window of a long record (its frames are not cut with it)"
    elif images:
        image, absent = read_image_features(run, events, read)
    return PreparedRun(
        image=image,
        image_absent=absent,
        lead_in_s=lead_in(run.ft_N, prof, events, run.sample_rate_hz),
        name=name,
        sample_rate_hz=run.sample_rate_hz,
        n_samples=run.n_samples,
        drive=prof,
        read=read,
        events=events,
        blocks=_blocks(events),
        notes=(*unit_notes(run, prof, name, probes.delta_measured), *probes.notes(name)),
        delta_measured=probes.delta_measured,
        ring_fits=tuple(run_ring_fits(t, run.ft_N, events.t_drop_s, slips.i_peak, slips.sign,
                                      events.features["step_frac"], noise_sigma(run.ft_N)))
        if ringing else (),
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
    rates = [r.sample_rate_hz for r in runs if r.sample_rate_hz > 0]
    dt = 1.0 / float(np.median(rates)) if rates else float("nan")
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
        elif info.floor_kind == "sample":
            floor = SAMPLE_FLOOR * dt
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


IRREGULAR_FACTOR = 3.0
"""A phase whose slips vary from one to the next by more than this many campaign scatters (in
``drop_N``) is irregular: compared by its mean, not slip by slip (:func:`irregular_phases`)."""
SHORT_CYCLE_FACTOR = 2.0
"""...or whose median cycle is shorter than this many post-slip settle times."""
MIN_PHASE_EVENTS = 5  # slips a phase needs before its cycle regularity is judged


def _phase_values(ev: EventTable, name: str, seg: int, first: np.ndarray) -> FloatArray:
    v = ev.features[name][(ev.segment == seg) & ~first]
    v = v[np.isfinite(v)]
    return np.log(v[v > 0]) if FEATURES[name].log else v


def irregular_phases(run: PreparedRun, sigma: dict[str, float]) -> np.ndarray:
    """Per protocol phase of ``run``: True where its stick-slip is irregular.

    In a phase whose cycles are about as short as the ringing after a slip, each slip starts at
    another phase of the previous one's ringing: slip sizes then wander between branches (period
    doubling, chaos), and a model with the right physics makes an equally irregular sequence that
    a change of 0.1 % in a parameter reshuffles. Compared slip by slip, such a phase would
    dominate the error and make it jump with every parameter change. A phase (at least
    MIN_PHASE_EVENTS slips after its first) is irregular when its median cycle is shorter than
    SHORT_CYCLE_FACTOR post-slip settle times (the run's measured ringing,
    :func:`_settle_time`), or when the successive-difference scatter of its drops (as in
    :func:`_scatter`) exceeds IRREGULAR_FACTOR campaign scatters (irregular for another reason,
    in a campaign whose other phases are regular).
    """
    ev = run.events
    n_ph = max(run.drive.n_segments(), int(ev.segment.max()) + 1 if ev.n else 0)
    out = np.zeros(n_ph, dtype=bool)
    first = ev.first_in_segment()
    base = sigma["drop_N"]
    cycle = ev.covariates["stick_time_s"]
    for seg in np.unique(ev.segment):
        sel = (ev.segment == seg) & ~first
        v = _phase_values(ev, "drop_N", int(seg), first)
        if np.count_nonzero(sel) < MIN_PHASE_EVENTS:
            continue
        short = float(np.median(cycle[sel])) < SHORT_CYCLE_FACTOR * run.read.settle_s
        s = _robust_spread(np.diff(v)) / math.sqrt(2.0) if v.size >= 3 else math.nan
        out[seg] = short or bool(np.isfinite(s) and s > IRREGULAR_FACTOR * base)
    return out


def phase_scatter(
    run: PreparedRun, sigma: dict[str, float], irregular: np.ndarray
) -> dict[str, FloatArray]:
    """Per feature, the scatter of each phase of ``run``: the campaign's, and in an irregular
    phase the standard deviation of the phase's values if that is larger (not a robust spread:
    the slips of an irregular phase wander between branches, and the spread is the physics). An irregular
    phase is one block (:func:`_blocks`) whose z is the difference of the means in units of this
    spread, not of the spread of a mean: its slips are a deterministic, correlated sequence,
    not independent draws (:mod:`rigctl.workbench.metrics`)."""
    ev = run.events
    first = ev.first_in_segment()
    out: dict[str, FloatArray] = {}
    for name in EVENT_FEATURES:
        arr = np.full(irregular.shape[0], sigma[name])
        for seg in np.flatnonzero(irregular):
            v = _phase_values(ev, name, int(seg), first)
            if v.size >= 3:
                arr[seg] = max(sigma[name], float(np.std(v)))
        out[name] = arr
    return out


def event_scatter(
    run: PreparedRun, phase: dict[str, FloatArray]
) -> dict[str, FloatArray]:
    """Per feature, the scatter each event of ``run`` is measured in: its phase's (``phase``, from
    :func:`phase_scatter`); for the first slip after an irregular phase, which starts from
    wherever that phase left off, at least that phase's; and raised to the event's own standard
    error where that is larger (a slope read from a short window, :attr:`EventTable.se`: e.g. the
    stick cut short by a velocity step, whose loading rate from 40 samples is uncertain by 30 %
    where the campaign's rates scatter by 0.5 %)."""
    ev = run.events
    prev = np.clip(ev.segment - 1, 0, None)
    after = ev.first_in_segment() & (ev.segment > 0)
    after &= run.irregular[prev] if run.irregular.size else np.zeros(ev.n, dtype=bool)
    out: dict[str, FloatArray] = {}
    for name, ph in phase.items():
        sig: FloatArray = ph[ev.segment]
        sig[after] = np.maximum(sig[after], ph[prev[after]])
        se = ev.se.get(name)
        if se is not None and se.shape == sig.shape:
            sig = np.where(np.isfinite(se), np.maximum(sig, se), sig)
        out[name] = sig
    return out


def prepare_dataset(runs: list[MeasuredRun]) -> Dataset:
    """Check and read a campaign (one or more runs)."""
    if not runs:
        raise DataError("no runs given")
    prepared: list[PreparedRun] = []
    rig = campaign_description(runs)
    notes: list[str] = rig.notes()
    for run in runs:
        check_run(run)
    coupling = campaign_coupling([(r.ft_N, r.fn_N) for r in runs])
    for i, run in enumerate(runs):
        name = run.source or f"run{i + 1}"
        pr = prepare_run(run, name, rig.delta_measured, images=True, ringing=True,
                         coupling=coupling)
        if WINDOW_KEY in run.metadata:
            notes.append(run.metadata[WINDOW_KEY])
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
    without = [f"{p.name} ({p.image_absent})" for p in prepared if p.image is None]
    if without:
        listed = ", ".join(without[:MAX_LISTED]) + (
            f" and {len(without) - MAX_LISTED} more" if len(without) > MAX_LISTED else "")
        notes.append(f"no image feature (the model's P(i, t) against the contact images) for "
                     f"{listed}")
    sigma, scale = feature_scales(prepared)
    for i, r in enumerate(prepared):
        irr = irregular_phases(r, sigma)
        blocks = _blocks(r.events, irr)
        prepared[i] = replace(r, irregular=irr, blocks=blocks,
                              block_irregular=_block_flags(r.events, blocks, irr))
        if irr.any():
            notes.append(
                f"{r.name}: irregular stick-slip in phase(s) "
                f"{', '.join(str(int(k) + 1) for k in np.flatnonzero(irr))}: compared by the "
                "phase mean, not slip by slip")
    per_event = tuple(event_scatter(r, phase_scatter(r, sigma, r.irregular)) for r in prepared)
    ds = Dataset(tuple(prepared), sigma, scale, tuple(notes), per_event, rig)
    if not ds.mass_from_ringing:
        return ds
    ring = ds.ringing
    return replace(ds, notes=(*ds.notes, (
        f"post-slip ringing resolved after {ring.n_resolved} of {ring.n_tried} slips: "
        f"{ring.freq_hz:.4g} Hz, decaying at {ring.decay_per_s:.3g} /s; a fitted model's "
        "mass follows its drive and interface stiffnesses at that frequency, "
        "M = (K0 + Kts) / omega_n^2")))


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
