"""Slip events found in a sampled tangential-force record.

Why not single samples: the rig samples at 1024 Hz while a slip lasts under a millisecond and the
specimen then rings at about 1 kHz (docs/model.md), so the samples right after a slip alias
the ringing into a slow-looking, several-newton oscillation. A slip is therefore detected as a *drop*
of the tangential force by more than a threshold within a short window (a few ms), and every drop that
follows within the merge gap (the aliased ringing, even where it swings through zero) belongs to the
same event, whose direction is that of its first drop. The threshold is
``max(k * noise RMS, f * force scale)`` and is fixed per campaign from the measured data, so model
and measurement are read with the same eyes. Drops are counted in the direction of loading
(|Ft| falls), so a reversed run works too. A drop that is only a few thresholds large must come with
a forward jump of the interface displacement delta (a real slip moves the interface; an unloading does
not) when delta carries a signal, a jump beyond three times the *measured* record's delta noise in
the model's output too. Where the drive velocity is given, a drop while the stage moves
against the force (a reciprocating rig's stroke reversal: the force falls through zero as the stage
turns back, however fast) is an unloading, not a slip. A drop that is a swing of the previous
slip's ringing (a lightly damped slider rings for longer than the merge gap, and each ring swing can
pass the threshold: :func:`is_ring_swing`) belongs to that slip, not a new one.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigctl.records.signals import FloatArray, noise_sigma, sliding_extreme


@dataclass(frozen=True)
class DetectionSettings:
    """How slips are told from noise; thresholds in newtons, windows in seconds."""

    threshold_N: float
    drop_window_s: float = 0.006
    merge_gap_s: float = 0.03
    confirm_factor: float = 4.0
    """Drops below confirm_factor * threshold need a forward delta jump."""
    delta_sigma_m: float = 0.0
    """The measured record's delta noise RMS. A confirming delta jump must exceed 3 of it in any
    record read with these settings: a model's noise-free delta would otherwise confirm every
    small drop that the measured probe's noise leaves unconfirmed."""

    def drop_window(self, dt: float) -> int:
        """``drop_window_s`` in samples of interval ``dt`` (at least 2)."""
        return max(2, round(self.drop_window_s / dt))

    @staticmethod
    def from_signal(
        ft_N: FloatArray, k_sigma: float = 12.0, frac_of_scale: float = 0.004,
        delta_m: FloatArray | None = None, delta_valid: np.ndarray | None = None,
    ) -> DetectionSettings:
        """Threshold from a measured force record: k noise RMS or a fraction of the force scale;
        with ``delta_m``, the record's delta noise (over ``delta_valid`` samples where given)."""
        sigma = noise_sigma(ft_N)
        scale = float(np.percentile(np.abs(ft_N), 99.0)) if ft_N.size else 0.0
        d_sigma = 0.0 if delta_m is None else noise_sigma(_in_range(delta_m, delta_valid))
        return DetectionSettings(threshold_N=max(k_sigma * sigma, frac_of_scale * scale, 1e-9),
                                 delta_sigma_m=d_sigma)


@dataclass(frozen=True)
class SlipIndices:
    """Detected slips of one record, as sample indices (all arrays the same length)."""

    i_peak: np.ndarray
    """Last sample at the peak, just before the force falls."""
    i_end: np.ndarray
    """Last sample of the event's drops (the aliased ringing included)."""
    sign: np.ndarray
    """+1 for slips under positive Ft, -1 under negative Ft."""

    @property
    def n(self) -> int:
        return int(self.i_peak.shape[0])


