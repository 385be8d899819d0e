"""signals.median: np.median's value, bit for bit, from one partition."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rigctl.records.signals import median, noise_sigma


def _bits(v: float) -> bytes:
    return np.float64(v).tobytes()


@pytest.mark.parametrize("n", [1, 2, 3, 4, 7, 8, 9, 16, 17, 127, 128, 129, 1000, 1001, 23984])
def test_the_same_bits_as_numpy_on_random_data_odd_and_even(n):
    rng = np.random.default_rng(n)
    for x in (rng.normal(size=n), np.round(rng.normal(size=n) * 0.1) * -1.0,
              rng.normal(size=n) * 1e-9 + 3.0, np.round(rng.normal(size=n), 1),
              rng.integers(-3, 3, size=n).astype(np.float64), np.exp(rng.normal(size=n) * 30)):
        assert _bits(median(x)) == _bits(float(np.median(x)))


def test_ties_infinities_nan_and_empty():
    assert median(np.array([1.0, 1.0, 1.0, 2.0])) == 1.0
    assert median(np.array([-np.inf, 0.0, 1.0, np.inf])) == 0.5
    with np.errstate(invalid="ignore"):  # numpy warns of inf - inf too
        assert math.isnan(median(np.array([-np.inf, np.inf])))
        assert math.isnan(float(np.median(np.array([-np.inf, np.inf]))))
    assert math.isnan(median(np.array([1.0, np.nan, 2.0])))
    assert math.isnan(median(np.zeros(0)))
    x = np.array([3.0, 1.0, 2.0, 4.0])
    median(x)
    assert x.tolist() == [3.0, 1.0, 2.0, 4.0]  # the input is not reordered


def test_noise_sigma_reads_the_noise_it_was_given():
    rng = np.random.default_rng(3)
    x = np.linspace(0.0, 5.0, 40_000) + rng.normal(0.0, 0.02, 40_000)
    assert noise_sigma(x) == pytest.approx(0.02, rel=0.03)


@pytest.mark.parametrize("n", [1, 2, 3, 4, 5, 8, 9, 64, 65, 1000, 1001, 23984])
@pytest.mark.parametrize("zero_share", [0.25, 0.4, 0.5, 0.6, 0.9, 1.0])
def test_the_same_bits_as_numpy_where_many_values_are_exactly_zero(n, zero_share):
    """A noise-free series' second differences: many exact zeros of either sign, the middle
    falling among the negatives, the zeros or the positives as the shares vary."""
    rng = np.random.default_rng(int(n + 1000 * zero_share))
    for neg_share in (0.0, 0.2, 0.5, 0.8, 1.0):
        zero = rng.random(n) < zero_share
        sign = np.where(rng.random(n) < neg_share, -1.0, 1.0)
        x = np.where(zero, np.where(rng.random(n) < 0.5, -0.0, 0.0),
                     sign * np.abs(rng.normal(size=n)) * 1e-14)
        assert _bits(median(x)) == _bits(float(np.median(x)))
        lattice = np.where(zero, 0.0, sign * rng.integers(1, 4, size=n) * 2.0**-46)
        assert _bits(median(lattice)) == _bits(float(np.median(lattice)))


def test_zeros_with_infinities():
    for x in ([-np.inf, 0.0, 0.0, np.inf], [-np.inf, 0.0, np.inf, np.inf], [0.0, -0.0, np.inf],
              [-np.inf, -0.0, -0.0, 5.0]):
        a = np.array(x)
        assert _bits(median(a)) == _bits(float(np.median(a)))
