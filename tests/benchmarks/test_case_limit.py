"""benchmarks/bench_other_rigs.py --case-limit-s: a case still running at its limit is cancelled
and answers "time limit" (a miss with no name), and the run goes on to the next case."""

from __future__ import annotations

import time

import pytest

from benchmarks.bench_other_rigs import run_case


@pytest.mark.slow
def test_a_case_past_its_limit_is_cancelled_and_answers_time_limit():
    t0 = time.monotonic()
    res = run_case(0, seed=7, workers=1, limit_s=1.0)
    assert res["answer"] == "time limit"
    assert res["hit"] is False and res["final"] == []
    assert "time limit (1 s)" in res["unexplained"]
    # drawing the case and simulating it takes its own time; the diagnosis ends soon after 1 s
    assert res["wall_s"] < 30.0, res["wall_s"]
    assert time.monotonic() - t0 < 120.0
