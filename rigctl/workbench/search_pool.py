"""Evaluations of one search's points in worker processes that hold the dataset once.

:class:`EvaluationPool` evaluates a batch of points (a CMA-ES population) of one model on one
dataset and returns each point's cost and status (:data:`OK`, :data:`TRAPPED`: the model misses
most measured slips, :data:`FAILED`: not physically valid or cannot be run). With ``workers`` >= 1
the points go to a :class:`multiprocessing.pool.Pool` whose initialiser receives the pickled
dataset and the model once, so a task carries only a point; each worker

* holds one :class:`~rigctl.workbench.identify.Objective` per element count it has seen;
* limits BLAS to one thread (``threadpoolctl``): the workers are the parallelism, and a BLAS
  pool per worker would put more busy threads than cores on the machine;
* ignores SIGINT (Ctrl-C at a terminal reaches the whole process group; the parent handles it and
  terminates the pool) and, on Linux, asks the kernel to kill it when its parent dies
  (:func:`rigctl.workbench.parallel.die_with_parent`).

**A time limit per evaluation.** Once the pool has timed an evaluation on a point's integration
path, the point is sent with a limit of :data:`TIME_LIMIT_FACTOR` times the median of the pool's
evaluations on that path so far (at least :data:`TIME_LIMIT_FLOOR_S`), both in CPU seconds of the
worker's thread (:func:`rigctl.model.run_clock`: a machine busy with other jobs neither stops a
point a quiet one lets end nor changes the median); a model run that passes it
is stopped (:class:`~rigctl.model.simulator.TimeLimitError`) and the point counts as one that
cannot be run, as a model that slips past the record's slip budget does. The path is the kernel's
(:meth:`~rigctl.model.spec.ModelSpec.general_path`): a plug-in's terms act only away from their
off values, and where they act the model is integrated by classical RK4 throughout, at a hundred
or more times the exact path's cost. That difference is the model's design, not a point that
chatters, so each path is timed against its own evaluations. The first point of a path runs
alone and unlimited, to time one (and to compile what the path needs). Each worker first runs the
model for a few samples, unlimited, so that compiling its code (numba: the engine's paths in a
fresh cache) is not charged to a point.

The parent waits for a batch in steps of :data:`POLL_S`, checking the budget's cancel flag
(:meth:`~rigctl.workbench.budget.Budget.check`) and the signals noted
(:func:`~rigctl.workbench.interrupts.raise_if_signalled`: a Ctrl-C whose exception Python dropped
in a destructor) between them; a cancel or Ctrl-C terminates every worker at once. The polish's
Jacobians are batches of points like a population; the answer's final evaluation and its
uncertainties run as one task in a worker, so they are cancelled the same way. With ``workers=0``
everything runs in this process (debugging, profiling); a cancel is then seen between evaluations
only.
"""

from __future__ import annotations

import contextlib
import math
import multiprocessing
import os
import pickle
import signal
import statistics
from collections.abc import Sequence
from dataclasses import dataclass, replace
from types import TracebackType
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from rigctl.errors import SimulationError
from rigctl.model import Drive, ParameterError, Simulator, run_clock
from rigctl.records.dataset import Dataset
from rigctl.records.signals import FloatArray
from rigctl.workbench.budget import Budget
from rigctl.workbench.evaluate import evaluate, model_drive
from rigctl.workbench.guess import guess_from_events, initial_guess
from rigctl.workbench.identify import (
    FitResult,
    FreeParam,
    Objective,
    misses_most_slips,
    with_uncertainties,
)
from rigctl.workbench.interrupts import raise_if_signalled
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import die_with_parent

