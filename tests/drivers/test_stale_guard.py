"""The stale-reading watchdog: a force reading that stops changing is a fault (drivers/safety.py)."""

from __future__ import annotations

import numpy as np
import pytest

from drivers.errors import StaleReadingError
from drivers.safety import STALE_WINDOW_S, StaleReadingGuard

RATE_HZ = 1024.0


class _Stage:
    name = "stage"

    def __init__(self, fail: bool = False) -> None:
        self.stops = 0
        self.estops = 0
        self.fail = fail

    def stop(self) -> None:
        self.stops += 1
        if self.fail:
            raise RuntimeError("controller silent")

    def emergency_stop(self) -> None:
        self.estops += 1


def _blocks(values: np.ndarray, block: int = 64):
    t = np.arange(values.shape[0]) / RATE_HZ
    for i in range(0, values.shape[0], block):
        yield t[i : i + block], [values[i : i + block, k] for k in range(3)]


def test_a_live_noisy_reading_never_trips() -> None:
    rng = np.random.default_rng(0)
    live = np.round(rng.normal(0.0, 0.05, (20 * 1024, 3)) / 0.025) * 0.025  # 20 s on 0.025 N counts
    guard = StaleReadingGuard([_Stage()])
    assert all(guard.feed(t, ch) is None for t, ch in _blocks(live))


@pytest.mark.parametrize("frozen_at_s", [0.0, 3.0])
def test_a_frozen_reading_trips_within_the_window(frozen_at_s: float) -> None:
    rng = np.random.default_rng(1)
    v = np.round(rng.normal(50.0, 0.05, (10 * 1024, 3)) / 0.025) * 0.025
    i0 = int(frozen_at_s * RATE_HZ)
    v[i0:] = v[i0]  # the counter advances, the values repeat (a stuck sensor)
    stage_a, stage_b = _Stage(fail=True), _Stage()
    guard = StaleReadingGuard([stage_a, stage_b], device="daq")
    tripped_at = None
    for t, ch in _blocks(v):
        err = guard.feed(t, ch)
        if err is not None:
            tripped_at = float(t[-1])
            assert isinstance(err, StaleReadingError) and "daq" in str(err) and "frozen" in str(err)
            guard.halt()
            break
    assert tripped_at is not None
    assert STALE_WINDOW_S <= tripped_at - frozen_at_s <= STALE_WINDOW_S + 64 / RATE_HZ + 1e-9
    # each stage stopped, the failing one emergency-stopped instead, the other still stopped
    assert (stage_a.stops, stage_a.estops, stage_b.stops) == (1, 1, 1)
    assert guard.feed(np.array([99.0]), [np.zeros(1)] * 3) is None  # stays tripped, reported once


def test_the_window_must_be_positive() -> None:
    with pytest.raises(ValueError, match="positive"):
        StaleReadingGuard([], window_s=0.0)
