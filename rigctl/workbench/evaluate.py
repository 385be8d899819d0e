"""Simulate a model on every run of a campaign and read its slips like the measurement's.

Each run is simulated on its own simplified drive (:mod:`rigctl.records.drive_profile`) at the
run's own sample rate with :class:`rigctl.model.Simulator`, then read with the run's measured
settings (:mod:`rigctl.records.features`), so model and measurement go through the same eyes.
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from rigctl.model import Drive, ModelSpec, SimResult, Simulator
from rigctl.records.dataset import Dataset, PreparedRun
from rigctl.records.features import EventTable, extract_events
from rigctl.records.image_features import model_image_numbers
from rigctl.records.signals import FloatArray
from rigctl.records.time_base import TimeBase
from rigctl.workbench.metrics import Score, score
from rigctl.workbench.model_choice import ModelChoice


def model_drive(run: PreparedRun) -> Drive:
    """The run's drive; with a lead-in (:func:`rigctl.records.dataset.lead_in`) the first
    segment is extended back by ``run.lead_in_s`` and the times shifted to start at 0."""
    d = run.drive
    if run.lead_in_s <= 0.0:
        return Drive(d.t_s, d.x_stage_m, d.fn_N)
    v0 = float(d.velocity_m_per_s[0])
    t = np.concatenate([[0.0], d.t_s + run.lead_in_s])
    x = np.concatenate([[d.x_stage_m[0] - v0 * run.lead_in_s], d.x_stage_m])
    f = np.concatenate([[d.fn_N[0]], d.fn_N])
    return Drive(t, x, f)


MODEL_SLIPS_PER_SAMPLE = 4
"""A model run inside a fit that slips more than this many times per output sample on average
(and more than MODEL_SLIPS_MIN times) is stopped and counts as one that cannot be run: the record
cannot show slips that close together (it shows a slip as a fall between samples, so at most one
per sample interval), and integrating them is what costs, in time and memory.
The sampling limit is one per sample; the margin of four over it is tuned, not derived: models a
fit passes through may slip somewhat more often than the record shows and must still be fitted
(docs/decisions.md)."""
MODEL_SLIPS_MIN = 100_000


def slip_budget(run: PreparedRun) -> int:
    """The most global slips a model run on ``run`` may have (MODEL_SLIPS_PER_SAMPLE)."""
    return max(MODEL_SLIPS_MIN, MODEL_SLIPS_PER_SAMPLE * run.n_samples)


def simulate_run(spec: ModelSpec, run: PreparedRun, bounded: bool = False,
                 deadline: float | None = None) -> SimResult:
    """The model on the run's drive, sampled at the run's rate on the run's time base; ``bounded``
    (the fits' evaluations): at most :func:`slip_budget` slips, else SlipBudgetError;
    ``deadline`` (a :func:`time.monotonic` value): ended by TimeLimitError once passed."""
    sim = Simulator(spec, sample_rate_hz=run.sample_rate_hz)
    res = sim.run(model_drive(run), record_elements=False,
                  max_slips=slip_budget(run) if bounded else None, deadline=deadline)
    if run.lead_in_s <= 0.0:
        return res
    i0 = round(run.lead_in_s * run.sample_rate_hz)
    out = res.slice(i0, res.n_samples)
    out.t_s = out.t_s - out.t_s[0]
    return out


_TIME_BASES: dict[int, tuple[weakref.ref[PreparedRun], TimeBase]] = {}
"""Per run (by id, while it lives), the time base of its model runs (:func:`model_time_base`)."""


def model_time_base(run: PreparedRun, t_s: FloatArray) -> TimeBase:
    """The :class:`~rigctl.records.time_base.TimeBase` of the model's runs on ``run``: every
    evaluation samples them on the run's times, so it is made once per run and reused while it
    fits the times given."""
    held = _TIME_BASES.get(id(run))
    if held is not None and held[0]() is run and held[1].fits(t_s, run.drive):
        return held[1]
    base = TimeBase.of(t_s, run.drive)
    for key in [k for k, (ref, _) in _TIME_BASES.items() if ref() is None]:
        _TIME_BASES.pop(key, None)
    _TIME_BASES[id(run)] = (weakref.ref(run), base)
    return base


class Channels(Protocol):
    """The sampled channels a run is read from, on a time base starting at 0: a model run
    (:class:`~rigctl.model.SimResult`) or a record in memory (:class:`rigctl.data.MeasuredRun`,
    e.g. a generated campaign's noise-free twin, ``benchmarks.reading_noise``)."""

    @property
    def t_s(self) -> FloatArray: ...
    @property
    def ft_N(self) -> FloatArray: ...
    @property
    def fn_N(self) -> FloatArray: ...
    @property
    def d1_m(self) -> FloatArray: ...
    @property
    def d2_m(self) -> FloatArray: ...


def read_result(res: Channels, run: PreparedRun) -> EventTable:
    """The model's slips and features on ``run``, read with the run's own settings."""
    return extract_events(
        res.t_s, res.ft_N, res.d1_m - res.d2_m, res.fn_N, run.drive, run.read,
        time_base=model_time_base(run, res.t_s),
    )


@dataclass
class Evaluation:
    score: Score
    events: list[EventTable]
    results: list[SimResult] | None
    images: list[dict[str, float]] | None = None
    """Per run, the model's image features over the run's frames (empty without frames)."""


def evaluate(
    dataset: Dataset, model: ModelChoice | ModelSpec, keep_results: bool = False,
    bounded: bool = False, deadline: float | None = None,
) -> Evaluation:
    """Simulate and score ``model`` on ``dataset`` (``bounded``, ``deadline``: see
    :func:`simulate_run`; one deadline for every run)."""
    spec = model.build() if isinstance(model, ModelChoice) else model
    events: list[EventTable] = []
    results: list[SimResult] = []
    images: list[dict[str, float]] = []
    for run in dataset.runs:
        res = simulate_run(spec, run, bounded, deadline)
        events.append(read_result(res, run))
        # the model's P(i, t) over the run's frames: its stage's shares (no extra engine work)
        images.append(model_image_numbers(res, run.image) if run.image is not None else {})
        if keep_results:
            results.append(res)
    return Evaluation(score(dataset, events, images), events,
                      results if keep_results else None, images)
