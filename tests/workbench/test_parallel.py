"""Parallel candidate fits: order, failures, time limits, and a Dask cluster.

No test sleeps. A task that "takes long" is *held*: its worker blocks on a pipe (its gate) until the
test writes to it, or for ever, and is then stopped at its limit. The adaptive time limit is run in
virtual time: the test holds ``parallel._clock`` (:class:`VirtualClock`) and sets the time at
which each held task finishes, so the limits are checked at the figures they are written with
(the 20 s floor, 6 x the slowest per unit of cost) and the outcome does not depend on how fast
the machine starts workers.
"""

from __future__ import annotations

import multiprocessing
import os
import select
import signal
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import psutil
import pytest

from rigctl.workbench import parallel
from rigctl.workbench.parallel import TaskFailed, run_tasks

WAIT_S = 60.0  # longest wait for a worker or for run_tasks (a bound for a broken run, not a pace)


def square(x: int) -> int:
    return x * x


def fails_on_three(x: int) -> int:
    if x == 3:
        raise RuntimeError("no threes")
    return x


def held(task: tuple[int, int, int, float]) -> float:
    """Says it runs (its index on the ``started`` pipe), then returns ``value`` once a byte comes
    on its gate; never otherwise (the worker is stopped at its time limit)."""
    index, started, gate, value = task
    os.write(started, bytes([index]))
    os.read(gate, 1)
    return value


class VirtualClock:
    """``parallel._clock`` in the test's hands: it reads ``now`` (set by the test) and counts the
    reads, so that the test knows when run_tasks has looked at the time since it was set."""

    def __init__(self) -> None:
        self.now = 0.0
        self.reads = 0
        self.ended = False  # run_tasks has returned: it reads the clock no more
        self._cond = threading.Condition()

    def __call__(self) -> float:
        with self._cond:
            self.reads += 1
            self._cond.notify_all()
            return self.now

    def set(self, t: float) -> None:
        with self._cond:
            self.now = t

    def end(self) -> None:
        with self._cond:
            self.ended = True
            self._cond.notify_all()

    def settle(self) -> None:
        """Return once run_tasks has read the clock twice more: the first of those reads is a
        whole pass of its loop at the time set (results taken, limits checked) when the second
        comes, where no task is started in between (its start is one read); or once it ended."""
        with self._cond:
            target = self.reads + 2
            if not self._cond.wait_for(lambda: self.reads >= target or self.ended, WAIT_S):
                raise AssertionError(f"run_tasks did not read the clock within {WAIT_S} s")


class HeldTasks:
    """Tasks held on gates, the virtual clock, and what run_tasks reported (``on_done``)."""

    def __init__(self, values: list[float]) -> None:
        self.clock = VirtualClock()
        self.started_r, self.started_w = os.pipe()
        self.gates = [os.pipe() for _ in values]
        self.tasks = [(i, self.started_w, gate_r, v)
                      for i, ((gate_r, _w), v) in enumerate(zip(self.gates, values, strict=True))]
        self.seen_started: set[int] = set()
        self.done: dict[int, float | TaskFailed] = {}
        self._cond = threading.Condition()

    def close(self) -> None:
        for fd in [self.started_r, self.started_w, *(fd for gate in self.gates for fd in gate)]:
            os.close(fd)

    def on_done(self, i: int, res: float | TaskFailed) -> None:
        with self._cond:
            self.done[i] = res
            self._cond.notify_all()

    def release(self, *indices: int) -> None:
        for i in indices:
            os.write(self.gates[i][1], b"x")

    def wait_started(self, *indices: int) -> None:
        """Wait until each task of ``indices`` runs in its worker, then until run_tasks has taken
        its start time (the clock read right after the worker's start)."""
        t_end = time.monotonic() + WAIT_S
        while not self.seen_started.issuperset(indices):
            if not select.select([self.started_r], [], [], max(0.0, t_end - time.monotonic()))[0]:
                raise AssertionError(f"tasks {sorted(set(indices) - self.seen_started)} did not "
                                     f"start within {WAIT_S} s")
            self.seen_started.update(os.read(self.started_r, 64))
        self.clock.settle()

    def wait_done(self, *indices: int) -> None:
        with self._cond:
            if not self._cond.wait_for(lambda: all(i in self.done for i in indices), WAIT_S):
                raise AssertionError(f"tasks {indices} not done within {WAIT_S} s: {self.done}")

    def running(self, i: int) -> bool:
        with self._cond:
            return i not in self.done

    def run(self, script: Callable[[HeldTasks], None], **kwargs: Any
            ) -> list[float | TaskFailed]:
        """run_tasks on the held tasks in this thread while ``script`` drives the clock and the
        gates in another; a failing script ends the run (every gate opened, the clock past every
        limit) and its error is raised here."""
        errors: list[BaseException] = []

        def drive() -> None:
            try:
                script(self)
            except BaseException as exc:
                errors.append(exc)
                self.clock.set(1e12)
                self.release(*range(len(self.tasks)))

        driver = threading.Thread(target=drive, daemon=True)
        driver.start()
        try:
            out = run_tasks(held, self.tasks, on_done=self.on_done, **kwargs)
        finally:
            self.clock.end()
            driver.join(WAIT_S)
        if errors:
            raise errors[0]
        return out


