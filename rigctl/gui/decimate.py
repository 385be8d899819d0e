"""Peak-preserving decimation for overview plots: a whole run in a few thousand points.

A stick-slip record is a sawtooth: its peaks and troughs are what an overview must show. Each bin of
``B`` samples keeps two samples, those where the chosen signal (Ft) is lowest and highest, in time
order (the "min/max" or "peak" decimation pyqtgraph uses on screen). Every channel is taken at the
same kept samples, so Ft against delta is still a curve of real sample pairs. No Qt here: the
workbench's worker processes use it too.

:class:`PeakEnvelope` does the same incrementally for a run that grows (the Runs tab following a run
being recorded): samples arrive in pieces, memory stays bounded (bins are merged pairwise, doubling
``B``, when there are too many), and nothing is read twice.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def peak_indices(y: FloatArray, max_points: int) -> NDArray[np.int64]:
    """Indices (sorted) of at most ``max_points`` samples of ``y``: the min and max of each bin.

    Short signals (``len(y) <= max_points``) are kept whole. NaNs are ignored within a bin (a bin of
    NaNs keeps its first sample)."""
    if max_points < 2:
        raise ValueError(f"max_points must be at least 2, got {max_points}")
    n = len(y)
    if n <= max_points:
        return np.arange(n, dtype=np.int64)
    size = int(np.ceil(n / (max_points // 2)))
    n_bins = n // size
    head = np.asarray(y[: n_bins * size], dtype=np.float64).reshape(n_bins, size)
    filled_lo = np.where(np.isnan(head), np.inf, head)
    filled_hi = np.where(np.isnan(head), -np.inf, head)
    offsets = np.arange(n_bins, dtype=np.int64) * size
    lo = offsets + np.argmin(filled_lo, axis=1)
    hi = offsets + np.argmax(filled_hi, axis=1)
    idx = np.concatenate([lo, hi, np.arange(n_bins * size, n, dtype=np.int64)])
    return np.unique(idx)


class PeakEnvelope:
    """Incremental :func:`peak_indices` over named channels keyed by one of them.

    ``append(columns)`` takes the next samples (equal-length arrays by channel name); ``view()``
    returns the kept samples of every channel, at most about ``max_points`` of them plus the
    samples of the bin being filled."""

    def __init__(self, key: str, max_points: int = 4000) -> None:
        if max_points < 8:
            raise ValueError(f"max_points must be at least 8, got {max_points}")
        self.key = key
        self.max_points = max_points
        self.bin_size = 2
        """Samples per bin folded from now on (two kept per bin; doubles at each merge)."""
        self.n_samples = 0
        self._kept: dict[str, FloatArray] = {}
        self._pending: dict[str, FloatArray] = {}

    def append(self, columns: dict[str, FloatArray]) -> None:
        if self.key not in columns:
            raise KeyError(f"the samples have no {self.key!r} column (they have "
                           f"{', '.join(columns)})")
        lengths = {len(v) for v in columns.values()}
        if len(lengths) != 1:
            raise ValueError(f"columns of unequal length: {sorted(lengths)}")
        if not self._pending:
            self._pending = {k: np.empty(0) for k in columns}
            self._kept = {k: np.empty(0) for k in columns}
        elif set(columns) != set(self._pending):
            raise KeyError(f"channels changed: {sorted(columns)} after {sorted(self._pending)}")
        self._pending = {k: np.concatenate([self._pending[k], np.asarray(columns[k], float)])
                         for k in self._pending}
        self.n_samples += lengths.pop()
        self._fold()

    def _fold(self) -> None:
        """Move whole bins from the pending samples to the kept ones; merge when too many."""
        size = self.bin_size
        n_full = (len(self._pending[self.key]) // size) * size
        if n_full:
            idx = _min_max_in_groups(self._pending[self.key][:n_full], size)
            for k in self._kept:
                self._kept[k] = np.concatenate([self._kept[k], self._pending[k][idx]])
                self._pending[k] = self._pending[k][n_full:]
        while len(self._kept[self.key]) > self.max_points:
            idx = _min_max_in_groups(self._kept[self.key], 4)
            self._kept = {k: v[idx] for k, v in self._kept.items()}
            self.bin_size *= 2

    def view(self) -> dict[str, FloatArray]:
        """The kept samples and the not yet binned tail, by channel."""
        return {k: np.concatenate([self._kept[k], self._pending[k]]) for k in self._kept}


def _min_max_in_groups(y: FloatArray, size: int) -> NDArray[np.int64]:
    """Indices of the min and the max (in time order) of each group of ``size`` samples of ``y``;
    a last incomplete group is kept whole."""
    n_groups = len(y) // size
    groups = y[: n_groups * size].reshape(n_groups, size)
    offsets = np.arange(n_groups, dtype=np.int64) * size
    lo = np.argmin(np.where(np.isnan(groups), np.inf, groups), axis=1)
    hi = np.argmax(np.where(np.isnan(groups), -np.inf, groups), axis=1)
    pairs = np.stack([np.minimum(lo, hi), np.maximum(lo, hi)], axis=1) + offsets[:, None]
    return np.concatenate([pairs.ravel(), np.arange(n_groups * size, len(y), dtype=np.int64)])