def detect_slips(
    t_s: FloatArray,
    ft_N: FloatArray,
    delta_m: FloatArray | None,
    settings: DetectionSettings,
    delta_valid: np.ndarray | None = None,
    v_drive_m_s: FloatArray | None = None,
    fn_N: FloatArray | None = None,
) -> SlipIndices:
    """Find slip events in a force record (see the module docstring).

    Where ``delta_valid`` is False (a probe over range) delta cannot confirm a small drop, which is
    then judged by the force alone. ``v_drive_m_s`` (the stage velocity per sample, e.g. from the
    simplified drive) rejects drops while the stage moves against the force (stroke reversals),
    except where ``fn_N`` changes over the drop (a release of the normal load, which the
    workbench pairs as such: :mod:`rigctl.records.features`).
    """
    n = ft_N.shape[0]
    empty = SlipIndices(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0, np.int8))
    if n < 8:
        return empty
    dt = float(np.median(np.diff(t_s)))
    w = settings.drop_window(dt)
    gap = max(w + 1, round(settings.merge_gap_s / dt))
    thr = settings.threshold_N
    fwd_min = sliding_extreme(ft_N, w, "min")
    fwd_max = sliding_extreme(ft_N, w, "max")
    sign = np.sign(ft_N)
    drop = np.where(sign > 0, ft_N - fwd_min, fwd_max - ft_N)
    cand = np.flatnonzero((drop > thr) & (np.abs(ft_N) > thr))
    if cand.size == 0:
        return empty
    breaks = np.flatnonzero(np.diff(cand) > gap) + 1
    clusters = split_ring_chains(np.split(cand, breaks), ft_N, w, gap)
    d_sigma, d_informative = 0.0, False
    if delta_m is not None:
        d_ok = _in_range(delta_m, delta_valid)
        d_sigma = max(noise_sigma(d_ok), settings.delta_sigma_m)
        d_informative = d_ok.size > 0 and float(np.ptp(d_ok)) > 20.0 * d_sigma
    v_ref = 0.0
    if v_drive_m_s is not None:
        moving = np.abs(v_drive_m_s[v_drive_m_s != 0.0])
        v_ref = float(np.median(moving)) if moving.size else 0.0
    peaks: list[int] = []
    ends: list[int] = []
    signs: list[int] = []
    prev_size = 0.0
    for c in clusters:
        c0, c1 = int(c[0]), int(c[-1])
        s = int(sign[c0])
        i_end = min(c1 + w, n - 1)
        seg = s * ft_N[c0 : min(c0 + w + 2, n)]
        # the peak is the last sample before the first clear one-sample fall (under noise the
        # highest sample may sit a few samples early); else the highest sample
        size_est = _run_size(c, ft_N, w, n)
        falls = np.flatnonzero(seg[:-1] - seg[1:] > max(0.5 * thr, 0.1 * size_est))
        i_pk = c0 + int(falls[0]) if falls.size else c0 + int(np.argmax(seg))
        if i_pk > i_end:
            # a lone candidate whose force is highest after its drop window: it rises on, no slip
            continue
        size = s * ft_N[i_pk] - float(np.min(s * ft_N[i_pk : i_end + 1]))
        if size <= thr:
            continue
        if (peaks and signs[-1] == s
                and is_ring_swing(s * ft_N, w, peaks[-1], prev_size, i_pk, i_end, size)):
            continue
        if (v_drive_m_s is not None and _against_the_force(v_drive_m_s, i_pk, i_end, s, v_ref)
                and not _load_changes(fn_N, i_pk - gap, i_end + gap)):
            continue
        if (size < settings.confirm_factor * thr and d_informative and delta_m is not None
                and (delta_valid is None
                     or delta_valid[max(0, i_pk - w) : min(n, i_end + gap)].all())):
            before = float(np.median(delta_m[max(0, i_pk - w) : i_pk + 1]))
            after = float(np.median(delta_m[i_end : min(n, i_end + gap)]))
            if s * (after - before) <= 3.0 * d_sigma:
                continue
        peaks.append(i_pk)
        ends.append(i_end)
        signs.append(s)
        prev_size = size
    return SlipIndices(
        np.array(peaks, dtype=np.intp), np.array(ends, dtype=np.intp), np.array(signs, np.int8)
    )


LONG_CHAIN_GAPS = 5
"""A cluster of drops longer than this many merge gaps is a chain of ring swings (swings closer
than the merge gap, ringing on above the threshold) that may hold the next slip."""
CHAIN_GROWTH = 1.5
"""In a chain, a drop this much larger than the one before it is not a swing of a decaying
ringing."""


def split_ring_chains(clusters: list[np.ndarray], ft_N: FloatArray, w: int,
                      gap: int) -> list[np.ndarray]:
    """Clusters of drop candidates, with every long chain cut before each slip in it.

    A lightly damped slider ringing faster than the merge gap, above the threshold until the next
    slip (a light slider, a low noise floor), chains every swing and that slip into one cluster,
    and the slip would be lost. A long cluster (over LONG_CHAIN_GAPS merge gaps) is cut into runs
    of consecutive drops (no gap larger than the drop window). A run starts a new slip when its
    drop exceeds RING_SIZE_FRACTION of the slip that opened its part of the chain and
    CHAIN_GROWTH times the run before it (a free oscillation's swings only shrink); the others
    stay with that slip. Where the chain opens with drops under RING_SIZE_FRACTION of a later one
    (the tail of an earlier ringing, a noise dip on the ramp), that later one is its slip, not a
    new one: the cluster reads as before.
    """
    out: list[np.ndarray] = []
    n = ft_N.shape[0]
    for c in clusters:
        if c.size == 0 or int(c[-1] - c[0]) <= LONG_CHAIN_GAPS * gap:
            out.append(c)
            continue
        runs = np.split(c, np.flatnonzero(np.diff(c) > w + 1) + 1)
        current = [runs[0]]
        opened = last = _run_size(runs[0], ft_N, w, n)
        for run in runs[1:]:
            size = _run_size(run, ft_N, w, n)
            if opened < RING_SIZE_FRACTION * size:
                current.append(run)
                opened = size
            elif size > RING_SIZE_FRACTION * opened and size > CHAIN_GROWTH * last:
                out.append(np.concatenate(current))
                current, opened = [run], size
            else:
                current.append(run)
            last = size
        out.append(np.concatenate(current))
    return out


