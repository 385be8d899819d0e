"""Where the displacement probes were over range: the samples delta cannot be read from.

A probe driven beyond its range (the MTI-2100: 74 um) sits at its rail and the record holds the rail
value, not a displacement (docs/acquisition.md, "Displacement probes over range"). Delta = d1 - d2 is
then flat and every feature read from it (K(i), slip distance, lag, the initial-stage curve) is
meaningless, while Ft, Fn and the stage are still valid. Over range is found

* in a run file (``.h5``) from its ``probe_over_range`` / ``probe_in_range`` events (the samples
  from the first to the second are over range; an entry without a return lasts to the end), and
* in any record (CSV from another rig included) by saturation: a probe that sits at its extreme
  value (the column's max or min, within one quantisation step) for at least ``MIN_SATURATED_S``
  of consecutive samples while the stage moves (a probe at rest during a hold or before motion is
  not saturated, the interface does not move either).

Both are combined. The samples recorded while a probe's mount was moving across a slip (the
windows of its ``probe_recentre`` events across which the specimen was not steady,
:func:`rigctl.records.delta_stitch.unsteady_windows`) are not valid either, without counting as
over range; a move made while the specimen was steady is bridged and read like any sample. The
result is a per-sample mask of valid delta samples and a note per over-range probe.

A probe column that never changes over the whole record (all zero, or one constant: a rig without
displacement probes, a CSV that fills the column) was **not measured**; it is not over range. When no
probe column varies, delta was not measured at all: every sample is invalid for delta, the delta
features (K(i), slip distance, lag, the initial-stage curve) are left out and the note says so.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rigctl.data import MeasuredRun
from rigctl.records.delta_stitch import record_events, unsteady_windows
from rigctl.records.signals import FloatArray, noise_sigma

if TYPE_CHECKING:
    from rigctl.storage.reader import RunEvent

PROBES: tuple[str, ...] = ("d1_m", "d2_m")
MIN_SATURATED_S = 0.1
"""Shortest stretch at the column's extreme counted as saturation."""
OVER_EVENT = "probe_over_range"
IN_EVENT = "probe_in_range"


@dataclass(frozen=True)
class ProbeRange:
    """Per-sample validity of delta and what was found."""

    delta_valid: np.ndarray
    """True where both probes were in range."""
    over_fraction: dict[str, float]
    """Fraction of the record each over-range probe spent over range."""
    source: dict[str, str]
    """How it was found per probe: 'events', 'saturation' or 'events + saturation'."""
    not_measured: tuple[str, ...] = ()
    """Probe columns constant over the whole record (no probe)."""
    why_not: str = ""
    """Why delta counts as not measured (for the note)."""

    @property
    def any_over(self) -> bool:
        return not bool(self.delta_valid.all())

    @property
    def delta_measured(self) -> bool:
        """False when no probe column varies: the record holds no delta."""
        return len(self.not_measured) < len(PROBES)

    def notes(self, name: str) -> list[str]:
        if not self.delta_measured:
            why = self.why_not or f"{' and '.join(self.not_measured)} constant"
            return [f"no delta measured in {name} ({why}): "
                    "delta features (K(i), slip distance, lag, initial-stage curve) left out"]
        return [
            f"{probe.split('_')[0].upper()} over range for {100.0 * frac:.0f} % of {name} "
            f"({self.source[probe]}): delta features excluded there"
            for probe, frac in self.over_fraction.items()
        ]


def _quantum(x: FloatArray) -> float:
    """The column's quantisation step: the typical gap between neighbouring distinct values."""
    u = np.unique(x)
    if u.size < 2:
        return 0.0
    gaps = np.diff(u)
    return float(np.median(gaps))


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, stop) of the runs of True in mask."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    edges = np.flatnonzero(np.diff(m))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)]


def not_measured(x: FloatArray) -> bool:
    """The column holds one value over the whole record (zero-filled, or a disconnected probe)."""
    return x.shape[0] > 0 and bool(np.all(x == x[0]))


def saturated(x: FloatArray, t: FloatArray, x_stage: FloatArray) -> np.ndarray:
    """Samples where the probe column ``x`` sits at its extreme (see the module docstring)."""
    out = np.zeros(x.shape[0], dtype=bool)
    if x.shape[0] < 4:
        return out
    tol = 1.01 * _quantum(x) + 1e-15
    dt = float(np.median(np.diff(t)))
    min_len = max(4, int(np.ceil(MIN_SATURATED_S / dt)))
    stage_tol = max(5.0 * noise_sigma(x_stage), 1e-9)
    for at_extreme in (x >= float(np.max(x)) - tol, x <= float(np.min(x)) + tol):
        for a, b in _runs(at_extreme):
            if b - a < min_len:
                continue
            if float(np.ptp(x_stage[a:b])) > stage_tol:
                out[a:b] = True
    return out


def _event_mask(run: MeasuredRun, events: list[RunEvent]) -> dict[str, np.ndarray]:
    """Over-range samples per probe from a run file's events ({} for CSV or no events)."""
    t = run.t_s
    out: dict[str, np.ndarray] = {}
    start: dict[str, float] = {}
    for ev in sorted(events, key=lambda e: e.t_s):
        if ev.name not in (OVER_EVENT, IN_EVENT):
            continue
        probe = ev.message.split(":", 1)[0].strip()
        if probe not in PROBES:
            continue
        if ev.name == OVER_EVENT:
            start.setdefault(probe, ev.t_s)
        elif probe in start:
            mask = out.setdefault(probe, np.zeros(t.shape[0], dtype=bool))
            mask[(t >= start.pop(probe)) & (t < ev.t_s)] = True
    for probe, t0 in start.items():
        mask = out.setdefault(probe, np.zeros(t.shape[0], dtype=bool))
        mask[t >= t0] = True
    return out


def probe_range(run: MeasuredRun, delta_measured: bool | None = None) -> ProbeRange:
    """Where each probe of ``run`` was over range and the resulting valid-delta mask
    (``delta_measured=False``: the record states it has no probes)."""
    n = run.n_samples
    if delta_measured is False:
        return ProbeRange(np.zeros(n, dtype=bool), {}, {}, PROBES, "rig.delta_measured: no")
    events = record_events(run)
    from_events = _event_mask(run, events)
    valid = np.ones(n, dtype=bool)
    for moving in unsteady_windows(run, events).values():
        valid &= ~moving  # a mount moved across a slip (re-centring): no delta read there
    frac: dict[str, float] = {}
    source: dict[str, str] = {}
    constant = tuple(p for p in PROBES if not_measured(getattr(run, p)))
    if len(constant) == len(PROBES):
        return ProbeRange(np.zeros(n, dtype=bool), {}, {}, constant)
    for probe in PROBES:
        if probe in constant:
            continue
        sat = saturated(getattr(run, probe), run.t_s, run.x_stage_m)
        ev = from_events.get(probe)
        over = sat if ev is None else (sat | ev)
        if not over.any():
            continue
        valid &= ~over
        frac[probe] = float(np.count_nonzero(over)) / max(n, 1)
        kinds = [k for k, m in (("events", ev), ("saturation", sat))
                 if m is not None and m.any()]
        source[probe] = " + ".join(kinds)
    return ProbeRange(valid, frac, source, constant)
