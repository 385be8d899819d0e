"""benchmarks/reading_noise.py: a case's noise-free twin is the same campaign without the sensor
noise, and the slips read in it are counted with the record's own settings."""

from __future__ import annotations

import numpy as np

from benchmarks.bench_other_rigs import draw_case
from benchmarks.reading_noise import slips_read
from rigctl.records.dataset import prepare_dataset

SEED = 7
"""Case 0 of every seed is a control with a TLRE only: the cheapest case to draw."""


def test_the_noise_free_twin_is_the_same_campaign_without_its_noise():
    noisy, hidden, truth, drawn = draw_case(0, SEED)
    clean, hidden_2, truth_2, drawn_2 = draw_case(0, SEED, noisy=False)
    assert (hidden, drawn) == (hidden_2, drawn_2)
    assert truth.values == truth_2.values
    assert [r.source for r in clean] == [r.source for r in noisy]
    rig = drawn["rig"]
    ft_rms_N = drawn["noise_factor"] * 0.005 * rig["mu_s"] * rig["fn_N"]  # bench_other_rigs
    for a, b in zip(noisy, clean, strict=True):
        np.testing.assert_array_equal(a.t_s, b.t_s)
        assert not np.array_equal(a.ft_N, b.ft_N)
        assert 0.7 * ft_rms_N < float(np.std(a.ft_N - b.ft_N)) < 1.4 * ft_rms_N


def test_the_record_is_counted_as_the_workbench_reads_it():
    runs = slips_read(SEED, 0)
    record = prepare_dataset(draw_case(0, SEED)[0])
    assert [(name, n) for name, n, _ in runs] == [
        (run.name, len(run.events.features["drop_N"])) for run in record.runs]
    assert all(n_twin > 0 for _, _, n_twin in runs)
