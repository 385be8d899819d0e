"""Shared helpers of the io tests."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.data import MeasuredRun


def make_run(n: int = 200, seed: int = 0, extra: bool = True) -> MeasuredRun:
    """A run with awkward but finite values (tiny, large, negative, non-round)."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 1024.0 + 0.1
    return MeasuredRun(
        t_s=t,
        x_stage_m=1e-5 * t,
        fn_N=300.0 + rng.normal(0.0, 0.3, n),
        ft_N=40.0 * np.sin(t) + rng.normal(0.0, 1e-3, n),
        d1_m=rng.normal(0.0, 1e-6, n),
        d2_m=-rng.normal(0.0, 1e-7, n),
        extra={"fx_N": rng.normal(size=n) * 1e3, "temp_C": np.full(n, 21.5)} if extra else {},
        metadata={"sample_rate_hz": "1024", "operator": "A. Tester", "lab note": "x: y"},
    )


@pytest.fixture
def run() -> MeasuredRun:
    return make_run()
