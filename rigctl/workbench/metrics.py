"""The event-aware error between a model and a measured campaign.

Per paired slip (:mod:`rigctl.workbench.alignment`) and feature (:mod:`rigctl.records.features`)
the residual is ``model - measured`` (``ln(model / measured)`` for durations, rates and
stiffnesses). It is expressed in units of the feature's event-to-event scatter in the measurement
(``Dataset.sigma``) and averaged over *blocks* of up to six consecutive slips of a drive segment (the
first slip of a segment is a block of its own), giving

    z_b = mean_{i in b}(r_i) / (sigma / sqrt(n_b)).

Averaging first lets a small systematic misfit of a noisy feature (e.g. drop sharpness, which
depends on where the samples fall in a sub-millisecond slip) stand out of the scatter, while the
blocks stay short enough to keep trends over cycles, holds and velocity steps. The error is

    E = sqrt( mean_features( mean_blocks z_b^2 ) ),

every feature weighing the same whatever its number of events; E is about 1 when the model is
within the measurement's scatter. A measured slip the model does not make counts z = 5 per slip; a
model slip in a segment where the measurement has none counts z = 3 per slip (in ``drop_N``). A
measured slip compared with the model's first slip of its segment for want of a later one
(:func:`~rigctl.workbench.alignment.stand_in_pairs`) counts at most z = 5 per feature, as a missing
slip would. A measured slip whose settled drop is under half the detection threshold is *marginal*:
the record's noise carried its fall over the threshold, and a noise-free model's twin of it does not
cross; a model without a slip for it (missing, or only a stand-in) is not charged for it. ``lag_m``
has no zero of its own (the probes' zero is arbitrary) and is compared up to a constant
(:func:`_less_offset`).

Nothing here compares time series point by point over many cycles: slip timing drifts, and such an
RMSE would measure the phase drift, not the physics (docs/workbench.md, "Why not a pointwise RMSE").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from rigctl.records.dataset import Dataset, PreparedRun
from rigctl.records.feature_info import FEATURES, IMAGE_FEATURES
from rigctl.records.features import EVENT_FEATURES, EventTable
from rigctl.records.signals import FloatArray, median
from rigctl.workbench.alignment import (
    match_events,
    segments_of,
    spurious_counts,
    stand_in_pairs,
)

MISSING_EVENT_Z = 5.0
MARGINAL_DROP_FRACTION = 0.5
"""A measured slip whose settled drop (``drop_N``) is under this fraction of the run's detection
threshold was lifted over the threshold by the record's noise; a model that does not make it is not
charged for it (see the module docstring)."""
SPURIOUS_EVENT_Z = 3.0
INIT_FEATURE = "init_k_N_per_m"


@dataclass
class RunComparison:
    """Event-level comparison of one run."""

    match: np.ndarray
    residual: dict[str, FloatArray]
    """Per measured event: model - measured (ln ratio for log features); NaN where not compared."""
    missing: dict[str, np.ndarray]
    """Per measured event: measured value exists but the model has none (no paired slip)."""
    init_residual: FloatArray
    spurious: np.ndarray
    """Model slips per drive segment where the measurement has none."""
    image_residual: dict[str, float] = field(default_factory=dict)
    """Image features (:mod:`rigctl.records.image_features`): model - measured; empty for a run
    without frames."""
    stand_in: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Per measured event: compared with the model's first slip of its segment, which stands in for
    a later slip the model does not make (its z is capped at MISSING_EVENT_Z); empty: none is."""
    excused: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))
    """Per measured event: a marginal slip (MARGINAL_DROP_FRACTION) the model has no slip for, left
    out of the error; empty: none is."""

    def like_for_like(self, name: str) -> FloatArray:
        """The residuals of ``name`` where a slip was compared with its like: NaN for stand-in
        pairs too (what the residual map and the physical errors describe)."""
        if not self.stand_in.any():
            return self.residual[name]
        out: FloatArray = np.where(self.stand_in, np.nan, self.residual[name])
        return out


def _residual(name: str, meas: FloatArray, model: FloatArray) -> FloatArray:
    if FEATURES[name].log:
        with np.errstate(divide="ignore", invalid="ignore"):
            out: FloatArray = np.where((meas > 0) & (model > 0), np.log(model / meas), np.nan)
        return out
    return model - meas


def _less_offset(meas: FloatArray, model: FloatArray, stand_in: np.ndarray) -> FloatArray:
    """A zero-free feature's residuals, each side's values taken about its median over the same
    paired events (stand-in pairs, which compare unlike slips, left out). Each record's table gives
    them about its median over its own slips, so a slip one side lacks would otherwise shift every
    residual of the run. Where every slip is paired this changes nothing."""
    r = model - meas
    use = np.isfinite(r) & ~stand_in
    if not use.any():
        return r
    out: FloatArray = r - (median(model[use]) - median(meas[use]))
    return out