OK, TRAPPED, FAILED = "ok", "trapped", "failed"
POLL_S = 0.1
"""The parent checks the cancel flag this often while workers run: a cancel is seen within a tenth
of a second, far inside the 2 s a user waits for, at no cost."""
TIME_LIMIT_FACTOR = 20.0
"""An evaluation may take this many times the median of the pool's evaluations so far. The
points of one pool are one model at other values, so their costs differ by the slips they make
(an integration is linear in them) and the path they take, not by the model; a point that costs
twenty typical ones holds its worker for longer than a whole CMA-ES generation takes (a
population of 4 + 3 ln n <= 13 points for the search's n <= 20 coordinates): a model that
chatters through slips the record cannot show. Evaluated to the end, one such point has held a
search for minutes; stopped, it is a point that cannot be run."""
TIME_LIMIT_FLOOR_S = 0.5
"""... and at least this much. The limit is CPU time of the worker's thread
(:func:`rigctl.model.run_clock`), which other jobs on the machine do not inflate, so the floor
only keeps a limit above a run's fixed costs (the model's build, page faults of its output tables:
tens of milliseconds), which a median of short evaluations may not show."""
WARM_UP_SAMPLES = 8
"""Samples of the first run each worker simulates before its first point, to compile the model's
code (numba) outside the points' time limits."""


@dataclass(frozen=True)
class Point:
    """A point of the search: the free parameters' internal coordinates and the element count
    (None: the model's own)."""

    u: FloatArray
    n_elements: int | None = None
    time_limit_s: float | None = None
    """CPU seconds its evaluation may take (:func:`rigctl.model.run_clock`; None: no limit;
    :class:`EvaluationPool` sets it)."""
    reread: bool = False
    """Also re-read the base levels from the data at this point (:attr:`Outcome.reread`)."""


@dataclass(frozen=True)
class Outcome:
    """A point's cost |r|^2 (the residual vector of :class:`~rigctl.workbench.identify.Objective`,
    in scatter units), its status and the residual vector itself (None where it failed): the
    search's Jacobians are differences of these."""

    cost: float
    status: str
    vector: FloatArray | None = None
    elapsed_s: float = math.nan
    """CPU seconds the evaluation took (:func:`rigctl.model.run_clock`; NaN where it was stopped
    or failed at once)."""
    timed_out: bool = False
    """The model run passed the point's time limit (a :data:`FAILED` point)."""
    reread: dict[str, float] | None = None
    """Where the point asked for it (:attr:`Point.reread`) and the model ran there: the base
    levels and stiffnesses re-read from the data at the point (the ratio guess of
    :mod:`rigctl.workbench.guess`) from the slips of this same run of the model."""


@dataclass(frozen=True)
class FinishTask:
    """The search's answer: its model (the final values set) evaluated once, as a
    :class:`~rigctl.workbench.identify.FitResult` of ``free``, with uncertainties if asked."""

    choice: ModelChoice
    free: tuple[str, ...]
    message: str
    with_uncertainty: bool


