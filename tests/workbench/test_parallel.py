"""Parallel candidate fits: order, failures, time limits, and a Dask cluster."""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time

import psutil
import pytest

from rigctl.workbench import parallel
from rigctl.workbench.parallel import TaskFailed, run_tasks


def square(x: int) -> int:
    return x * x


def fails_on_three(x: int) -> int:
    if x == 3:
        raise RuntimeError("no threes")
    return x


def sleeps(x: float) -> float:
    time.sleep(x)
    return x


def test_results_come_back_in_task_order_from_processes():
    seen = []
    out = run_tasks(square, [3, 1, 2, 5], workers=2, on_done=lambda i, r: seen.append(i))
    assert out == [9, 1, 4, 25]
    assert sorted(seen) == [0, 1, 2, 3]


def test_a_failing_task_is_reported_and_the_others_finish():
    out = run_tasks(fails_on_three, [1, 3, 5], workers=2)
    assert out[0] == 1 and out[2] == 5
    assert isinstance(out[1], TaskFailed) and "no threes" in out[1].message


def test_a_task_past_its_time_limit_is_stopped():
    t0 = time.monotonic()
    out = run_tasks(sleeps, [0.01, 30.0], workers=2, timeout_s=1.0)
    assert out[0] == 0.01
    assert isinstance(out[1], TaskFailed) and "time limit" in out[1].message
    assert time.monotonic() - t0 < 10.0


def test_in_process_mode_runs_serially():
    assert run_tasks(square, [2, 3], in_process=True) == [4, 9]


def test_tasks_run_on_a_dask_cluster():
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  dashboard_address=None) as cluster:
        out = run_tasks(square, [1, 2, 3], scheduler=cluster.scheduler_address)
        assert out == [1, 4, 9]
        out = run_tasks(fails_on_three, [3, 4], scheduler=cluster.scheduler_address)
        assert isinstance(out[0], TaskFailed) and out[1] == 4


def test_the_adaptive_limit_scales_with_each_tasks_expected_cost(monkeypatch):
    """Once three tasks finish, the limit tightens to 6 x the slowest per unit of cost: a task
    known to cost 40 times more (a candidate with a state variable) is not stopped for being
    slower than the quick ones, while one that overruns its own share still is."""
    monkeypatch.setattr(parallel, "ADAPTIVE_FLOOR_S", 0.5)
    quick = [0.05, 0.05, 0.05]
    # The slow task would sleep 30 s, so that the limit (6 x the slowest quick task, whose measured
    # time includes the worker's start) stays below it even when a loaded machine starts workers
    # slowly (with 5 s it was not stopped under nice 15 beside three busy processes on two cores);
    # stopped at the limit, it costs only that.
    blind = run_tasks(sleeps, [*quick, 30.0], workers=4)
    assert isinstance(blind[3], TaskFailed) and "time limit" in blind[3].message
    aware = run_tasks(sleeps, [*quick, 5.0], workers=4, costs=[1.0, 1.0, 1.0, 40.0])
    assert aware[3] == 5.0
    t0 = time.monotonic()
    hung = run_tasks(sleeps, [*quick, 60.0], workers=4, costs=[1.0, 1.0, 1.0, 2.0])
    assert isinstance(hung[3], TaskFailed) and time.monotonic() - t0 < 20.0
    with pytest.raises(ValueError, match="2 costs for 4 tasks"):
        run_tasks(sleeps, [*quick, 1.0], costs=[1.0, 1.0])


def lingers(x: int) -> int:
    """Returns at once but leaves a non-daemon thread behind, which keeps its process alive."""
    threading.Thread(target=time.sleep, args=(60.0,)).start()
    return x


def test_a_worker_that_does_not_exit_after_its_result_is_killed():
    me = psutil.Process()
    before = {c.pid for c in me.children(recursive=True)}
    t0 = time.monotonic()
    assert run_tasks(lingers, [1, 2], workers=2) == [1, 2]
    assert time.monotonic() - t0 < 2 * parallel.EXIT_GRACE_S + 5.0
    left = [c for c in me.children(recursive=True) if c.pid not in before
            and c.status() != psutil.STATUS_ZOMBIE]
    assert left == []
    assert multiprocessing.active_children() == []


def test_workers_ignore_sigint_and_the_parent_kills_them_on_keyboard_interrupt():
    """Ctrl-C reaches the workers too (one process group); they leave the decision to the parent,
    which stops with KeyboardInterrupt and kills every worker it started."""
    me = psutil.Process()
    before = {c.pid for c in me.children(recursive=True)}
    ignored: list[bool] = []

    def interrupt(i: int, _res: object) -> None:
        workers = [c for c in me.children(recursive=True) if c.pid not in before
                   and c.status() != psutil.STATUS_ZOMBIE]
        for c in workers:
            os.kill(c.pid, signal.SIGINT)
        time.sleep(0.5)
        ignored.extend(c.is_running() and c.status() != psutil.STATUS_ZOMBIE for c in workers)
        raise KeyboardInterrupt  # what Ctrl-C does in the parent

    with pytest.raises(KeyboardInterrupt):
        run_tasks(sleeps, [0.01, 30.0], workers=2, on_done=interrupt)
    assert ignored == [True]  # the worker still sleeping kept on
    left = [c for c in me.children(recursive=True) if c.pid not in before
            and c.status() != psutil.STATUS_ZOMBIE]
    assert left == []


def test_no_task_is_stopped_before_it_ran_as_long_as_the_slowest_finished(monkeypatch):
    """A task whose expected cost is tiny (a cheap probe) is not stopped before it has run as long
    as a finished task took: per unit of cost it may be far slower than the others, but it is no
    slower than a fit that was allowed to finish. Two workers: A (5 s) and B (2 s) start; C after
    B; X (4 s, cost 0.01) after C, at about 2 s; A is the third to finish, at 5 s, with X at 3 s of
    its 4. Its cost-scaled limit is 6 x (2 s / 1) x 0.01 = 0.12 s: the 0.5 s floor would stop it
    at once; the slowest finished task (5 s) lets it finish."""
    monkeypatch.setattr(parallel, "ADAPTIVE_FLOOR_S", 0.5)
    out = run_tasks(sleeps, [5.0, 2.0, 0.05, 4.0], workers=2, costs=[10.0, 1.0, 1.0, 0.01])
    assert out == [5.0, 2.0, 0.05, 4.0]
