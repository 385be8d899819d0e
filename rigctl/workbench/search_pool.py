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
  (:func:`rigctl.workbench.parallel.die_with_parent`, as the diagnosis's task processes do).

The parent waits for a batch in steps of :data:`POLL_S`, checking the budget's cancel flag
(:meth:`~rigctl.workbench.budget.Budget.check`) between them; a cancel or Ctrl-C terminates every
worker at once. The polish's Jacobians are batches of points like a population; the answer's final
evaluation and its uncertainties run as one task in a worker, so they are cancelled the same way.
With ``workers=0`` everything runs in this process (debugging, profiling); a cancel is then seen
between evaluations only.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import signal
from collections.abc import Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from rigctl.errors import SimulationError
from rigctl.model import ParameterError
from rigctl.records.dataset import Dataset
from rigctl.records.signals import FloatArray
from rigctl.workbench.budget import Budget
from rigctl.workbench.evaluate import evaluate
from rigctl.workbench.identify import (
    FitResult,
    FreeParam,
    Objective,
    misses_most_slips,
    with_uncertainties,
)
from rigctl.workbench.model_choice import ModelChoice
from rigctl.workbench.parallel import die_with_parent

OK, TRAPPED, FAILED = "ok", "trapped", "failed"
POLL_S = 0.1
"""The parent checks the cancel flag this often while workers run: a cancel is seen within a tenth
of a second, far inside the 2 s a user waits for, at no cost."""


@dataclass(frozen=True)
class Point:
    """A point of the search: the free parameters' internal coordinates and the element count
    (None: the model's own)."""

    u: FloatArray
    n_elements: int | None = None


@dataclass(frozen=True)
class Outcome:
    """A point's cost |r|^2 (the residual vector of :class:`~rigctl.workbench.identify.Objective`,
    in scatter units), its status and the residual vector itself (None where it failed): the
    search's Jacobians are differences of these."""

    cost: float
    status: str
    vector: FloatArray | None = None


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

    def __call__(self, point: Point) -> Outcome:
        try:
            obj = self._objectives.get(point.n_elements)
            if obj is None:
                choice = self.choice if point.n_elements is None else \
                    self.choice.with_values({"n_elements": point.n_elements})
                obj = self._objectives[point.n_elements] = Objective(self.dataset, choice,
                                                                     self.free)
            vec = obj(point.u)
        except (SimulationError, ParameterError):
            return Outcome(np.inf, FAILED)
        if obj.failed(point.u):  # the vector is the failure penalty: a least-squares fit's value
            return Outcome(np.inf, FAILED, vec)
        return Outcome(float(vec @ vec), TRAPPED if obj.trapped(point.u) else OK, vec)

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
    # a forked worker inherits the parent's SIGTERM handler (parallel.raise_terminated, where a
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
        self.workers = max(int(workers), 0)
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

    def evaluate(self, points: Sequence[Point]) -> list[Outcome]:
        """Each point's outcome, in order; each counts one evaluation of the budget. Raises
        :class:`~rigctl.workbench.budget.SearchCancelledError` when the budget is cancelled."""
        self.budget.check()
        if self._local is not None:
            out = []
            for p in points:
                out.append(self._local(p))
                self.budget.spend(1)
                self.budget.check()
            return out
        pending = self._pool.map_async(_evaluate_in_worker, list(points), chunksize=1)
        outcomes: list[Outcome] = self._wait(pending)
        self.budget.spend(len(outcomes))
        return outcomes

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
            if self.budget.cancelled:
                self.close(terminate=True)
                self.budget.check()
        return pending.get()