def compare_run(run: PreparedRun, model_events: EventTable,
                model_image: dict[str, float] | None = None) -> RunComparison:
    meas = run.events
    segments = segments_of(meas, model_events, run.drive)
    match = match_events(meas, model_events, run.drive, segments)
    paired = match >= 0
    stand_in = stand_in_pairs(meas, model_events, match, run.drive, segments)
    residual: dict[str, FloatArray] = {}
    missing: dict[str, np.ndarray] = {}
    for name in EVENT_FEATURES:
        mv = meas.features[name]
        model_v = np.full(meas.n, np.nan)
        model_v[paired] = model_events.features[name][match[paired]]
        residual[name] = (_less_offset(mv, model_v, stand_in) if FEATURES[name].zero_free
                          else _residual(name, mv, model_v))
        missing[name] = np.isfinite(mv) & ~np.isfinite(residual[name])
    init = _residual(INIT_FEATURE, meas.init_k_N_per_m, model_events.init_k_N_per_m)
    spur = spurious_counts(meas, model_events, run.drive.n_segments(), run.drive, segments)
    image: dict[str, float] = {}
    if run.image is not None:
        measured = run.image.measured()
        for name in IMAGE_FEATURES:
            if math.isfinite(measured[name]):
                image[name] = (model_image or {}).get(name, math.nan) - measured[name]
    marginal = np.abs(meas.features["drop_N"]) < MARGINAL_DROP_FRACTION * run.read.detection.threshold_N
    excused = marginal & (~paired | stand_in)
    return RunComparison(match, residual, missing, init, spur, image, stand_in, excused)


@dataclass
class Score:
    """The error of a model on a campaign and the residual vector identification minimises."""

    vector: FloatArray
    error: float
    feature_error: dict[str, float]
    """sqrt(mean_b z_b^2) of each feature (the terms of E)."""
    n_events: int
    comparisons: list[RunComparison]

    def to_dict(self) -> dict[str, float]:
        return {"error": self.error, **{f"{k}": v for k, v in self.feature_error.items()}}


def score(dataset: Dataset, model_events: list[EventTable],
          model_images: list[dict[str, float]] | None = None) -> Score:
    """Compare model events with the measured ones run by run; see the module docstring.

    ``model_images``: per run, the model's image features over the run's frames (runs with frames
    add one entry per image feature, after the initial-stage curve; a model value that cannot be
    read counts MISSING_EVENT_Z).

    A diverging model's residuals (1e154 and more) overflow to inf: its error is inf and a fit
    rejects it, without numpy's overflow warning on the user's console."""
    with np.errstate(over="ignore"):
        return _score(dataset, model_events, model_images)


def _score(dataset: Dataset, model_events: list[EventTable],
           model_images: list[dict[str, float]] | None) -> Score:
    imgs = model_images or [{} for _ in dataset.runs]
    comps = [compare_run(r, m, i)
             for r, m, i in zip(dataset.runs, model_events, imgs, strict=True)]
    parts: list[FloatArray] = []
    sums: dict[str, float] = {}
    counts: dict[str, int] = {}
    # per run: the events counted (all but the excused) and whether any is a stand-in
    counted = [~c.excused if c.excused.any() else np.ones(r.events.n, bool)
               for r, c in zip(dataset.runs, comps, strict=True)]
    any_stand_in = [bool(c.stand_in.any()) for c in comps]
    for name in EVENT_FEATURES:
        for i_run, (run, comp) in enumerate(zip(dataset.runs, comps, strict=True)):
            meas = run.events.features[name]
            z_ev = comp.residual[name] / dataset.event_sigma(i_run, name)
            if any_stand_in[i_run]:
                z_ev = np.where(comp.stand_in,
                                np.clip(z_ev, -MISSING_EVENT_Z, MISSING_EVENT_Z), z_ev)
            z_ev = np.where(comp.missing[name], MISSING_EVENT_Z, z_ev)
            z_ev = np.where(np.isfinite(z_ev), z_ev, MISSING_EVENT_Z)
            active = np.isfinite(meas) & counted[i_run]
            zb = np.zeros(len(run.blocks))
            irregular = run.block_irregular or (False,) * len(run.blocks)
            for b, idx in enumerate(run.blocks):
                sel = idx[active[idx]]
                if sel.size == 0:
                    continue
                z = z_ev[sel]
                # an irregular phase: the difference of the means in units of the spread;
                # np.mean(z) bit for bit, without its wrapper (numpy's sum over the count)
                zb[b] = float(np.add.reduce(z) / z.size) * (1.0 if irregular[b]
                                                             else math.sqrt(z.size))
                sums[name] = sums.get(name, 0.0) + zb[b] ** 2
                counts[name] = counts.get(name, 0) + 1
            parts.append(zb)
            if name == "drop_N":
                empty = np.bincount(run.events.segment, minlength=run.drive.n_segments())
                empty = empty[: run.drive.n_segments()] == 0
                zs = SPURIOUS_EVENT_Z * comp.spurious.astype(np.float64)
                parts.append(np.where(empty, zs, 0.0))
                sums[name] = sums.get(name, 0.0) + float(np.sum(zs[empty] ** 2))
                counts[name] = counts.get(name, 0) + int(np.count_nonzero(empty))
    sigma_i = dataset.sigma[INIT_FEATURE]
    for run, comp in zip(dataset.runs, comps, strict=True):
        active = np.isfinite(run.events.init_k_N_per_m)
        z = np.where(active, comp.init_residual / sigma_i, 0.0)
        z = np.where(active & ~np.isfinite(z), MISSING_EVENT_Z, z)
        parts.append(z)
        if active.any():
            sums[INIT_FEATURE] = sums.get(INIT_FEATURE, 0.0) + float(np.sum(z[active] ** 2))
            counts[INIT_FEATURE] = counts.get(INIT_FEATURE, 0) + int(np.count_nonzero(active))
    for name in IMAGE_FEATURES:
        for run, comp in zip(dataset.runs, comps, strict=True):
            if run.image is None or name not in comp.image_residual:
                continue
            z_img = comp.image_residual[name] / run.image.sigma()[name]
            z_img = z_img if math.isfinite(z_img) else MISSING_EVENT_Z
            parts.append(np.array([z_img]))
            sums[name] = sums.get(name, 0.0) + z_img**2
            counts[name] = counts.get(name, 0) + 1
    feature_error = {k: math.sqrt(sums[k] / counts[k]) for k in sums if counts[k] > 0}
    error = math.sqrt(float(np.mean([v**2 for v in feature_error.values()]))) \
        if feature_error else float("nan")
    vec = np.concatenate(parts) if parts else np.zeros(0)
    # the least-squares vector weighs features equally too: scale each feature's entries
    return Score(_equalise(vec, dataset, counts), error, feature_error, dataset.n_events, comps)