class _Evaluator:
    """The objectives of one model on one dataset, one per element count (in a worker or here)."""

    def __init__(self, dataset: Dataset, choice: ModelChoice, free: Sequence[FreeParam]) -> None:
        self.dataset, self.choice, self.free = dataset, choice, list(free)
        self._objectives: dict[int | None, Objective] = {}
        self._warm_up()

    def _warm_up(self) -> None:
        """The model over the first WARM_UP_SAMPLES samples of the first run, unlimited: its
        compiled code loaded or compiled here, not inside a point's time limit (a model that
        cannot be run here is left to its points)."""
        run = self.dataset.runs[0]
        drive = model_drive(run)
        t = np.array([drive.t_s[0], min(drive.t_s[-1],
                                        drive.t_s[0] + WARM_UP_SAMPLES / run.sample_rate_hz)])
        short = Drive(t - t[0], np.interp(t, drive.t_s, drive.x_stage_m),
                      np.interp(t, drive.t_s, drive.fn_N))
        with contextlib.suppress(SimulationError, ParameterError, ValueError):
            Simulator(self.choice.build(), run.sample_rate_hz).run(short, record_elements=False)

    def __call__(self, point: Point) -> Outcome:
        t0 = run_clock()
        try:
            obj = self._objective(point.n_elements)
            obj.time_limit_s = point.time_limit_s
            vec = obj(point.u)
        except (SimulationError, ParameterError):
            return Outcome(np.inf, FAILED)
        if obj.failed(point.u):  # the vector is the failure penalty: a least-squares fit's value
            return Outcome(np.inf, FAILED, vec, timed_out=obj.timed_out(point.u))
        elapsed = run_clock() - t0
        return Outcome(float(vec @ vec), TRAPPED if obj.trapped(point.u) else OK, vec, elapsed,
                       reread=self._reread_here(obj, point) if point.reread else None)

    def _reread_here(self, obj: Objective, point: Point) -> dict[str, float] | None:
        """:meth:`reread` from the model's slips of the evaluation just made at ``point`` (the
        same run of the model; run again only where the objective answered from its cache)."""
        events = obj.events_at(point.u)
        if events is None:
            return self.reread(point)
        choice = obj.choice.with_values(obj.values(point.u))
        return guess_from_events(self.dataset, choice, self.free, events)

    def _objective(self, n_elements: int | None) -> Objective:
        """The objective of the model with ``n_elements`` elements (None: its own), made once."""
        obj = self._objectives.get(n_elements)
        if obj is None:
            choice = self.choice if n_elements is None else \
                self.choice.with_values({"n_elements": n_elements})
            obj = self._objectives[n_elements] = Objective(self.dataset, choice, self.free)
        return obj

    def reread(self, point: Point) -> dict[str, float] | None:
        """The base levels and stiffnesses re-read from the data at ``point`` (the ratio guess of
        :mod:`rigctl.workbench.guess`: one run of the model there, within the point's time
        limit); None where the model cannot be run there."""
        obj = self._objective(point.n_elements)
        choice = obj.choice.with_values(obj.values(point.u))
        deadline = None if point.time_limit_s is None else run_clock() + point.time_limit_s
        try:
            return initial_guess(self.dataset, choice, self.free, bounded=True, deadline=deadline)
        except (SimulationError, ParameterError):
            return None

    def finish(self, task: FinishTask) -> FitResult:
        ev = evaluate(self.dataset, task.choice)
        result = FitResult(
            choice=task.choice, error=ev.score.error, feature_error=ev.score.feature_error,
            free=task.free, n_evaluations=1, message=task.message,
            misses_most_slips=misses_most_slips(self.dataset, ev.score.comparisons))
        if task.with_uncertainty and task.free:
            result = with_uncertainties(self.dataset, result)
        return result


_WORKER: dict[str, Any] = {}
"""A worker process's state: its evaluator and its BLAS limit (kept alive)."""


def _init_worker(dataset_pickle: bytes, choice: ModelChoice, free: tuple[FreeParam, ...],
                 parent_pid: int) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    # a forked worker inherits the parent's SIGTERM handler (interrupts.signals_raise, where a
    # diagnose installed it): the pool's terminate must end the worker, not raise in it
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    die_with_parent(parent_pid)
    _WORKER["blas"] = threadpool_limits(limits=1)
    _WORKER["evaluator"] = _Evaluator(pickle.loads(dataset_pickle), choice, free)


def _evaluate_in_worker(point: Point) -> Outcome:
    evaluator: _Evaluator = _WORKER["evaluator"]
    return evaluator(point)


def _finish_in_worker(task: FinishTask) -> FitResult:
    evaluator: _Evaluator = _WORKER["evaluator"]
    return evaluator.finish(task)


