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
pass the threshold: :func:`rigctl.records.slip_scan.is_ring_swing`) belongs to that slip, not a
new one. The scan over the samples is compiled (:mod:`rigctl.records.slip_scan`, with the rules'
constants): it reads every model evaluation's series.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rigctl.records import slip_scan
from rigctl.records.signals import FloatArray, median, noise_sigma


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
    *,
    dt_s: float | None = None,
    delta_noise_m: float | None = None,
    v_moving_m_s: float | None = None,
) -> SlipIndices:
    """Find slip events in a force record (see the module docstring).

    Where ``delta_valid`` is False (a probe over range) delta cannot confirm a small drop, which is
    then judged by the force alone. ``v_drive_m_s`` (the stage velocity per sample, e.g. from the
    simplified drive) rejects drops while the stage moves against the force (stroke reversals),
    except where ``fn_N`` changes over the drop (a release of the normal load, which the
    workbench pairs as such: :mod:`rigctl.records.features`). ``dt_s`` (the median sample
    interval) and ``delta_noise_m`` (``noise_sigma`` of delta where valid): a caller that has
    read them from this record already passes them (they are medians of the whole record), as
    ``v_moving_m_s``: the median of ``|v_drive_m_s|`` where it is not 0 (0.0 where it is 0 throughout).
    """
    n = ft_N.shape[0]
    empty = SlipIndices(np.zeros(0, np.intp), np.zeros(0, np.intp), np.zeros(0, np.int8))
    if n < 8:
        return empty
    dt = median(np.diff(t_s)) if dt_s is None else dt_s
    w = settings.drop_window(dt)
    gap = max(w + 1, round(settings.merge_gap_s / dt))
    d_sigma, d_informative = 0.0, False
    if delta_m is not None:
        d_ok = _in_range(delta_m, delta_valid)
        noise = noise_sigma(d_ok) if delta_noise_m is None else delta_noise_m
        d_sigma = max(noise, settings.delta_sigma_m)
        d_informative = d_ok.size > 0 and float(np.ptp(d_ok)) > 20.0 * d_sigma
    v_ref = 0.0
    if v_moving_m_s is not None:
        v_ref = v_moving_m_s
    elif v_drive_m_s is not None:
        v_ref = moving_median(v_drive_m_s)
    peaks, ends, signs = slip_scan.scan_slips(
        _samples(ft_N), _samples(delta_m), _NO_MASK if delta_valid is None
        else np.ascontiguousarray(delta_valid, dtype=np.bool_), _samples(v_drive_m_s),
        _samples(fn_N), w, gap, settings.threshold_N, settings.confirm_factor, d_sigma,
        d_informative, v_ref)
    return SlipIndices(peaks, ends, signs)


_NO_MASK = np.zeros(0, dtype=np.bool_)


def moving_median(v_drive_m_s: FloatArray) -> float:
    """The median of ``|v_drive_m_s|`` where it is not 0 (0.0 where it is 0 throughout): the
    drive's typical sliding speed, which :func:`detect_slips` judges drops against."""
    moving = np.abs(v_drive_m_s[v_drive_m_s != 0.0])
    return median(moving) if moving.size else 0.0


def _samples(x: FloatArray | None) -> FloatArray:
    """A channel as the compiled scan takes it: contiguous float64, empty where absent."""
    out: FloatArray = np.zeros(0) if x is None else np.ascontiguousarray(x, dtype=np.float64)
    return out


def split_ring_chains(clusters: list[np.ndarray], ft_N: FloatArray, w: int,
                      gap: int) -> list[np.ndarray]:
    """Clusters of drop candidates (sample indices), with every long chain of ring swings cut
    before each slip in it (:func:`rigctl.records.slip_scan.split_ring_chains`)."""
    if not clusters:
        return []
    cand = np.concatenate(clusters).astype(np.intp)
    starts = np.concatenate([[0], np.cumsum([c.shape[0] for c in clusters])]).astype(np.intp)
    cut = slip_scan.split_ring_chains(cand, starts, _samples(ft_N), w, gap)
    return [cand[a:b] for a, b in zip(cut[:-1], cut[1:], strict=True)]


def _in_range(delta_m: FloatArray, delta_valid: np.ndarray | None) -> FloatArray:
    """Delta where the probes were in range (all of it where no mask is given)."""
    return delta_m if delta_valid is None else delta_m[delta_valid]