def _run_size(run: np.ndarray, ft_N: FloatArray, w: int, n: int) -> float:
    """Force fall of a run of drop candidates in the direction of loading: the highest of its
    first samples down to the lowest until a drop window after it."""
    s = 1.0 if ft_N[int(run[0])] >= 0 else -1.0
    i0, i1 = int(run[0]), min(int(run[-1]) + w + 1, n)
    return float(np.max(s * ft_N[i0 : min(i0 + w + 2, n)]) - np.min(s * ft_N[i0:i1]))


def _in_range(delta_m: FloatArray, delta_valid: np.ndarray | None) -> FloatArray:
    """Delta where the probes were in range (all of it where no mask is given)."""
    return delta_m if delta_valid is None else delta_m[delta_valid]


RING_SIZE_FRACTION = 0.5
"""A ring swing is at most this fraction of the slip that set it ringing."""
RING_RISE_RANGE = (0.5, 3.0)
"""Just before a ring swing falls, the force rose by about as much as it then falls (a sinusoid's
halves are equal); before a slip it rose far less in the same time (the stick loading rate), or
far more (a stroke reversal loading the contact from the other side)."""
RING_LOOK_BACK = 3
"""The rise is read within this many times the drop's fall (peak to lowest sample, plus the
drop window) before its peak."""
RING_LOW_QUANTILE = 0.1
"""The level the force rose from: this quantile of the look-back (single-sample spikes of a
record do not count as a trough)."""
RING_RETURN = 0.75
"""After a swing the force comes back up: its median over the look-back after the drop lies
less than this fraction of the drop below the peak (about half way: the oscillation's centre),
where after a slip it stays down at the trough."""
RING_SPAN_OVER_ELAPSED = 0.5
"""The look-back is a small part of the time since the slip (several swings fit in it); in a
near-harmonic stick-slip each cycle is a single swing."""


def is_ring_swing(f: FloatArray, w: int, i_prev_peak: int, prev_size: float, i_pk: int,
                  i_end: int, size: float) -> bool:
    """A drop of ``size`` from ``i_pk`` to ``i_end`` is a swing of the ringing of the previous
    slip (peak at ``i_prev_peak``, drop ``prev_size``); ``f`` is the force in the direction of
    loading and ``w`` the drop window in samples.

    A decaying oscillation about the post-slip line has four features a slip lacks together:
    its swings are small against the slip that excited it (a free oscillation loses energy),
    the force rose just before each swing by about as much as it then falls, within a few fall
    times (a sinusoid's halves are equal, where a slip ends a stick ramp rising at the loading
    rate), it comes back up after the swing (where a slip leaves it at the trough), and several
    swings fit in the time since that slip. A slip of a near-harmonic stick-slip, a slip of
    comparable size, a slip after a stroke reversal and a slow slip starting at a spike each fail
    one.
    """
    if size > RING_SIZE_FRACTION * prev_size:
        return False
    i_min = i_pk + int(np.argmin(f[i_pk : i_end + 1]))
    look = RING_LOOK_BACK * (i_min - i_pk + w)
    if look > RING_SPAN_OVER_ELAPSED * (i_pk - i_prev_peak):
        return False
    before = f[max(i_pk - look, i_prev_peak) : i_pk]
    if before.size == 0:
        return False
    rise = f[i_pk] - float(np.quantile(before, RING_LOW_QUANTILE))
    lo, hi = RING_RISE_RANGE
    if not lo * size <= rise <= hi * size:
        return False
    after = f[i_end : i_end + look]
    return after.size > 0 and float(np.median(after)) > f[i_pk] - RING_RETURN * size


AGAINST_FRACTION = 0.1
"""A drop is an unloading when the stage moves against the force faster than this fraction of the
record's typical drive speed (a stage at rest, or a phase line drifting by its noise, is not)."""


def _against_the_force(v_drive_m_s: FloatArray, i_pk: int, i_end: int, sign: int,
                       v_ref: float) -> bool:
    """The stage moves against the force over the drop: an unloading by a stroke reversal (a slip
    happens while the drive pushes the way the force points)."""
    v = sign * v_drive_m_s[i_pk : i_end + 1]
    return bool(v.size) and float(np.mean(v)) < -AGAINST_FRACTION * v_ref


LOAD_CHANGE = 0.25
"""Relative change of Fn around a drop that makes it a load change (as the release rule of
:mod:`rigctl.records.features`), not a stroke reversal."""


def _load_changes(fn_N: FloatArray | None, i0: int, i1: int) -> bool:
    if fn_N is None:
        return False
    seg = np.abs(fn_N[max(i0, 0) : max(i1, 0) + 1])
    if seg.size == 0:
        return False
    top = float(np.max(seg))
    return top > 0.0 and float(np.max(seg) - np.min(seg)) > LOAD_CHANGE * top