class EvaluationPool:
    """Evaluates points of one model on one dataset, counting each in ``budget``."""

    def __init__(self, dataset: Dataset, choice: ModelChoice, free: Sequence[FreeParam],
                 budget: Budget, workers: int) -> None:
        self.budget, self.dataset = budget, dataset
        self.choice, self.free = choice, tuple(free)
        self.workers = max(int(workers), 0)
        self._times: dict[bool, list[float]] = {}
        """CPU seconds of each evaluation that ran to its end, by integration path (True: the
        general path), for the time limit's median."""
        self._tried: set[bool] = set()
        """The paths that have had a point run alone (module docstring)."""
        self.n_timed_out = 0
        """Points stopped at the time limit: the part of a search that depends on the machine's
        speed and load (a point a quiet run evaluates can be stopped on a busy one)."""
        self._local = _Evaluator(dataset, choice, free) if self.workers == 0 else None
        self._pool: Any = None
        if self.workers:
            methods = multiprocessing.get_all_start_methods()
            ctx = multiprocessing.get_context("fork" if "fork" in methods else "spawn")
            self._pool = ctx.Pool(self.workers, initializer=_init_worker,
                                  initargs=(pickle.dumps(dataset), choice, tuple(free),
                                            os.getpid()))

    def __enter__(self) -> EvaluationPool:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close(terminate=exc_type is not None)

    def close(self, terminate: bool = False) -> None:
        """Stop the workers (at once with ``terminate``: a cancel, an error, Ctrl-C)."""
        if self._pool is None:
            return
        if terminate:
            self._pool.terminate()
        else:
            self._pool.close()
        self._pool.join()
        self._pool = None

    def time_limit_s(self, general: bool = False) -> float | None:
        """The CPU seconds an evaluation on the exact (or ``general``) path may take now (module
        docstring; None before an evaluation on that path is timed)."""
        times = self._times.get(general)
        if not times:
            return None
        return max(TIME_LIMIT_FLOOR_S, TIME_LIMIT_FACTOR * statistics.median(times))

    def general_path(self, point: Point) -> bool:
        """Whether the model at ``point`` is integrated by the general path (plug-in terms
        acting: :meth:`~rigctl.model.spec.ModelSpec.general_path`)."""
        values = {fp.name: fp.to_p(float(x)) for fp, x in zip(self.free, point.u, strict=True)}
        try:
            return self.choice.with_values(values).build().general_path()
        except (ParameterError, ValueError):  # fails at once in its evaluation: either path
            return False

    def evaluate(self, points: Sequence[Point]) -> list[Outcome]:
        """Each point's outcome, in order; each counts one evaluation of the budget, each is
        stopped at its path's time limit (module docstring). Raises
        :class:`~rigctl.workbench.budget.SearchCancelledError` when the budget is cancelled."""
        points = list(points)
        paths = [self.general_path(p) for p in points]
        first = next((i for i, g in enumerate(paths) if g not in self._tried), None)
        if first is not None and len(points) > 1:  # time one point of the path, then the rest
            alone = self.evaluate([points[first]])
            rest = self.evaluate(points[:first] + points[first + 1:])
            return rest[:first] + alone + rest[first:]
        self._tried.update(paths)
        points = [replace(p, time_limit_s=self.time_limit_s(g))
                  for p, g in zip(points, paths, strict=True)]
        self.budget.check()
        if self._local is not None:
            out = []
            for p in points:
                out.append(self._local(p))
                self.budget.spend(1)
                self.budget.check()
        else:
            pending = self._pool.map_async(_evaluate_in_worker, points, chunksize=1)
            out = self._wait(pending)
            self.budget.spend(len(out))
        for o, g in zip(out, paths, strict=True):
            if math.isfinite(o.elapsed_s):
                self._times.setdefault(g, []).append(o.elapsed_s)
        self.n_timed_out += sum(1 for o in out if o.timed_out)
        return out

    def finish(self, task: FinishTask) -> FitResult:
        """The answer of ``task`` (and its uncertainties); its evaluations count in the budget."""
        self.budget.check()
        if self._local is not None:
            result = self._local.finish(task)
        else:
            result = self._wait(self._pool.apply_async(_finish_in_worker, (task,)))
        self.budget.spend(result.n_evaluations)
        return result

    def _wait(self, pending: Any) -> Any:
        while not pending.ready():
            pending.wait(POLL_S)
            raise_if_signalled()  # a Ctrl-C whose exception a destructor dropped
            if self.budget.cancelled:
                self.close(terminate=True)
                self.budget.check()
        return pending.get()