def layout(dataset: Dataset) -> list[tuple[str, int]]:
    """The layout of :func:`score`'s residual vector on ``dataset``, whatever the model: its
    segments in order, each a feature and its number of entries. An entry per block of each event
    feature of each run (``drop_N`` followed by an entry per drive segment: spurious slips), per
    initial-stage band of each run, and per run that measured an image feature, all of them the
    data's (:func:`_score` appends its parts in this order)."""
    segments: list[tuple[str, int]] = []
    for name in EVENT_FEATURES:
        for run in dataset.runs:
            segments.append((name, len(run.blocks)))
            if name == "drop_N":
                segments.append((name, run.drive.n_segments()))
    segments.append((INIT_FEATURE, sum(int(r.events.init_k_N_per_m.shape[0])
                                       for r in dataset.runs)))
    for name in IMAGE_FEATURES:
        segments.append((name, sum(1 for r in dataset.runs if r.image is not None
                                   and math.isfinite(r.image.measured()[name]))))
    return segments


def residual_length(dataset: Dataset) -> int:
    """The length of :func:`score`'s residual vector on ``dataset`` (:func:`layout`). A fit needs
    it for a point whose model cannot be run, without running a model."""
    return sum(n for _, n in layout(dataset))


def _equalise(vec: FloatArray, dataset: Dataset, counts: dict[str, int]) -> FloatArray:
    """Scale each feature's entries (:func:`layout`) by 1/sqrt(its count of terms) so that
    |vec|^2 = n_feat * E^2 (a feature with no term weighs nothing)."""
    out = vec.copy()
    pos = 0
    for name, n in layout(dataset):
        c = counts.get(name, 0)
        out[pos : pos + n] *= 1.0 / math.sqrt(c) if c else 0.0
        pos += n
    return out


@dataclass(frozen=True)
class FeatureError:
    """Event residuals of one feature in physical terms."""

    unit: str
    """The feature's unit, or 'relative' for log features (model / measured - 1)."""
    rms: float
    mean: float
    n: int


def physical_errors(comps: list[RunComparison]) -> dict[str, FeatureError]:
    """Per feature: RMS and mean of the event residuals in the feature's unit (or relative)."""
    out: dict[str, FeatureError] = {}
    for name in (*EVENT_FEATURES, INIT_FEATURE, *IMAGE_FEATURES):
        if name in IMAGE_FEATURES:
            r = np.array([c.image_residual[name] for c in comps if name in c.image_residual])
        elif name == INIT_FEATURE:
            r = np.concatenate([c.init_residual for c in comps])
        else:
            r = np.concatenate([c.like_for_like(name) for c in comps])
        r = r[np.isfinite(r)]
        if r.size == 0:
            continue
        info = FEATURES[name]
        vals = np.expm1(r) if info.log else r
        out[name] = FeatureError(
            "relative" if info.log else info.unit,
            float(np.sqrt(np.mean(vals**2))),
            float(np.mean(vals)),
            int(r.size),
        )
    return out
