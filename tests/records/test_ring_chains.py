"""A ringing faster than the merge gap that lasts until the next slip does not swallow that slip
(events.split_ring_chains)."""

from __future__ import annotations

import numpy as np
import pytest

from rigctl.records.dataset import prepare_dataset
from rigctl.records.events import split_ring_chains
from tests.workbench.synth import LIGHT_RIG, light_rig_tlre


@pytest.fixture(scope="module")
def ringing_rig():
    """The light slider at 1 % damping on a low noise floor: it rings at 34 Hz (swings 29 ms
    apart, under the 30 ms merge gap) above the detection threshold through the whole 1 s stick."""
    return prepare_dataset(light_rig_tlre(c0_N_s_per_m=LIGHT_RIG["c0_N_s_per_m"]))


def test_every_slip_of_a_ringing_chain_is_found(ringing_rig):
    (run,) = ringing_rig.runs
    t = run.events.covariates["t_s"]
    # 30 s of sliding at 7.4 mm/s, a slip about every 1.05 s: the chain had held all but 2
    assert run.events.n >= 25
    intervals = np.diff(t)[1:]  # the first stick starts from rest
    assert np.all(np.abs(intervals / np.median(intervals) - 1.0) < 0.05), intervals


def test_a_short_cluster_is_left_whole():
    ft = np.array([10.0, 10.0, 8.0, 9.0, 7.0, 8.0, 6.0] + [6.0] * 20)
    cluster = np.array([1, 3, 5])
    (out,) = split_ring_chains([cluster], ft, w=2, gap=4)
    assert np.array_equal(out, cluster)


def test_a_long_chain_is_cut_before_a_slip_not_at_its_swings():
    # a slip of 10 N, then swings of 2 N every 4 samples, then a second slip of 10 N, all one
    # cluster at a merge gap of 5 samples
    ft = np.full(200, 20.0)
    ft[10:] = 10.0
    swings = np.arange(14, 90, 4)
    ft[swings + 1] = 8.0
    ft[100:] = 20.0
    ft[104:] = 10.0
    cand = np.concatenate([[9], swings, [103]])
    out = split_ring_chains([cand], ft, w=2, gap=5)
    assert [int(c[0]) for c in out] == [9, 103]
