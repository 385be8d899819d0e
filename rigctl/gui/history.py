"""Bounded live history of the DAQ stream for plotting (no Qt): fixed-size ring buffers.

The live view keeps the last ``window_s`` of rig time of a few channels in preallocated numpy rings, so
memory does not grow with the length of a run and appending a block costs O(block length). Nothing is
re-read from the run file.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np


class LiveHistory:
    """The newest ``capacity`` samples of ``channels`` (each a float64 ring), oldest first on read."""

    def __init__(self, channels: Sequence[str], capacity: int) -> None:
        if capacity < 1:
            raise ValueError(f"live history capacity must be >= 1 sample, got {capacity}")
        self.channels = tuple(channels)
        self.capacity = int(capacity)
        self._rings = {c: np.full(self.capacity, np.nan) for c in self.channels}
        self._head = 0  # next write position
        self._count = 0  # valid samples (<= capacity)
        self.total = 0
        """Samples appended since the last clear (including those pushed out of the ring)."""

    def __len__(self) -> int:
        return self._count

    def clear(self) -> None:
        for ring in self._rings.values():
            ring.fill(np.nan)
        self._head = self._count = self.total = 0

    def append(self, block: Mapping[str, np.ndarray]) -> None:
        """Append one block (every channel the same length; extra keys in ``block`` are ignored)."""
        n = int(np.shape(block[self.channels[0]])[0])
        if n == 0:
            return
        self.total += n
        for c in self.channels:
            data = np.asarray(block[c], dtype=float)
            if data.shape[0] != n:
                raise ValueError(f"live block: channel {c} has {data.shape[0]} samples, expected {n}")
            if n >= self.capacity:
                self._rings[c][:] = data[-self.capacity:]
                continue
            end = self._head + n
            ring = self._rings[c]
            if end <= self.capacity:
                ring[self._head:end] = data
            else:
                split = self.capacity - self._head
                ring[self._head:] = data[:split]
                ring[:end - self.capacity] = data[split:]
        if n >= self.capacity:
            self._head, self._count = 0, self.capacity
        else:
            self._head = (self._head + n) % self.capacity
            self._count = min(self._count + n, self.capacity)

    def view(self, channel: str) -> np.ndarray:
        """The stored samples of ``channel``, oldest first (a new array)."""
        ring = self._rings[channel]
        if self._count < self.capacity:
            return ring[self._head - self._count:self._head].copy()
        return np.concatenate([ring[self._head:], ring[:self._head]])

    def latest(self, channel: str) -> float:
        if self._count == 0:
            return float("nan")
        return float(self._rings[channel][self._head - 1])

    @property
    def nbytes(self) -> int:
        return sum(r.nbytes for r in self._rings.values())


def peak_decimate(x: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ``max_points`` points keeping each bucket's min and max (a stick-slip drop stays visible).

    ``x`` is assumed monotonic (time); buckets are equal sample counts. Returns views when no
    decimation is needed.
    """
    n = int(x.shape[0])
    if n <= max_points or max_points < 4:
        return x, y
    buckets = max_points // 2
    size = n // buckets
    m = buckets * size
    yb = y[n - m:].reshape(buckets, size)
    xb = x[n - m:].reshape(buckets, size)
    lo = np.argmin(yb, axis=1)  # a NaN in a bucket is picked (a gap stays a gap)
    hi = np.argmax(yb, axis=1)
    first = np.minimum(lo, hi)
    second = np.maximum(lo, hi)
    rows = np.arange(buckets)
    xo = np.empty(2 * buckets)
    yo = np.empty(2 * buckets)
    xo[0::2], xo[1::2] = xb[rows, first], xb[rows, second]
    yo[0::2], yo[1::2] = yb[rows, first], yb[rows, second]
    return xo, yo
