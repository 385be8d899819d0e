"""Shared helpers of the storage tests."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from rigctl.storage import DEFAULT_DAQ_CHANNELS


def block(
    start: int, n: int, channels: Sequence[str] = DEFAULT_DAQ_CHANNELS, rate_hz: float = 1024.0
) -> dict[str, np.ndarray]:
    """Samples start..start+n: t = i / rate, channel j = j * 1000 + i (easy to check)."""
    i = np.arange(start, start + n, dtype=np.float64)
    out = {"t_s": i / rate_hz}
    for j, name in enumerate(channels):
        out[name] = j * 1000.0 + i
    return out