@pytest.fixture
def held_tasks(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[list[float]], HeldTasks]]:
    made: list[HeldTasks] = []

    def make(values: list[float]) -> HeldTasks:
        made.append(HeldTasks(values))
        monkeypatch.setattr(parallel, "_clock", made[-1].clock)
        return made[-1]

    yield make
    for h in made:
        h.close()


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
    """In real time (the monotonic clock): the held task never returns and is stopped at 1 s."""
    started_r, started_w = os.pipe()
    (quick_r, quick_w), (never_r, never_w) = os.pipe(), os.pipe()
    try:
        os.write(quick_w, b"x")  # the quick task's gate is open from the start
        t0 = time.monotonic()
        out = run_tasks(held, [(0, started_w, quick_r, 0.01), (1, started_w, never_r, 30.0)],
                        workers=2, timeout_s=1.0)
        assert out[0] == 0.01
        assert isinstance(out[1], TaskFailed) and "time limit" in out[1].message
        assert 1.0 <= time.monotonic() - t0 < 10.0
    finally:
        for fd in (started_r, started_w, quick_r, quick_w, never_r, never_w):
            os.close(fd)


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


@pytest.mark.parametrize(("quick_s", "cost", "alive_at", "stopped_at"), [
    (5.0, 1.0, 29.0, 31.0),  # 6 x 5 s: 30 s
    (5.0, 2.0, 59.0, 61.0),  # twice the cost: 60 s
    (5.0, 40.0, 290.0, None),  # 6 x 5 s x 40 is past timeout_s (300 s): let finish at 290 s
    (1.0, 1.0, 19.0, 21.0),  # 6 x 1 s is below the floor: 20 s
])
def test_the_adaptive_limit_scales_with_each_tasks_expected_cost(
        held_tasks, quick_s, cost, alive_at, stopped_at):
    """Once three tasks finish, the limit tightens to max(6 x the slowest per unit of cost x the
    task's cost, 20 s): a task known to cost 40 times more (a candidate with a state variable) is
    not stopped for being slower than the quick ones, while one that overruns its own share still
    is. Three quick tasks finish at ``quick_s`` (virtual time); the fourth is running at
    ``alive_at`` and stopped by ``stopped_at`` (or released and returns its value)."""
    h = held_tasks([0.1, 0.2, 0.3, 99.0])

    def script(h: HeldTasks) -> None:
        h.wait_started(0, 1, 2, 3)  # every start time 0
        h.clock.set(quick_s)
        h.release(0, 1, 2)
        h.wait_done(0, 1, 2)
        h.clock.set(alive_at)
        h.clock.settle()
        assert h.running(3), f"stopped at {alive_at} s: {h.done.get(3)}"
        if stopped_at is None:
            h.release(3)
        else:
            h.clock.set(stopped_at)
        h.wait_done(3)

    out = h.run(script, workers=4, costs=[1.0, 1.0, 1.0, cost])
    assert out[:3] == [0.1, 0.2, 0.3]
    if stopped_at is None:
        assert out[3] == 99.0
    else:
        assert out[3] == TaskFailed(f"stopped after {stopped_at:.0f} s (time limit)")


def test_the_limit_is_the_timeout_until_three_tasks_finished(held_tasks):
    h = held_tasks([0.1, 0.2, 99.0])

    def script(h: HeldTasks) -> None:
        h.wait_started(0, 1, 2)
        h.clock.set(1.0)
        h.release(0, 1)
        h.wait_done(0, 1)
        h.clock.set(99.0)  # far past 6 x 1 s and the 20 s floor, within timeout_s
        h.clock.settle()
        assert h.running(2)
        h.clock.set(101.0)
        h.wait_done(2)

    out = h.run(script, workers=3, timeout_s=100.0)
    assert out == [0.1, 0.2, TaskFailed("stopped after 101 s (time limit)")]


def test_costs_must_match_the_tasks():
    with pytest.raises(ValueError, match="2 costs for 4 tasks"):
        run_tasks(square, [1, 2, 3, 4], costs=[1.0, 1.0])


def lingers(_x: int) -> int:
    """Returns its pid at once but leaves a non-daemon thread behind (waiting for ever), which
    keeps its process alive."""
    threading.Thread(target=threading.Event().wait).start()
    return os.getpid()


def _alive(pid: int | TaskFailed) -> bool:
    assert isinstance(pid, int), pid
    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_a_worker_that_does_not_exit_after_its_result_is_killed(monkeypatch):
    """Killed once its grace is over, before its result is reported (not only when the run ends)."""
    monkeypatch.setattr(parallel, "EXIT_GRACE_S", 0.5)
    me = psutil.Process()
    before = {c.pid for c in me.children(recursive=True)}
    alive_when_done: list[bool] = []
    t0 = time.monotonic()
    pids = run_tasks(lingers, [1, 2], workers=2,
                     on_done=lambda _i, pid: alive_when_done.append(_alive(pid)))
    assert time.monotonic() - t0 < 2 * parallel.EXIT_GRACE_S + 5.0
    assert len(set(pids)) == 2 and alive_when_done == [False, False]
    left = [c for c in me.children(recursive=True) if c.pid not in before
            and c.status() != psutil.STATUS_ZOMBIE]
    assert left == []
    assert multiprocessing.active_children() == []


def answers(task: tuple[int, int] | None) -> str:
    """None: returns at once. Otherwise writes its pid on ``reply``, waits for a byte on ``gate``,
    writes "alive" (it was not interrupted in between) and waits for ever."""
    if task is None:
        return "quick"
    gate, reply = task
    os.write(reply, f"{os.getpid()}\n".encode())
    os.read(gate, 1)
    os.write(reply, b"alive\n")
    os.read(gate, 1)
    return "never"


def _read_line(fd: int) -> str:
    got = b""
    t_end = time.monotonic() + WAIT_S
    while not got.endswith(b"\n"):
        if not select.select([fd], [], [], max(0.0, t_end - time.monotonic()))[0]:
            raise AssertionError(f"no answer from the worker within {WAIT_S} s (read {got!r})")
        got += os.read(fd, 1)
    return got.decode().strip()


def test_workers_ignore_sigint_and_the_parent_kills_them_on_keyboard_interrupt():
    """Ctrl-C reaches the workers too (one process group); they leave the decision to the parent,
    which stops with KeyboardInterrupt and kills every worker it started. The worker is sent
    SIGINT while it waits on its gate (a SIGINT it did not ignore would end the wait with
    KeyboardInterrupt), then its gate is opened: it answers that it is still there."""
    me = psutil.Process()
    before = {c.pid for c in me.children(recursive=True)}
    worker: list[psutil.Process] = []
    answered: list[str] = []
    gate_r, gate_w = os.pipe()
    reply_r, reply_w = os.pipe()

    def interrupt(i: int, _res: object) -> None:
        worker.append(psutil.Process(int(_read_line(reply_r))))
        assert worker[0].ppid() == os.getpid()
        worker[0].send_signal(signal.SIGINT)
        os.write(gate_w, b"x")
        answered.append(_read_line(reply_r))
        raise KeyboardInterrupt  # what Ctrl-C does in the parent

    try:
        with pytest.raises(KeyboardInterrupt):
            run_tasks(answers, [None, (gate_r, reply_w)], workers=2, on_done=interrupt)
    finally:
        for fd in (gate_r, gate_w, reply_r, reply_w):
            os.close(fd)
    assert answered == ["alive"]  # the worker kept on after SIGINT
    left = [c for c in me.children(recursive=True) if c.pid not in before
            and c.status() != psutil.STATUS_ZOMBIE]
    assert left == []


@pytest.mark.slow
def test_no_task_is_stopped_before_it_ran_as_long_as_the_slowest_finished(held_tasks):
    """A task whose expected cost is tiny (a cheap probe) is not stopped before it has run as long
    as a finished task took: per unit of cost it may be far slower than the others, but it is no
    slower than a fit that was allowed to finish. Two workers, virtual time: A (cost 10) and B
    start at 0; B ends at 10 s (10 s per unit of cost), C starts and ends at 12 s (2 s); X (cost
    0.01) starts at 12 s; A is the third to finish, at 60 s (6 s per unit), with X at 48 s. X's
    cost-scaled limit is 6 x 10 s x 0.01 = 0.6 s and the floor 20 s: either would stop it at
    once; the slowest finished task (60 s) lets it run to 60 s, and not past."""
    h = held_tasks([1.0, 2.0, 3.0, 4.0])

    def script(h: HeldTasks) -> None:
        h.wait_started(0, 1)
        h.clock.set(10.0)
        h.release(1)
        h.wait_done(1)
        h.wait_started(2)
        h.clock.set(12.0)
        h.release(2)
        h.wait_done(2)
        h.wait_started(3)
        h.clock.set(60.0)
        h.release(0)
        h.wait_done(0)
        h.clock.set(12.0 + 59.0)
        h.clock.settle()
        assert h.running(3), f"stopped at 59 s: {h.done.get(3)}"
        h.clock.set(12.0 + 61.0)
        h.wait_done(3)

    out = h.run(script, workers=2, costs=[10.0, 1.0, 1.0, 0.01])
    assert out == [1.0, 2.0, 3.0, TaskFailed("stopped after 61 s (time limit)")]
